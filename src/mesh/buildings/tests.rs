use std::collections::HashMap;

use super::*;
use crate::features::buildings::{appearance, basement_m, height_m, min_height_m, roof_spec};
use crate::features::FeatureSettings;
use crate::osm::Tags;

/// A building from tags on a footprint given in metres (tiles of 1,000 m).
fn building(pairs: &[(&str, &str)], outer: &[Point]) -> BuildingShape {
    let tags = Tags::from_pairs(pairs.iter().copied());
    let settings = FeatureSettings::default();
    let (height, tagged) = height_m(&tags, &settings);
    BuildingShape {
        feature: 0,
        footprint: Polygon {
            outer: outer
                .iter()
                .map(|p| [p[0] / 1000.0, p[1] / 1000.0])
                .collect(),
            holes: Vec::new(),
        },
        height_m: height,
        height_tagged: tagged,
        basement_m: basement_m(&tags, &settings),
        roof: roof_spec(&tags, &settings),
        min_height_m: min_height_m(&tags, &settings),
        drawn: true,
        base: None,
        appearance: appearance(&tags),
        facade: crate::features::facades::facade(&tags, None, None, &settings),
        passages: Vec::new(),
    }
}

fn heights(solid: &Solid) -> (f64, f64) {
    solid
        .faces()
        .flatten()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), c| {
            (lo.min(c[2]), hi.max(c[2]))
        })
}

#[test]
fn a_footprint_whose_skeleton_trips_keeps_its_outline_under_a_gabled_roof() {
    // Way 143210134 in Monaco: nearly rectilinear, with a notch whose sides are 3° apart.
    let outline = [
        [0.0, 0.0],
        [0.0, -2.773831922817812],
        [-4.230140648659374, -2.773831922817812],
        [-4.230140648659374, -15.101983899019935],
        [-9.57347621282245, -15.101983899019935],
        [-9.462156721717003, -17.10531014979389],
        [-13.692297370376375, -17.10531014979389],
        [-13.692297370376375, -15.101983899019935],
        [-18.924313434535563, -15.101983899019935],
        [-19.03563292564101, -2.773831922817812],
        [-5.009377086397511, -2.6197301299243883],
        [-5.009377086397511, -0.154101750625828],
    ];
    let hipped = building(&[("roof:shape", "hipped"), ("height", "12")], &outline);
    let shell = solid(&hipped, 1000.0, 0.0, 0.0);
    assert_eq!(shell.fallback, Some(Fallback::Skeleton));
    assert!(!shell.flat_roof);
    assert!((heights(&shell).1 - 12.0).abs() < 1e-9);
    assert_eq!(unmatched_edges(&shell), 0);
    // The walls stand on the outline as drawn (the ground is cut by it): every corner of it,
    // and nothing else, is the foot of a wall.
    let mut feet: Vec<[f64; 2]> = shell
        .walls
        .iter()
        .flat_map(|w| w.iter().filter(|c| c[2] < 0.0).map(|c| [c[0], c[1]]))
        .collect();
    feet.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    feet.dedup();
    let mut corners = outline.to_vec();
    corners.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    assert_eq!(feet.len(), corners.len());
    for (foot, corner) in feet.iter().zip(&corners) {
        assert!(
            (foot[0] - corner[0]).abs() < 1e-9 && (foot[1] - corner[1]).abs() < 1e-9,
            "{foot:?} is no corner of the outline"
        );
    }
}

/// Directed edges of a shell's faces not met by exactly one edge running the other way.
fn unmatched_edges(solid: &Solid) -> usize {
    let key = |c: [f64; 3]| c.map(|x| (x + 0.0).to_bits());
    let mut edges: HashMap<([u64; 3], [u64; 3]), i32> = HashMap::new();
    for face in solid.faces() {
        for i in 0..face.len() {
            let (a, b) = (key(face[i]), key(face[(i + 1) % face.len()]));
            if a != b {
                *edges.entry((a, b)).or_default() += 1;
            }
        }
    }
    edges
        .iter()
        .filter(|(&(a, b), &n)| n != 1 || edges.get(&(b, a)) != Some(&1))
        .count()
}

/// Level ground at 100 m.
struct Level100;

impl Elevation for Level100 {
    fn elevation_uv(&self, _: [f64; 2]) -> f64 {
        100.0
    }
}

/// A road 4.5 m wide crossing a 20 m × 12 m footprint from south to north (tile units of
/// 1,000 m).
fn road_across() -> Polygon {
    Polygon {
        outer: vec![
            [0.008, -0.005],
            [0.0125, -0.005],
            [0.0125, 0.02],
            [0.008, 0.02],
        ],
        holes: Vec::new(),
    }
}

#[test]
fn a_road_through_a_building_opens_its_walls_under_a_closed_shell() {
    let footprint = [[0.0, 0.0], [20.0, 0.0], [20.0, 12.0], [0.0, 12.0]];
    let road = road_across();
    for roof in ["flat", "gabled", "hipped"] {
        let mut house = building(
            &[("building", "yes"), ("height", "12"), ("roof:shape", roof)],
            &footprint,
        );
        house.passages = vec![road.clone()];
        let closed = solid(&house, 1000.0, 100.0, 100.0);
        let open = solid_over_passages(&house, 1000.0, 100.0, 100.0, Some(&Level100));
        assert_eq!(unmatched_edges(&closed), 0, "{roof}: closed shell");
        assert_eq!(unmatched_edges(&open), 0, "{roof}: opened shell");
        // The ceiling over the road, 4 m over its ground, spans the passage: 4.5 m × 12 m.
        let ceiling: f64 = open
            .floor
            .iter()
            .filter(|t| t.iter().all(|c| (c[2] - 104.0).abs() < 1e-9))
            .map(|t| newell(t)[2].abs() / 2.0)
            .sum();
        assert!(
            (ceiling - 54.0).abs() < 1e-6,
            "{roof}: ceiling {ceiling} m²"
        );
        // No wall reaches below the ceiling inside the passage.
        let inside = |c: &[f64; 3]| c[0] > 8.0 + 1e-9 && c[0] < 12.5 - 1e-9;
        let low_in_passage = open
            .walls
            .iter()
            .flatten()
            .filter(|c| inside(c) && c[2] < 104.0 - 1e-9)
            .count();
        assert_eq!(low_in_passage, 0, "{roof}: wall corners below the ceiling");
    }
}

#[test]
fn a_building_too_low_for_a_passage_stays_closed_over_the_road() {
    let footprint = [[0.0, 0.0], [20.0, 0.0], [20.0, 12.0], [0.0, 12.0]];
    let mut shed = building(&[("building", "yes"), ("height", "3")], &footprint);
    shed.passages = vec![road_across()];
    let shell = solid_over_passages(&shed, 1000.0, 100.0, 100.0, Some(&Level100));
    assert_eq!(shell.walls.len(), 4);
    assert_eq!(unmatched_edges(&shell), 0);
}

#[test]
fn parts_stack_by_min_height() {
    let square = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
    let lower = building(&[("building:part", "yes"), ("height", "10")], &square);
    let upper = building(
        &[
            ("building:part", "yes"),
            ("min_height", "10"),
            ("height", "25"),
            ("roof:shape", "pyramidal"),
            ("roof:height", "5"),
        ],
        &square,
    );
    let (low, high) = (100.0, 104.0);
    let lower = solid(&lower, 1000.0, low, high);
    let upper = solid(&upper, 1000.0, low, high);
    assert_eq!(heights(&lower), (low - WALL_SKIRT_M, low + 10.0));
    assert!(!lower.floating && upper.floating);
    assert_eq!(heights(&upper), (low + 10.0, low + 25.0));
    // The upper part's walls reach its eaves, its roof the top.
    let eaves = upper
        .walls
        .iter()
        .flatten()
        .map(|c| c[2])
        .fold(0.0, f64::max);
    assert!((eaves - (low + 20.0)).abs() < 1e-9, "{eaves}");
}

/// The height of a solid's walls at the corner `(0, 0)` of its plan (the eaves of a roof
/// whose gables stand elsewhere).
fn eaves(solid: &Solid) -> f64 {
    solid
        .walls
        .iter()
        .flatten()
        .filter(|c| c[0].abs() < 1e-9 && c[1].abs() < 1e-9)
        .map(|c| c[2])
        .fold(f64::NEG_INFINITY, f64::max)
}

#[test]
fn a_pitched_roof_stands_on_the_levels_tagged_not_in_them() {
    let house = [[0.0, 0.0], [10.0, 0.0], [10.0, 8.0], [0.0, 8.0]];
    // Two levels of walls, the gabled roof on top (4 m wide each side at 30°).
    let levels = solid(
        &building(
            &[
                ("building", "house"),
                ("building:levels", "2"),
                ("roof:shape", "gabled"),
            ],
            &house,
        ),
        1000.0,
        0.0,
        0.0,
    );
    assert!(!levels.flat_roof);
    let ridge = 4.0 * 30f64.to_radians().tan();
    assert!((eaves(&levels) - 6.0).abs() < 1e-9, "{}", eaves(&levels));
    assert!((heights(&levels).1 - (6.0 + ridge)).abs() < 1e-6);
    // The synonym `building:roof:shape` is the same roof.
    let synonym = solid(
        &building(
            &[
                ("building", "yes"),
                ("building:levels", "2"),
                ("building:roof:shape", "gabled"),
            ],
            &house,
        ),
        1000.0,
        0.0,
        0.0,
    );
    assert_eq!(heights(&synonym), heights(&levels));
    // A tagged height holds the roof; so do levels that count the roof's own (of 3 m).
    for (tags, roof) in [
        (
            &[
                ("building", "house"),
                ("height", "6"),
                ("roof:shape", "gabled"),
            ][..],
            ridge,
        ),
        (
            &[
                ("building", "house"),
                ("building:levels", "1"),
                ("roof:levels", "1"),
                ("roof:shape", "gabled"),
            ][..],
            3.0,
        ),
    ] {
        let shell = solid(&building(tags, &house), 1000.0, 0.0, 0.0);
        assert!((heights(&shell).1 - 6.0).abs() < 1e-9, "{tags:?}");
        assert!((eaves(&shell) - (6.0 - roof)).abs() < 1e-6, "{tags:?}");
    }
}

#[test]
fn a_slope_shows_the_underground_levels_on_its_low_side() {
    let square = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
    let tags = [
        ("building:levels", "4"),
        ("building:levels:underground", "2"),
    ];
    let shell = solid(&building(&tags, &square), 1000.0, 50.0, 54.0);
    // Four levels above the high side's ground: 12 m plus the 4 m the ground falls.
    assert_eq!(heights(&shell).1, 50.0 + 12.0 + 4.0);
    let shell = solid(&building(&tags, &square), 1000.0, 50.0, 60.0);
    assert_eq!(heights(&shell).1, 50.0 + 12.0 + 6.0);
}

#[test]
fn an_l_shape_is_covered_exactly() {
    let polygon = Polygon {
        outer: vec![
            [0.0, 0.0],
            [2.0, 0.0],
            [2.0, 1.0],
            [1.0, 1.0],
            [1.0, 2.0],
            [0.0, 2.0],
        ],
        holes: vec![],
    };
    let area: f64 = triangulate_polygon(&polygon)
        .iter()
        .map(|t| signed_area2(t).abs() / 2.0)
        .sum();
    assert!((area - 3.0).abs() < 1e-12, "{area}");
}

#[test]
fn a_courtyard_stays_open() {
    let polygon = Polygon {
        outer: vec![[0.0, 0.0], [3.0, 0.0], [3.0, 3.0], [0.0, 3.0]],
        holes: vec![vec![[1.0, 1.0], [2.0, 1.0], [2.0, 2.0], [1.0, 2.0]]],
    };
    let area: f64 = triangulate_polygon(&polygon)
        .iter()
        .map(|t| signed_area2(t).abs() / 2.0)
        .sum();
    assert!((area - 8.0).abs() < 1e-12, "{area}");
}

#[test]
fn a_footprint_that_crosses_itself_keeps_both_lobes() {
    // A bow tie: the ring crosses itself at (1, 1); even-odd inside is both triangles.
    let polygon = Polygon {
        outer: vec![[0.0, 0.0], [2.0, 2.0], [2.0, 0.0], [0.0, 2.0]],
        holes: vec![],
    };
    let area: f64 = triangulate_polygon(&polygon)
        .iter()
        .map(|t| signed_area2(t).abs() / 2.0)
        .sum();
    assert!((area - 2.0).abs() < 1e-12, "{area}");
}
