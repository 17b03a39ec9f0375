//! Lane markings painted on a road on the ground: the lines between its lanes, where `lanes`
//! (and `lanes:forward`/`lanes:backward`, `oneway`, `overtaking`) says how many there are.
//!
//! A road of `n` lanes has `n − 1` lines, at equal shares of its width: between lanes running
//! the same way a dashed lane line, between the two directions the centre line — solid on
//! motorways and trunk roads, on roads of four lanes or more and where `overtaking=no`, dashed
//! elsewhere. Traffic keeps to the right, so a way's backward lanes lie on its left. A road of
//! tertiary class or above that is not one-way and tags no `lanes` has two, so a centre line;
//! service roads, tracks, paths, living streets and residential streets without `lanes` get
//! none. Motorways and trunk roads (and their links) have a solid edge line along each side.
//! A cycle lane (`cycleway`, `cycleway:both|left|right` = `lane`, `opposite_lane`) is marked off
//! by a line its width (`…:width`, else 1.5 m) inside the edge — solid, or dashed where
//! `…:lane=advisory` — and the lanes for motor traffic share what is left between them. The
//! lines follow the road's surface as drawn (pieces cut back at junctions, bends
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
/// Width of an edge line, and the distance of its middle from the road's edge, metres.
pub const EDGE_LINE_M: f64 = 0.2;
const EDGE_INSET_M: f64 = 0.3;
/// Width of the line marking off a cycle lane: solid, and dashed (advisory), metres.
const CYCLE_LINE_M: f64 = 0.25;
const ADVISORY_LINE_M: f64 = 0.12;
/// Width of a cycle lane whose tags give none, and the range of widths taken as meant, metres.
const CYCLE_LANE_M: f64 = 1.5;
const CYCLE_LANE_RANGE_M: std::ops::RangeInclusive<f64> = 0.8..=3.0;
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
#[derive(Debug, Clone, PartialEq)]
pub struct LanePlan {
    pub lanes: u32,
    /// Lanes against the way's direction, on its left.
    pub backward: u32,
    pub centre: Pattern,
    pub lane: Pattern,
    /// Whether the lines between the lanes are painted (not on a street that tags no `lanes`
    /// and is painted only for its cycle lanes).
    pub lined: bool,
    /// Whether a solid line runs along each edge.
    pub edges: bool,
    /// The cycle lanes on the left and the right of the way.
    pub cycle: [Option<CycleLane>; 2],
    /// The turns of the lanes against the way and along it, each direction's left to right
    /// as its traffic sees them.
    pub turns: [Option<Vec<Vec<Turn>>>; 2],
}

/// A cycle lane along one edge of a road.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleLane {
    pub width_m: f64,
    pub line: Pattern,
}

impl LanePlan {
    /// The shares of a road `width_m` wide, from its left side, where its lanes for motor
    /// traffic begin and end (inside its cycle lanes).
    pub fn motor_lanes(&self, width_m: f64) -> (f64, f64) {
        let share = |lane: Option<CycleLane>| lane.map_or(0.0, |l| l.width_m / width_m.max(1.0));
        let (left, right) = (share(self.cycle[0]), share(self.cycle[1]));
        if left + right >= 0.9 {
            return (0.0, 1.0);
        }
        (left, 1.0 - right)
    }

    /// The share of the width of a road `width_m` wide, from its left side, where the lanes
    /// against the way end: its centre line.
    pub fn centre_share(&self, width_m: f64) -> f64 {
        let (from, to) = self.motor_lanes(width_m);
        from + (to - from) * f64::from(self.backward) / f64::from(self.lanes.max(1))
    }
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
    /// Whether the line narrows to a point at its end (an arrow's head).
    pub tip: bool,
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
            || key.starts_with("cycleway")
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
    let edges = matches!(
        highway,
        "motorway" | "trunk" | "motorway_link" | "trunk_link"
    );
    let cycle = cycle_lanes(tags, oneway);
    let turns = lane_turns(tags, highway == "motorway");
    let turned = match (&turns[0], &turns[1]) {
        (Some(b), Some(f)) => Some(b.len() + f.len()),
        (None, Some(f)) if oneway => Some(f.len()),
        _ => None,
    }
    .and_then(|n| u32::try_from(n).ok())
    .filter(|n| (2..=MAX_LANES).contains(n));
    let (lanes, lined) = match tagged.or(turned) {
        Some(n) => (n, n >= 2),
        None if major && !oneway => (2, true),
        None => (if oneway { 1 } else { 2 }, false),
    };
    if !lined && !edges && cycle == [None, None] && turns == [None, None] {
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
        lined,
        edges,
        cycle,
        turns,
    })
}

/// A way to leave the lane, by its angle from straight on (degrees, negative to the left).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Turn(pub f64);

/// The turns of each lane of one direction, left to right; `None` when the value says nothing
/// to paint.
pub fn parse_turns(value: &str) -> Option<Vec<Vec<Turn>>> {
    let lanes: Vec<Vec<Turn>> = value
        .split('|')
        .map(|lane| lane.split(';').filter_map(turn).collect())
        .collect();
    lanes.iter().any(|l| !l.is_empty()).then_some(lanes)
}

fn turn(value: &str) -> Option<Turn> {
    let angle = match value.trim() {
        "through" => 0.0,
        "slight_left" => -35.0,
        "left" => -65.0,
        "sharp_left" => -100.0,
        "slight_right" => 35.0,
        "right" => 65.0,
        "sharp_right" => 100.0,
        "" | "none" | "reverse" | "merge_to_left" | "merge_to_right" => return None,
        other => {
            tracing::debug!(turn = other, "unknown turn in turn:lanes; not painted");
            return None;
        }
    };
    Some(Turn(angle))
}

/// The turns of a road's lanes, against the way and along it: `turn:lanes:backward` and
/// `turn:lanes:forward`, or `turn:lanes` on a road one-way along the way.
fn lane_turns(tags: &Tags, motorway: bool) -> [Option<Vec<Vec<Turn>>>; 2] {
    let oneway = match tags.get("oneway") {
        Some("yes" | "1" | "true") => true,
        Some(_) => false,
        None => motorway,
    };
    let forward = tags
        .get("turn:lanes:forward")
        .or_else(|| tags.get("turn:lanes").filter(|_| oneway));
    [
        tags.get("turn:lanes:backward")
            .filter(|_| !oneway)
            .and_then(parse_turns),
        forward.and_then(parse_turns),
    ]
}

/// The cycle lanes a road's tags map, left and right of the way: `cycleway` (`lane` on both
/// sides, on the right alone of a one-way road; `opposite_lane` on the left), then
/// `cycleway:both`, `cycleway:left`, `cycleway:right`.
fn cycle_lanes(tags: &Tags, oneway: bool) -> [Option<CycleLane>; 2] {
    let mut sides = [false, false];
    match tags.get("cycleway") {
        Some("lane") if oneway => sides[1] = true,
        Some("lane") => sides = [true, true],
        Some("opposite_lane") => sides[0] = true,
        _ => {}
    }
    if tags.get("cycleway:both") == Some("lane") {
        sides = [true, true];
    }
    for (k, side) in ["left", "right"].iter().enumerate() {
        match tags.get(&format!("cycleway:{side}")) {
            Some("lane" | "opposite_lane") => sides[k] = true,
            Some(_) => sides[k] = false,
            None => {}
        }
    }
    let lane = |side: &str| {
        let key = |rest: &str| {
            tags.get(&format!("cycleway:{side}:{rest}"))
                .or_else(|| tags.get(&format!("cycleway:both:{rest}")))
                .or_else(|| tags.get(&format!("cycleway:{rest}")))
        };
        let width_m = key("width")
            .and_then(crate::osm::units::parse_length_m)
            .filter(|w| CYCLE_LANE_RANGE_M.contains(w))
            .unwrap_or(CYCLE_LANE_M);
        let line = match key("lane") {
            Some("advisory") => Pattern::Dashed {
                dash_m: 1.0,
                gap_m: 1.0,
            },
            _ => Pattern::Solid,
        };
        CycleLane { width_m, line }
    };
    [
        sides[0].then(|| lane("left")),
        sides[1].then(|| lane("right")),
    ]
}

/// One line of a lane plan across a road: where it runs (a share of the road's width from its
/// left side), how it is painted and how wide it is, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanLine {
    pub share: f64,
    pub pattern: Pattern,
    pub width_m: f64,
}

impl PlanLine {
    /// The line painted along `line` (global tile units), whose points stand for `stations`
    /// along the way, `metre` tile units to the metre there.
    pub fn painted(
        &self,
        feature: u32,
        line: Vec<Point>,
        stations: Vec<f64>,
        metre: f64,
    ) -> Marking {
        Marking {
            feature,
            line,
            stations,
            pattern: self.pattern,
            width_m: self.width_m,
            metre,
            paint: Paint::Line,
            tip: false,
        }
    }
}

impl LanePlan {
    /// The lines of the plan on a road `width_m` wide: between the lanes, beside the cycle
    /// lanes and along the edges.
    pub fn lines(&self, width_m: f64) -> Vec<PlanLine> {
        let line = |share, pattern, width_m| PlanLine {
            share,
            pattern,
            width_m,
        };
        let mut lines = Vec::new();
        let (from, to) = self.motor_lanes(width_m);
        if self.lined {
            for boundary in 1..self.lanes {
                let share = from + (to - from) * f64::from(boundary) / f64::from(self.lanes);
                lines.push(if boundary == self.backward {
                    line(share, self.centre, CENTRE_LINE_M)
                } else {
                    line(share, self.lane, LANE_LINE_M)
                });
            }
        }
        for (lane, share) in self.cycle.iter().zip([from, to]) {
            if let Some(lane) = lane {
                let width = match lane.line {
                    Pattern::Solid => CYCLE_LINE_M,
                    Pattern::Dashed { .. } => ADVISORY_LINE_M,
                };
                lines.push(line(share, lane.line, width));
            }
        }
        if self.edges && width_m > 4.0 * EDGE_INSET_M {
            let inset = EDGE_INSET_M / width_m;
            lines.push(line(inset, Pattern::Solid, EDGE_LINE_M));
            lines.push(line(1.0 - inset, Pattern::Solid, EDGE_LINE_M));
        }
        lines
    }
}

/// The lines of `plan` on a road's surface `width_m` wide: one per line a stretch of it holds,
/// at its share of the width between the left and right sides of the stretch's pieces.
pub fn along(
    feature: u32,
    road: &RoadSurface,
    plan: &LanePlan,
    (width_m, metre): (f64, f64),
) -> Vec<Marking> {
    let lines = plan.lines(width_m);
    let mut markings = Vec::new();
    for ((range, _), stations) in road.lines.iter().zip(&road.stations) {
        if stations.len() != range.len() + 1 {
            continue;
        }
        for plan_line in &lines {
            let Some(line) = road.line_at(range.clone(), plan_line.share) else {
                continue;
            };
            markings.push(plan_line.painted(feature, line, stations.clone(), metre));
        }
    }
    markings
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::osm::tags;

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
    fn cycle_lanes_take_their_width_from_the_motor_lanes_and_motorways_get_edge_lines() {
        let plan = lane_plan(&tags(&[
            ("highway", "residential"),
            ("cycleway:right", "lane"),
            ("cycleway:right:lane", "advisory"),
        ]))
        .unwrap();
        assert!(!plan.lined && !plan.edges);
        assert_eq!(plan.cycle[0], None);
        let right = plan.cycle[1].unwrap();
        assert_eq!(right.width_m, 1.5);
        assert!(matches!(right.line, Pattern::Dashed { .. }));
        // 10 m wide: the motor lanes between 0 and 8.5 m, the centre in their middle.
        assert!((plan.centre_share(10.0) - 0.425).abs() < 1e-9);
        let plan = lane_plan(&tags(&[
            ("highway", "secondary"),
            ("cycleway", "lane"),
            ("cycleway:width", "2"),
        ]))
        .unwrap();
        assert!(plan.lined);
        assert_eq!(
            plan.cycle.map(|c| c.map(|c| c.width_m)),
            [Some(2.0), Some(2.0)]
        );
        let one_way = lane_plan(&tags(&[
            ("highway", "residential"),
            ("oneway", "yes"),
            ("cycleway", "lane"),
            ("cycleway:left", "no"),
        ]))
        .unwrap();
        assert_eq!(one_way.cycle.map(|c| c.is_some()), [false, true]);
        let motorway = lane_plan(&tags(&[("highway", "motorway"), ("lanes", "1")])).unwrap();
        assert!(motorway.edges && !motorway.lined);
        assert_eq!(
            lane_plan(&tags(&[("highway", "residential"), ("cycleway", "track")])),
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
