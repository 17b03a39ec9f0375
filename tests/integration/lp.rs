//! The elevation LP's own solver held to clarabel's optimum on components recorded from the
//! bundled tiles.

use std::io::Read;

use terrastitch::elevation::lp::VIOLATION_EPS;
use terrastitch::elevation::lp::{dot, interior, objective, reference, shortfall, text, Problem};
use terrastitch::elevation::solutions::Solved;

/// Components recorded from the ten golden tiles by `render --record-lp` and picked by
/// `scripts/lp_fixtures.py`: 300, from single variables to a few hundred.
fn recorded_components() -> Vec<Problem> {
    let gz = std::fs::read(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/lp-components.txt.gz"),
    )
    .expect("the fixtures");
    let mut recorded = String::new();
    flate2::read::GzDecoder::new(&gz[..])
        .read_to_string(&mut recorded)
        .expect("the fixtures decompress");
    text::read(&recorded).expect("the fixtures read")
}

#[test]
fn the_component_solver_reaches_clarabels_optimum_on_recorded_components() {
    let components = recorded_components();
    assert_eq!(components.len(), 300);
    let mut gave_up = 0;
    for (k, c) in components.iter().enumerate() {
        let theirs = reference::solve(c).expect("clarabel solves every recorded component");
        let Some(ours) = interior::solve(c) else {
            gave_up += 1;
            continue;
        };
        let (f, g) = (objective(c, &ours.values), objective(c, &theirs.values));
        // Never worse than clarabel's by more than 1e-6 relative; better by a little where
        // clarabel stops short (its gap tolerance is 1e-8 of its own, scaled, objective).
        assert!(
            f - g <= 1e-6 * g.abs().max(1.0) && g - f <= 1e-5 * g.abs().max(1.0),
            "component {k}: objective {f} against clarabel's {g}"
        );
        for (v, fixed) in c.fixed.iter().enumerate() {
            if let Some(value) = fixed {
                assert_eq!(ours.values[v], *value, "component {k}: fixed variable {v}");
            }
        }
        for (at, hard) in c.constraints.iter().enumerate() {
            if hard.penalty.is_none() {
                let miss = shortfall(hard, dot(&hard.terms, &ours.values));
                assert!(
                    miss <= 1e-6 * (1.0 + hard.rhs.abs()),
                    "component {k}: hard constraint {at} misses by {miss}"
                );
            }
        }
        // The same soft constraints give way (those near the threshold of a report aside).
        // How far may differ where the optimum is not one point: the objective holds that.
        let amount = |solved: &Solved, at: u32| {
            solved
                .violations
                .iter()
                .find(|&&(v, _)| v == at)
                .map_or(0.0, |&(_, x)| x)
        };
        for &(at, _) in ours.violations.iter().chain(&theirs.violations) {
            let (a, b) = (amount(&ours, at), amount(&theirs, at));
            assert!(
                a.min(b) > 0.0 || a.max(b) <= 2.0 * VIOLATION_EPS,
                "component {k}: constraint {at} gives way by {a} against clarabel's {b}"
            );
        }
    }
    // The few it gives up on go to clarabel; more would mean the solver no longer fits.
    assert!(gave_up <= 3, "gave up on {gave_up} of {}", components.len());
}

#[test]
fn recorded_components_written_as_text_read_back_the_same() {
    let components = recorded_components();
    let again = text::read(&components.iter().map(text::write).collect::<String>())
        .expect("written components read");
    assert_eq!(again.len(), components.len());
    for (a, b) in components.iter().zip(&again) {
        assert_eq!(a.targets, b.targets);
        assert_eq!(a.weights, b.weights);
        assert_eq!(a.fixed, b.fixed);
        assert_eq!(a.constraints, b.constraints);
        assert_eq!(a.smoothness, b.smoothness);
    }
}
