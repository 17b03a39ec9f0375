use super::*;
use proptest::prelude::*;

/// Roads from a shared centre node 0 out to their own far nodes, at the given angles
/// (radians), half widths and lengths.
fn star(arms: &[(f64, f64)], length: f64) -> Vec<RoadLine> {
    arms.iter()
        .enumerate()
        .map(|(i, &(angle, half_width))| RoadLine {
            nodes: vec![0, i as i64 + 1],
            points: vec![[0.0, 0.0], [angle.cos() * length, angle.sin() * length]],
            half_width,
            metre: 1.0,
        })
        .collect()
}

/// Whether `p` lies on the untrimmed strip of a straight star arm.
fn on_strip(p: Point, angle: f64, half_width: f64, length: f64) -> bool {
    let (c, s) = (angle.cos(), angle.sin());
    let along = p[0] * c + p[1] * s;
    let across = -p[0] * s + p[1] * c;
    (0.0..=length).contains(&along) && across.abs() <= half_width
}

/// How many road pieces and junctions cover each sample point of the strips within `reach`
/// of the centre: (points covered by none, points covered twice or more, points sampled).
fn coverage(arms: &[(f64, f64)], reach: f64) -> (usize, usize, usize) {
    let length = 100.0;
    let network = build(&star(arms, length));
    let (mut gaps, mut overlaps, mut sampled) = (0, 0, 0);
    let steps = 160;
    for i in 0..steps {
        for j in 0..steps {
            // An irrational offset keeps samples off the polygons' edges.
            let p = [
                -reach + 2.0 * reach * (i as f64 + 0.5137) / steps as f64,
                -reach + 2.0 * reach * (j as f64 + 0.4711) / steps as f64,
            ];
            if !arms.iter().any(|&(a, h)| on_strip(p, a, h, length)) {
                continue;
            }
            sampled += 1;
            let pieces = network
                .roads
                .iter()
                .flat_map(|r| &r.pieces)
                .filter(|piece| piece.contains(p))
                .count();
            let junctions = network
                .junctions
                .iter()
                .filter(|j| geometry::ring_contains(&j.ring, p))
                .count();
            match pieces + junctions {
                0 => gaps += 1,
                1 => {}
                _ => overlaps += 1,
            }
        }
    }
    (gaps, overlaps, sampled)
}

#[test]
fn a_crossing_a_t_and_a_fork_are_covered_exactly_once() {
    use std::f64::consts::PI;
    let crossing = [
        (0.0, 5.0),
        (PI / 2.0, 3.0),
        (PI, 5.0),
        (3.0 * PI / 2.0, 3.0),
    ];
    let t = [(0.0, 5.0), (PI, 5.0), (-PI / 2.0, 2.0)];
    let fork = [(0.0, 4.0), (2.0, 3.0), (-2.2, 3.5)];
    for arms in [&crossing[..], &t[..], &fork[..]] {
        let (gaps, overlaps, sampled) = coverage(arms, 30.0);
        assert!(sampled > 1000);
        assert_eq!((gaps, overlaps), (0, 0), "{arms:?}");
    }
}

#[test]
fn each_junction_gets_one_polygon_tracing_its_node() {
    let network = build(&star(&[(0.0, 5.0), (1.5, 5.0), (3.5, 5.0)], 100.0));
    assert_eq!(network.junctions.len(), 1);
    assert_eq!(network.junctions[0].node, 0);
    assert_eq!(network.junctions[0].roads, vec![0, 1, 2]);
    // A lone road has no junction and keeps its full length.
    let lone = build(&star(&[(0.0, 5.0)], 100.0));
    assert!(lone.junctions.is_empty());
    let area: f64 = lone.roads[0].pieces.iter().map(Polygon::area).sum();
    assert!((area - 1000.0).abs() < 1e-6, "{area}");
}

#[test]
fn two_roads_end_to_end_at_a_bend_leave_no_wedge() {
    let lines = vec![
        RoadLine {
            nodes: vec![1, 0],
            points: vec![[-100.0, 0.0], [0.0, 0.0]],
            half_width: 4.0,
            metre: 1.0,
        },
        RoadLine {
            nodes: vec![0, 2],
            points: vec![[0.0, 0.0], [70.0, 70.0]],
            half_width: 4.0,
            metre: 1.0,
        },
    ];
    let network = build(&lines);
    assert_eq!(network.junctions.len(), 1);
    // Just outside the bend, on the outer side: covered by one of the two roads' strips.
    let outer = [0.5, -3.5];
    let covered = network
        .roads
        .iter()
        .flat_map(|r| &r.pieces)
        .filter(|p| p.contains(outer))
        .count()
        + usize::from(geometry::ring_contains(&network.junctions[0].ring, outer));
    assert_eq!(covered, 1);
}

#[test]
fn bends_become_curves_that_keep_the_ends() {
    let line = [[0.0, 0.0], [50.0, 0.0], [50.0, 50.0]];
    let smoothed = smooth(&line, 10.0);
    assert_eq!(smoothed.first(), Some(&line[0]));
    assert_eq!(smoothed.last(), Some(&line[2]));
    assert!(smoothed.len() > 5);
    // No turn between consecutive segments is sharper than one curve step.
    for w in smoothed.windows(3) {
        let (a, b) = (unit(w[0], w[1]), unit(w[1], w[2]));
        let turn = (a[0] * b[0] + a[1] * b[1]).clamp(-1.0, 1.0).acos();
        assert!(turn <= BEND_STEP + 1e-9, "{turn}");
    }
    // The curve starts where a circle of radius 10 touches the first segment.
    assert!(smoothed.contains(&[40.0, 0.0]));
    // A straight line stays as it is.
    assert_eq!(smooth(&[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]], 10.0).len(), 3);
}

#[test]
fn trimming_removes_length_from_both_ends() {
    let line = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]];
    let trimmed = trim(&line, 2.0, 3.0).expect("some length is left");
    assert_eq!(trimmed, vec![[2.0, 0.0], [10.0, 0.0], [10.0, 7.0]]);
    assert_eq!(trim(&line, 12.0, 9.0), None);
}

proptest! {
    #[test]
    fn any_star_junction_is_a_simple_polygon_and_leaves_no_gap(
        arms in prop::collection::vec((-3.2f64..3.2, 0.5f64..8.0), 2..7),
    ) {
        let network = build(&star(&arms, 100.0));
        for junction in &network.junctions {
            prop_assert!(junction.ring.len() >= 3);
            prop_assert!(
                !geometry::ring_self_intersects(&junction.ring)
                    || geometry::convex_hull(&junction.ring).len() == junction.ring.len()
            );
        }
        let (gaps, overlaps, sampled) = coverage(&arms, 20.0);
        prop_assert_eq!(gaps, 0);
        // Arms well apart meet without overlapping.
        let mut angles: Vec<f64> = arms
            .iter()
            .map(|a| a.0.rem_euclid(std::f64::consts::TAU))
            .collect();
        angles.sort_by(f64::total_cmp);
        let apart = angles
            .iter()
            .zip(angles.iter().cycle().skip(1))
            .all(|(a, b)| (b - a).rem_euclid(std::f64::consts::TAU) >= std::f64::consts::FRAC_PI_2);
        if apart && angles.len() > 1 {
            prop_assert!(overlaps * 1000 <= sampled, "{} of {}", overlaps, sampled);
        }
    }
}
