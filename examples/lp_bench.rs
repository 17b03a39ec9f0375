//! Solve times of the elevation LP on problems shaped like a tile's: ways as chains of stations
//! (targets from a rough terrain, smoothness along each way, a soft maximum incline between
//! neighbours), crossings where one way must clear another by 5 m, and some contradictions.
//!
//! Usage: lp_bench [STATIONS…]   (default 1000 10000 50000)

use std::time::Instant;

use terrastitch::elevation::lp::{solve, Constraint, Problem, Relation, Smoothness};
use terrastitch::elevation::solutions::Solutions;

/// Stations per way, metres between them, and the steepest grade before the penalty.
const WAY_STATIONS: usize = 40;
const STEP_M: f64 = 10.0;
const MAX_GRADE: f64 = 0.15;

/// A deterministic rough terrain.
fn terrain(x: f64, y: f64) -> f64 {
    40.0 * (x / 700.0).sin() * (y / 500.0).cos() + 8.0 * (x / 90.0 + y / 130.0).sin()
}

fn problem(stations: usize) -> Problem {
    let mut p = Problem::default();
    let ways = stations.div_ceil(WAY_STATIONS);
    let mut first_of_way = Vec::with_capacity(ways);
    for w in 0..ways {
        let y = w as f64 * 37.0;
        first_of_way.push(p.targets.len());
        for k in 0..WAY_STATIONS {
            let x = k as f64 * STEP_M + (w % 7) as f64 * 13.0;
            p.variable(terrain(x, y), 1.0);
        }
        let base = first_of_way[w];
        for k in 1..WAY_STATIONS {
            for sign in [1.0, -1.0] {
                p.constraints.push(Constraint {
                    terms: vec![(base + k, sign), (base + k - 1, -sign)],
                    kind: Relation::AtMost,
                    rhs: MAX_GRADE * STEP_M,
                    penalty: Some(100.0),
                    label: p.constraints.len() as u32,
                });
            }
            if k + 1 < WAY_STATIONS {
                p.smoothness.push(Smoothness {
                    terms: vec![(base + k - 1, 1.0), (base + k, -2.0), (base + k + 1, 1.0)],
                    weight: 5.0,
                });
            }
        }
    }
    // Every third way bridges the next one at its middle, 5 m clear; every fiftieth is also
    // asked to pass under it (a contradiction the penalties absorb).
    let clear = |p: &mut Problem, over: usize, under: usize| {
        let label = p.constraints.len() as u32;
        p.constraints.push(Constraint {
            terms: vec![(over, 1.0), (under, -1.0)],
            kind: Relation::AtLeast,
            rhs: 5.0,
            penalty: Some(1000.0),
            label,
        });
    };
    for w in (0..ways.saturating_sub(1)).step_by(3) {
        let (over, under) = (first_of_way[w] + WAY_STATIONS / 2, first_of_way[w + 1] + 7);
        clear(&mut p, over, under);
        if w % 50 == 0 {
            clear(&mut p, under, over);
        }
    }
    p
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let sizes: Vec<usize> = match std::env::args().skip(1).collect::<Vec<_>>().as_slice() {
        [] => vec![1_000, 10_000, 50_000],
        args => args.iter().map(|a| a.parse()).collect::<Result<_, _>>()?,
    };
    for stations in sizes {
        let p = problem(stations);
        let started = Instant::now();
        // A memo of its own: every component is solved, none found.
        let outcome = solve(&p, &Solutions::default());
        let elapsed = started.elapsed();
        println!(
            "{} variables, {} constraints, {} smoothness terms: {} components (largest {} \
             variables, {} constraints), {} failed, {} violations, {:.1} ms",
            p.targets.len(),
            p.constraints.len(),
            p.smoothness.len(),
            outcome.components,
            outcome.largest.0,
            outcome.largest.1,
            outcome.failed,
            outcome.violations.len(),
            elapsed.as_secs_f64() * 1e3
        );
    }
    Ok(())
}
