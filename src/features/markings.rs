//! Lane markings painted on a road on the ground: the lines between its lanes, where `lanes`
//! (and `lanes:forward`/`lanes:backward`, `oneway`, `overtaking`) says how many there are.
//!
//! A road of `n` lanes has `n − 1` lines, at equal shares of its width: between lanes running
//! the same way a dashed lane line, between the two directions the centre line — solid on
//! motorways and trunk roads, on roads of four lanes or more and where `overtaking=no`, dashed
//! elsewhere. Traffic keeps to the right, so a way's backward lanes lie on its left. A road of
//! tertiary class or above that is not one-way and tags no `lanes` has two, so a centre line;
//! service roads, tracks, paths, living streets and residential streets without `lanes` get
//! none. The lines follow the road's surface as drawn (pieces cut back at junctions, bends
//! rounded), so they stop where a junction begins; dashes are laid by the distance along the way, so
//! every tile that draws a way lays the same dashes.

use super::road_network::RoadSurface;
use crate::geometry::Point;
use crate::osm::units::parse_count;
use crate::osm::Tags;

/// Width of a lane line, metres.
pub const LANE_LINE_M: f64 = 0.12;
/// Width of a centre line, metres.
pub const CENTRE_LINE_M: f64 = 0.15;
/// Most lanes a road is drawn with; a tag above it is taken as a mistake.
const MAX_LANES: u32 = 12;

/// How a line is painted along its length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pattern {
    Solid,
    /// Dashes and gaps of these lengths, metres.
    Dashed {
        dash_m: f64,
        gap_m: f64,
    },
}

/// The lanes of a road and how the lines between them are painted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LanePlan {
    pub lanes: u32,
    /// Lanes against the way's direction, on its left.
    pub backward: u32,
    pub centre: Pattern,
    pub lane: Pattern,
}

/// One painted line: its points (global tile units, along the road), how it is painted, its
/// width in metres and one metre in tile units where it lies.
#[derive(Debug, Clone, PartialEq)]
pub struct Marking {
    pub feature: u32,
    pub line: Vec<Point>,
    /// For each point of `line`, the distance along the way's own line from its first node
    /// (tile units) it stands for: dashes are laid by it, so every tile lays the same ones.
    pub stations: Vec<f64>,
    pub pattern: Pattern,
    pub width_m: f64,
    pub metre: f64,
    pub paint: Paint,
}

/// What a marking paints: each is a glTF material of its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Paint {
    /// Lines along the road: lane and centre lines.
    Line,
    /// A pedestrian crossing's stripes or lines ([`super::crossings`]).
    Crossing,
}

/// The tags of a road that decide its lines (its class, lanes, direction and overtaking): the
/// lines' feature carries these, the road's own feature all of them.
pub fn painting_tags(tags: &Tags) -> Tags {
    Tags::from_pairs(tags.iter().filter(|(key, _)| {
        matches!(*key, "highway" | "oneway" | "overtaking")
            || key.starts_with("lanes")
            || key.starts_with("turn:lanes")
    }))
}

/// The lanes of a road from its tags; `None` for a road that gets no lines.
pub fn lane_plan(tags: &Tags) -> Option<LanePlan> {
    let highway = tags.get("highway")?;
    let major = matches!(
        highway,
        "motorway" | "trunk" | "primary" | "secondary" | "tertiary"
    );
    let minor = matches!(
        highway,
        "unclassified"
            | "residential"
            | "road"
            | "busway"
            | "motorway_link"
            | "trunk_link"
            | "primary_link"
            | "secondary_link"
            | "tertiary_link"
    );
    if !(major || minor) || tags.get("area") == Some("yes") {
        return None;
    }
    let oneway = matches!(
        tags.get("oneway"),
        Some("yes" | "1" | "true" | "-1" | "reversible")
    ) || (highway == "motorway" && tags.get("oneway") != Some("no"));
    let count = |key: &str| {
        tags.get(key)
            .and_then(parse_count)
            .filter(|n| (0.0..=f64::from(MAX_LANES)).contains(n))
            .map(|n| n.round() as u32)
    };
    let tagged = count("lanes");
    if tags.get("lanes").is_some() && tagged.is_none() {
        tracing::debug!(lanes = tags.get("lanes"), "lanes not a count; no lines");
    }
    let lanes = match tagged {
        Some(n) => n,
        None if major && !oneway => 2,
        None => return None,
    };
    if lanes < 2 {
        return None;
    }
    let backward = if oneway {
        0
    } else {
        match (count("lanes:backward"), count("lanes:forward")) {
            (Some(b), _) if b < lanes => b,
            (None, Some(f)) if f < lanes => lanes - f,
            _ => lanes / 2,
        }
    };
    let fast = matches!(highway, "motorway" | "trunk");
    let centre = if fast || lanes >= 4 || tags.get("overtaking") == Some("no") {
        Pattern::Solid
    } else {
        Pattern::Dashed {
            dash_m: 3.0,
            gap_m: 6.0,
        }
    };
    let lane = if fast {
        Pattern::Dashed {
            dash_m: 6.0,
            gap_m: 12.0,
        }
    } else {
        Pattern::Dashed {
            dash_m: 3.0,
            gap_m: 6.0,
        }
    };
    Some(LanePlan {
        lanes,
        backward,
        centre,
        lane,
    })
}

/// The lines of `plan` on a road's surface: one per line a stretch of it holds, at its share of
/// the width between the left and right sides of the stretch's pieces.
pub fn along(feature: u32, road: &RoadSurface, plan: &LanePlan, metre: f64) -> Vec<Marking> {
    let mut markings = Vec::new();
    for ((range, _), stations) in road.lines.iter().zip(&road.stations) {
        if stations.len() != range.len() + 1 {
            continue;
        }
        for boundary in 1..plan.lanes {
            let share = f64::from(boundary) / f64::from(plan.lanes);
            let Some(line) = road.line_at(range.clone(), share) else {
                continue;
            };
            let centre = boundary == plan.backward;
            markings.push(Marking {
                feature,
                line,
                stations: stations.clone(),
                pattern: if centre { plan.centre } else { plan.lane },
                width_m: if centre { CENTRE_LINE_M } else { LANE_LINE_M },
                metre,
                paint: Paint::Line,
            });
        }
    }
    markings
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tags(pairs: &[(&str, &str)]) -> Tags {
        Tags::from_pairs(pairs.iter().copied())
    }

    #[test]
    fn a_four_lane_road_has_three_lines_with_a_solid_centre() {
        let plan = lane_plan(&tags(&[("highway", "primary"), ("lanes", "4")])).unwrap();
        assert_eq!((plan.lanes, plan.backward), (4, 2));
        assert_eq!(plan.centre, Pattern::Solid);
        assert!(matches!(plan.lane, Pattern::Dashed { .. }));
    }

    #[test]
    fn a_one_way_road_has_no_centre_line() {
        let plan = lane_plan(&tags(&[
            ("highway", "secondary"),
            ("lanes", "2"),
            ("oneway", "yes"),
        ]))
        .unwrap();
        assert_eq!(plan.backward, 0);
    }

    #[test]
    fn lanes_by_direction_place_the_centre_line() {
        let plan = lane_plan(&tags(&[
            ("highway", "primary"),
            ("lanes", "3"),
            ("lanes:forward", "2"),
        ]))
        .unwrap();
        assert_eq!(plan.backward, 1);
    }

    #[test]
    fn untagged_major_roads_have_a_dashed_centre_line_and_minor_ones_none() {
        let plan = lane_plan(&tags(&[("highway", "tertiary")])).unwrap();
        assert_eq!((plan.lanes, plan.backward), (2, 1));
        assert!(matches!(plan.centre, Pattern::Dashed { .. }));
        assert_eq!(lane_plan(&tags(&[("highway", "residential")])), None);
        assert_eq!(
            lane_plan(&tags(&[("highway", "service"), ("lanes", "2")])),
            None
        );
        assert_eq!(
            lane_plan(&tags(&[("highway", "tertiary"), ("oneway", "yes")])),
            None
        );
    }

    #[test]
    fn odd_lane_tags_give_no_lines_and_no_panic() {
        for lanes in ["0", "-3", "1", "many", "99", "2;3"] {
            let plan = lane_plan(&tags(&[("highway", "residential"), ("lanes", lanes)]));
            assert_eq!(plan, None, "lanes={lanes}");
        }
        let plan = lane_plan(&tags(&[
            ("highway", "primary"),
            ("lanes", "2"),
            ("lanes:backward", "7"),
        ]))
        .unwrap();
        assert_eq!(plan.backward, 1);
    }
}
