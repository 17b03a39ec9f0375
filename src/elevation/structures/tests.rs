use super::*;
use crate::osm::fixture::way;

/// Level ground at 10 m.
struct Flat;
impl Elevation for Flat {
    fn elevation_uv(&self, _: [f64; 2]) -> f64 {
        10.0
    }
}

/// Ground falling eastwards from 10 m at 7.400° E, 3 m every 0.002°.
struct FallingEast;
impl Elevation for FallingEast {
    fn elevation_uv(&self, p: [f64; 2]) -> f64 {
        let lon = crate::tile::u_to_lon(p[0], 16_384.0);
        10.0 - (lon - 7.400) * 1_500.0
    }
}

fn settle_ways(ways: &[Way]) -> Vec<Settled> {
    settle_ways_on(ways, &Flat)
}

fn settle_ways_on(ways: &[Way], terrain: &dyn Elevation) -> Vec<Settled> {
    crate::osm::structures::find(ways, tags::classify)
        .iter()
        .map(|group| {
            settle(
                group,
                ways,
                terrain,
                &Projection::new(14),
                &FeatureSettings::default(),
                1.0,
                &Solutions::default(),
            )
        })
        .collect()
}

/// A 160 m bridge tagged `incline=up` whose far end the ground holds 3 m lower: the
/// contradiction is reported on that way alone, and a bridge solved in the same LP keeps
/// what it asks.
#[test]
fn a_contradiction_bends_only_its_own_way() {
    let ramp = way(
        1,
        &[
            ("highway", "residential"),
            ("bridge", "yes"),
            ("incline", "up"),
        ],
        &[(1, 7.400, 43.7), (2, 7.401, 43.7), (3, 7.402, 43.7)],
    );
    let over_river = way(
        2,
        &[
            ("highway", "residential"),
            ("bridge", "yes"),
            ("layer", "2"),
        ],
        &[(4, 7.4005, 43.697), (5, 7.4005, 43.703)],
    );
    let river = way(
        3,
        &[("waterway", "river")],
        &[(6, 7.4000, 43.7002), (7, 7.4010, 43.7002)],
    );
    let with = settle_ways_on(
        &[ramp.clone(), over_river.clone(), river.clone()],
        &FallingEast,
    );
    assert_eq!(
        with.len(),
        1,
        "one group: the second bridge crosses the first"
    );
    let group = &with[0];
    assert_eq!(group.failed, 0);
    let violated: Vec<(i64, ConstraintKind)> =
        group.violations(0.01).map(|v| (v.way, v.kind)).collect();
    assert!(
        violated.contains(&(1, ConstraintKind::TaggedIncline)),
        "{violated:?}"
    );
    assert!(violated.iter().all(|&(w, _)| w == 1), "{violated:?}");
    // The ends stay on the ground.
    let first = &group.profiles[0];
    assert!((first.elevations[0] - 10.0).abs() < 1e-6);
    assert!((first.elevations[first.elevations.len() - 1] - 7.0).abs() < 1e-6);
    for report in group.reports.iter().filter(|r| r.way == 2) {
        assert!(report.violation <= 0.01, "{report:?}");
    }
}

/// A tagged grade is the steepest the way gets, rising in its sign's direction; ends
/// joined to another chain are free.
#[test]
fn a_tagged_grade_bounds_the_way_where_the_ends_allow_it() {
    // A bridge ramp up from the ground to a second, higher bridge over a road.
    let ramp = way(
        1,
        &[("highway", "service"), ("bridge", "yes"), ("incline", "5%")],
        &[(1, 7.400, 43.7), (2, 7.401, 43.7)],
    );
    let upper = way(
        2,
        &[("highway", "service"), ("bridge", "yes"), ("layer", "2")],
        &[(2, 7.401, 43.7), (3, 7.404, 43.7)],
    );
    let road = way(
        3,
        &[("highway", "primary")],
        &[(4, 7.4025, 43.699), (5, 7.4025, 43.701)],
    );
    let settled = settle_ways(&[ramp, upper, road]);
    assert_eq!(settled.len(), 1);
    let group = &settled[0];
    let violated: Vec<_> = group.violations(0.01).collect();
    assert!(violated.is_empty(), "{violated:?}");
    let first = &group.profiles[0];
    let n = first.points.len();
    for k in 1..n {
        let grade = (first.elevations[k] - first.elevations[k - 1])
            / (first.along_m[k] - first.along_m[k - 1]);
        assert!((-1e-6..=0.05 + 1e-6).contains(&grade), "{grade}");
    }
    assert_eq!(first.grounded, [true, false]);
}
