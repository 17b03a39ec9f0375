use super::*;

fn at_least(a: usize, b: usize, gap: f64, penalty: Option<f64>, label: u32) -> Constraint {
    // x_a − x_b ≥ gap
    Constraint {
        terms: vec![(a, 1.0), (b, -1.0)],
        kind: Relation::AtLeast,
        rhs: gap,
        penalty,
        label,
    }
}

#[test]
fn unconstrained_variables_keep_their_targets_and_components_split() {
    let mut p = Problem::default();
    let v: Vec<usize> = [10.0, 20.0, 30.0, 40.0, 50.0]
        .iter()
        .map(|&t| p.variable(t, 1.0))
        .collect();
    // A bridge (v1) at least 5 m above what it crosses (v0); v2 and v3 at one height.
    p.constraints.push(at_least(v[1], v[0], 15.0, None, 0));
    p.constraints.push(Constraint {
        terms: vec![(v[2], 1.0), (v[3], -1.0)],
        kind: Relation::Equal,
        rhs: 0.0,
        penalty: None,
        label: 1,
    });
    let out = solve(&p, &Solutions::default());
    assert_eq!(out.components, 2);
    assert_eq!(out.failed, 0);
    assert!(
        out.values[1] - out.values[0] >= 15.0 - 1e-6,
        "{:?}",
        out.values
    );
    // Least total change: 5 m shared between the two, somewhere.
    let moved = (out.values[0] - 10.0).abs() + (out.values[1] - 20.0).abs();
    assert!((moved - 5.0).abs() < 1e-5, "{moved}");
    // The equal pair is snapped to exactly one value within the targets.
    assert_eq!(out.values[2], out.values[3]);
    assert!((30.0..=40.0).contains(&out.values[2]));
    assert_eq!(out.values[4], 50.0);
    assert!(out.violations.is_empty());
}

#[test]
fn a_contradiction_bends_only_what_it_involves_and_is_reported() {
    let mut p = Problem::default();
    let a = p.variable(0.0, 1.0);
    let b = p.variable(0.0, 1.0);
    let c = p.variable(7.0, 1.0);
    let d = p.variable(3.0, 1.0);
    // a above b by 10 and b above a by 10: impossible together.
    p.constraints.push(at_least(a, b, 10.0, Some(100.0), 7));
    p.constraints.push(at_least(b, a, 10.0, Some(100.0), 8));
    // An unrelated, satisfiable constraint elsewhere.
    p.constraints.push(at_least(c, d, 2.0, Some(100.0), 9));
    let out = solve(&p, &Solutions::default());
    assert_eq!(out.failed, 0);
    let total: f64 = out.violations.iter().map(|v| v.amount).sum();
    assert!((total - 20.0).abs() < 1e-3, "{:?}", out.violations);
    assert!(out.violations.iter().all(|v| v.label == 7 || v.label == 8));
    assert!((out.values[c] - 7.0).abs() < 1e-5 && (out.values[d] - 3.0).abs() < 1e-5);
}

#[test]
fn fixed_variables_hold_and_smoothness_rounds_a_peak_into_a_deck() {
    // Five stations of a bridge over a valley: the ends fixed on the banks at 10 m, the
    // terrain below at 0 m, the middle station at least 8 m above the valley floor.
    let mut p = Problem::default();
    let targets = [10.0, 0.0, 0.0, 0.0, 10.0];
    let x: Vec<usize> = targets.iter().map(|&t| p.variable(t, 0.01)).collect();
    p.fix(x[0], 10.0);
    p.fix(x[4], 10.0);
    let floor = p.variable(0.0, 1.0);
    p.constraints
        .push(at_least(x[2], floor, 8.0, Some(1000.0), 0));
    for k in 1..4 {
        p.smoothness.push(Smoothness {
            terms: vec![(x[k - 1], 1.0), (x[k], -2.0), (x[k + 1], 1.0)],
            weight: 10.0,
        });
    }
    let out = solve(&p, &Solutions::default());
    assert_eq!((out.values[x[0]], out.values[x[4]]), (10.0, 10.0));
    assert!(out.values[x[2]] - out.values[floor] >= 8.0 - 1e-6);
    // A straight deck from bank to bank: no peak at the middle, no sag either side.
    for &station in &x[1..4] {
        assert!(
            (out.values[station] - 10.0).abs() < 1e-4,
            "{:?}",
            out.values
        );
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(200))]
    /// Random soft "at least" constraints, contradictions included: the LP never fails,
    /// every shortfall in the values is reported, and free variables keep their targets.
    #[test]
    fn every_shortfall_is_reported(
        targets in proptest::collection::vec(-20.0f64..20.0, 2..30),
        pairs in proptest::collection::vec((0usize..30, 0usize..30, -10.0f64..10.0), 0..40),
        hard in proptest::collection::vec(proptest::bool::ANY, 40),
    ) {
        let mut p = Problem::default();
        for &t in &targets {
            p.variable(t, 1.0);
        }
        let n = targets.len();
        for (k, &(a, b, gap)) in pairs.iter().enumerate() {
            let (a, b) = (a % n, b % n);
            if a == b {
                continue;
            }
            // Hard ones only along increasing indices: they can always hold together.
            let penalty = if hard[k] && a > b { None } else { Some(50.0) };
            p.constraints.push(at_least(a, b, gap, penalty, k as u32));
        }
        let out = solve(&p, &Solutions::default());
        proptest::prop_assert_eq!(out.failed, 0);
        let mut reported = vec![0.0; pairs.len()];
        for v in &out.violations {
            reported[v.label as usize] += v.amount;
        }
        let mut constrained = vec![false; n];
        for c in &p.constraints {
            let (a, b) = (c.terms[0].0, c.terms[1].0);
            constrained[a] = true;
            constrained[b] = true;
            let shortfall = c.rhs - (out.values[a] - out.values[b]);
            let allowed = if c.penalty.is_some() { reported[c.label as usize] } else { 0.0 };
            proptest::prop_assert!(shortfall <= allowed + 1e-4, "{} > {}", shortfall, allowed);
        }
        for v in 0..n {
            if !constrained[v] {
                proptest::prop_assert_eq!(out.values[v], targets[v]);
            }
        }
    }
}

/// A contradiction (labels `label`, `label + 1`) among two variables placed after
/// `before` unrelated ones, with a target that differs by `target`.
fn contradiction(before: usize, label: u32, target: f64) -> (Problem, [usize; 2]) {
    let mut p = Problem::default();
    for k in 0..before {
        let v = p.variable(k as f64, 1.0);
        let w = p.variable(0.0, 1.0);
        p.constraints.push(at_least(v, w, 1.0, None, 100));
    }
    let a = p.variable(target, 1.0);
    let b = p.variable(0.0, 1.0);
    p.constraints.push(at_least(a, b, 10.0, Some(100.0), label));
    p.constraints
        .push(at_least(b, a, 3.0, Some(50.0), label + 1));
    (p, [a, b])
}

#[test]
fn a_component_solved_once_is_found_again_wherever_it_sits_with_its_own_labels() {
    let memo = Solutions::default();
    let target = 1234.5678;
    let (first, [a, b]) = contradiction(0, 7, target);
    let solved = solve(&first, &memo);
    let (found, solved_afresh) = memo.counts();
    assert_eq!((found, solved_afresh), (0, 1), "a new memo finds nothing");
    // The same contradiction after three components of its own.
    let (second, [c, d]) = contradiction(3, 40, target);
    let again = solve(&second, &memo);
    assert_eq!(
        memo.counts(),
        (1, 4),
        "the contradiction is found, not solved"
    );
    assert_eq!(
        [solved.values[a], solved.values[b]],
        [again.values[c], again.values[d]]
    );
    let labels = |o: &Outcome| -> Vec<(u32, u64)> {
        o.violations
            .iter()
            .filter(|v| v.label != 100)
            .map(|v| (v.label, v.amount.to_bits()))
            .collect()
    };
    let shifted: Vec<(u32, u64)> = labels(&solved)
        .into_iter()
        .map(|(label, amount)| (label + 33, amount))
        .collect();
    assert!(!shifted.is_empty());
    assert_eq!(labels(&again), shifted);
    // A component that differs in one number is solved, not found.
    let (other, [e, _]) = contradiction(0, 7, target + 1.0);
    assert_ne!(solve(&other, &memo).values[e], solved.values[a]);
    assert_eq!(memo.counts(), (1, 5), "a component that differs is solved");
}

#[test]
fn a_damaged_solution_read_back_is_solved_again() {
    let target = 4321.0;
    let (p, [a, b]) = contradiction(0, 3, target);
    // One value for two members: not a solution of this component.
    let damaged = solutions::encode(Some(&solutions::Solved {
        values: vec![-7.0],
        violations: Vec::new(),
    }));
    let key = component_key(&component(&p, &[a, b], &[0, 1], &[]));
    let memo = Solutions::default();
    assert_eq!(memo.remember([(key, damaged)]), 1);
    let out = solve(&p, &memo);
    assert_eq!(out.failed, 0);
    // The damaged entry would give a −7 m and leave b at its target, 17 m short of a ≥ b + 10.
    assert!(
        out.values[a] - out.values[b] >= 10.0 - 1e-6,
        "{:?}",
        out.values
    );
}

#[test]
fn a_component_written_as_text_reads_back_the_same() {
    let (mut p, _) = contradiction(2, 7, 1234.5678);
    p.fix(0, -0.1);
    p.smoothness.push(Smoothness {
        terms: vec![(0, 1.0), (1, -2.0), (2, 1.0 / 3.0)],
        weight: 20.0,
    });
    let again = text::read(&text::write(&p)).unwrap();
    assert_eq!(again.len(), 1);
    assert_eq!(again[0].targets, p.targets);
    assert_eq!(again[0].weights, p.weights);
    assert_eq!(again[0].fixed, p.fixed);
    assert_eq!(again[0].constraints, p.constraints);
    assert_eq!(again[0].smoothness, p.smoothness);
    assert!(text::read("component\nv 1.0 1.0 -\n").is_err());
    assert!(text::read("component\nv 1.0 NaN -\nend\n").is_err());
    assert!(text::read("component\nv 1.0 1.0 -\ns 1.0 3:1.0\nend\n").is_err());
}

#[test]
fn a_variable_named_twice_in_a_row_counts_twice_in_both_solvers() {
    // 2·a = b, hard; a smoothness term and a soft bound naming a twice as well.
    let mut p = Problem::default();
    let a = p.variable(3.0, 1.0);
    let b = p.variable(5.0, 2.0);
    let c = p.variable(1.0, 1.0);
    p.constraints.push(Constraint {
        terms: vec![(a, 1.0), (b, -1.0), (a, 1.0)],
        kind: Relation::Equal,
        rhs: 0.0,
        penalty: None,
        label: 0,
    });
    p.constraints.push(at_least(c, a, 1.0, Some(10.0), 1));
    p.smoothness.push(Smoothness {
        terms: vec![(a, 0.5), (c, -1.0), (a, 0.5)],
        weight: 0.25,
    });
    let ours = interior::solve(&p).expect("the solver takes it");
    let theirs = reference::solve(&p).expect("clarabel takes it");
    assert!(
        (2.0 * ours.values[a] - ours.values[b]).abs() < 1e-7,
        "{:?}",
        ours.values
    );
    let (f, g) = (objective(&p, &ours.values), objective(&p, &theirs.values));
    assert!((f - g).abs() < 1e-6 * g.max(1.0), "{f} against {g}");
}
