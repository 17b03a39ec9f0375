//! Pedestrian crossings painted on roads: a `highway=crossing` node (or one tagged
//! `crossing=*`) on a road for motor traffic.
//!
//! What is painted: `crossing:markings` when tagged (`zebra`, `ladder`… stripes; `lines`,
//! `dashes` two lines; `no`, `surface` nothing), else `crossing_ref=zebra` stripes, else by
//! `crossing`: `unmarked`, `no` and `informal` nothing; `zebra`, `marked`, `uncontrolled` (and
//! an untagged kind, mostly marked) stripes; `traffic_signals` stripes around the
//! Mediterranean and two lines across the road in central Europe, the Alps and North America,
//! as the rules there paint them. Stripes are 0.5 m wide with 0.5 m gaps, 4 m long along the
//! road, across its whole width; lines 0.3 m wide, 3 m apart. Each crossing is one feature,
//! its node's tags, drawn in the material `crossing`.

use super::inference::Region;
use super::markings::{Marking, Paint, Pattern};
use crate::geometry::Point;
use crate::osm::Tags;

/// Width of a zebra's stripe, and of the gap between two, metres.
const STRIPE_M: f64 = 0.5;
/// Length of a zebra's stripes along the road, metres.
const ZEBRA_LENGTH_M: f64 = 4.0;
/// Width of a signal crossing's lines, and the distance between them, metres.
const LINE_M: f64 = 0.3;
const LINES_APART_M: f64 = 3.0;

/// How a crossing is painted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CrossingPaint {
    /// Stripes along the road, across its width.
    Zebra,
    /// Two lines across the road, either side of the walkway.
    Lines,
}

/// Whether a road of these tags carries motor traffic, so its crossings are painted.
pub fn is_painted_road(tags: &Tags) -> bool {
    let Some(highway) = tags.get("highway") else {
        return false;
    };
    tags.get("area") != Some("yes")
        && matches!(
            highway.strip_suffix("_link").unwrap_or(highway),
            "motorway"
                | "trunk"
                | "primary"
                | "secondary"
                | "tertiary"
                | "unclassified"
                | "residential"
                | "living_street"
                | "service"
                | "road"
                | "busway"
        )
}

/// How the crossing a node's tags describe is painted in a region; `None` for a node that is
/// no crossing, or a crossing left unpainted.
pub fn paint(tags: &Tags, region: Region) -> Option<CrossingPaint> {
    let crossing = tags.get("crossing");
    if tags.get("highway") != Some("crossing") && crossing.is_none() {
        return None;
    }
    if let Some(markings) = tags.get("crossing:markings") {
        return match markings {
            "no" | "surface" => None,
            "lines" | "dashes" | "dots" | "lines:paired" | "dashes:paired" => {
                Some(CrossingPaint::Lines)
            }
            _ => Some(CrossingPaint::Zebra),
        };
    }
    if tags.get("crossing_ref") == Some("zebra") {
        return Some(CrossingPaint::Zebra);
    }
    match crossing {
        Some("unmarked" | "no" | "informal" | "island") => None,
        Some("traffic_signals") => Some(match region {
            Region::Mediterranean | Region::Other => CrossingPaint::Zebra,
            Region::Alpine | Region::CentralEurope | Region::NorthAmerica => CrossingPaint::Lines,
        }),
        Some("zebra" | "marked" | "uncontrolled") | None => Some(CrossingPaint::Zebra),
        Some(other) => {
            tracing::debug!(crossing = other, "unknown crossing kind painted as a zebra");
            Some(CrossingPaint::Zebra)
        }
    }
}

/// How far a crossing's paint reaches along the road either side of its node, metres.
pub fn depth_m(paint: CrossingPaint) -> f64 {
    match paint {
        CrossingPaint::Zebra => ZEBRA_LENGTH_M / 2.0,
        CrossingPaint::Lines => (LINES_APART_M + LINE_M) / 2.0,
    }
}

/// The strips a crossing paints at `at` (tile units) on a road running along `direction` (a
/// unit vector) `width_m` wide, `metre` tile units a metre there.
pub fn strips(
    feature: u32,
    paint: CrossingPaint,
    at: Point,
    direction: [f64; 2],
    width_m: f64,
    metre: f64,
) -> Vec<Marking> {
    let across = [-direction[1], direction[0]];
    let place = |along_m: f64, across_m: f64| -> Point {
        [
            at[0] + (direction[0] * along_m + across[0] * across_m) * metre,
            at[1] + (direction[1] * along_m + across[1] * across_m) * metre,
        ]
    };
    let strip = |from: Point, to: Point, width_m: f64| Marking {
        feature,
        line: vec![from, to],
        stations: vec![0.0, 1.0],
        pattern: Pattern::Solid,
        width_m,
        metre,
        paint: Paint::Crossing,
        tip: false,
    };
    match paint {
        CrossingPaint::Zebra => {
            // Whole stripes across the width, centred, none over its edges.
            let count = ((width_m + STRIPE_M) / (2.0 * STRIPE_M)).floor() as i64;
            let span = (count as f64) * 2.0 * STRIPE_M - STRIPE_M;
            (0..count)
                .map(|k| {
                    let offset = -span / 2.0 + STRIPE_M / 2.0 + (k as f64) * 2.0 * STRIPE_M;
                    strip(
                        place(-ZEBRA_LENGTH_M / 2.0, offset),
                        place(ZEBRA_LENGTH_M / 2.0, offset),
                        STRIPE_M,
                    )
                })
                .collect()
        }
        CrossingPaint::Lines => [-LINES_APART_M / 2.0, LINES_APART_M / 2.0]
            .iter()
            .map(|&along| {
                strip(
                    place(along, -width_m / 2.0),
                    place(along, width_m / 2.0),
                    LINE_M,
                )
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::osm::tags;

    #[test]
    fn the_markings_tag_wins_then_the_kind_of_crossing_and_the_region() {
        let m = Region::Mediterranean;
        let paint = |pairs: &[(&str, &str)], region| paint(&tags(pairs), region);
        assert_eq!(
            paint(&[("highway", "crossing")], m),
            Some(CrossingPaint::Zebra)
        );
        assert_eq!(
            paint(&[("highway", "crossing"), ("crossing", "unmarked")], m),
            None
        );
        assert_eq!(
            paint(
                &[
                    ("highway", "crossing"),
                    ("crossing", "unmarked"),
                    ("crossing:markings", "zebra")
                ],
                m
            ),
            Some(CrossingPaint::Zebra)
        );
        assert_eq!(
            paint(&[("highway", "crossing"), ("crossing:markings", "no")], m),
            None
        );
        let signals = [("highway", "crossing"), ("crossing", "traffic_signals")];
        assert_eq!(paint(&signals, m), Some(CrossingPaint::Zebra));
        assert_eq!(
            paint(&signals, Region::CentralEurope),
            Some(CrossingPaint::Lines)
        );
        assert_eq!(
            paint(&signals, Region::NorthAmerica),
            Some(CrossingPaint::Lines)
        );
        assert_eq!(paint(&[("highway", "traffic_signals")], m), None);
        assert_eq!(
            paint(&[("highway", "crossing"), ("crossing", "what?")], m),
            Some(CrossingPaint::Zebra)
        );
    }

    #[test]
    fn a_zebra_fills_the_road_with_whole_stripes_and_lines_span_it() {
        let metre = 1e-3;
        let zebra = strips(7, CrossingPaint::Zebra, [0.5, 0.5], [1.0, 0.0], 7.0, metre);
        // 7 m: seven stripes of 0.5 m with gaps, 6.5 m in all, centred.
        assert_eq!(zebra.len(), 7);
        let offsets: Vec<f64> = zebra.iter().map(|s| (s.line[0][1] - 0.5) / metre).collect();
        assert!(
            (offsets[0] + 3.0).abs() < 1e-9 && (offsets[6] - 3.0).abs() < 1e-9,
            "{offsets:?}"
        );
        for stripe in &zebra {
            let length = (stripe.line[1][0] - stripe.line[0][0]) / metre;
            assert!((length - ZEBRA_LENGTH_M).abs() < 1e-9);
            assert_eq!((stripe.feature, stripe.paint), (7, Paint::Crossing));
        }
        let lines = strips(0, CrossingPaint::Lines, [0.5, 0.5], [0.0, 1.0], 6.0, metre);
        assert_eq!(lines.len(), 2);
        let span = (lines[0].line[1][0] - lines[0].line[0][0]).abs() / metre;
        assert!((span - 6.0).abs() < 1e-9, "{span}");
        // A footpath-wide road still gets a stripe.
        assert_eq!(
            strips(0, CrossingPaint::Zebra, [0.5, 0.5], [1.0, 0.0], 0.6, metre).len(),
            1
        );
    }

    #[test]
    fn only_roads_for_traffic_have_their_crossings_painted() {
        assert!(is_painted_road(&tags(&[("highway", "primary_link")])));
        assert!(is_painted_road(&tags(&[("highway", "residential")])));
        assert!(!is_painted_road(&tags(&[("highway", "footway")])));
        assert!(!is_painted_road(&tags(&[
            ("highway", "pedestrian"),
            ("area", "yes")
        ])));
    }
}
