//! The LP component solver against clarabel on recorded components (`render --record-lp`):
//! objective, hard constraints, violations, the largest difference of a value, and time.
//!
//! Usage: [LP_MIN_FREE=N] [LP_MAX_FREE=N] lp_compare FILE…   (only components with that many
//! free variables)

use std::time::{Duration, Instant};

use terrastitch::elevation::lp::{interior, objective, reference, text};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut components = Vec::new();
    for path in std::env::args().skip(1) {
        components.extend(text::read(&std::fs::read_to_string(&path)?)?);
    }
    let (mut ours, mut theirs) = (Duration::ZERO, Duration::ZERO);
    let (mut gave_up, mut worse, mut largest_move) = (0, 0, 0.0f64);
    let limit: usize = std::env::var("LP_MAX_FREE")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(usize::MAX);
    let floor: usize = std::env::var("LP_MIN_FREE")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    for (k, c) in components.iter().enumerate() {
        let free = c.fixed.iter().filter(|f| f.is_none()).count();
        if free > limit || free < floor {
            continue;
        }
        let started = Instant::now();
        let a = interior::solve(c);
        ours += started.elapsed();
        let started = Instant::now();
        let b = reference::solve(c);
        theirs += started.elapsed();
        match (a, b) {
            (None, _) => {
                gave_up += 1;
                println!(
                    "{k}: gave up ({free} free, {} constraints)",
                    c.constraints.len()
                );
            }
            (Some(a), Some(b)) => {
                let (fa, fb) = (objective(c, &a.values), objective(c, &b.values));
                let moved = a
                    .values
                    .iter()
                    .zip(&b.values)
                    .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
                if moved > largest_move {
                    println!("{k}: moved {moved:e} ({free} free), objectives {fa} {fb}");
                }
                largest_move = largest_move.max(moved);
                let clear = |v: &[(u32, f64)]| -> Vec<u32> {
                    v.iter()
                        .filter(|(_, x)| *x > 2e-4)
                        .map(|(l, _)| *l)
                        .collect()
                };
                let (la, lb) = (clear(&a.violations), clear(&b.violations));
                let missing = la
                    .iter()
                    .filter(|l| !b.violations.iter().any(|(m, _)| m == *l))
                    .count()
                    + lb.iter()
                        .filter(|l| !a.violations.iter().any(|(m, _)| m == *l))
                        .count();
                if missing > 0 {
                    println!(
                        "{k}: violations differ: {:?} against {:?}",
                        a.violations, b.violations
                    );
                }
                if (fa - fb) > 1e-6 * fb.abs().max(1.0) {
                    worse += 1;
                    println!("{k}: objective {fa} against {fb} ({free} free)");
                }
            }
            (Some(_), None) => println!("{k}: clarabel failed"),
        }
    }
    println!(
        "{} components: ours {:.1} ms, clarabel {:.1} ms; gave up {gave_up}, worse {worse}, largest move {largest_move:e} m",
        components.len(),
        ours.as_secs_f64() * 1e3,
        theirs.as_secs_f64() * 1e3
    );
    Ok(())
}
