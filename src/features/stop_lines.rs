//! Lines painted across a road where its traffic halts: a solid stop line before traffic
//! signals (`highway=traffic_signals`, and a crossing with `crossing=traffic_signals`) and a
//! stop sign (`highway=stop`), a dashed give-way line before a give-way sign
//! (`highway=give_way`).
//!
//! A line spans the lanes of the traffic it halts (right of the centre line for the way's own
//! direction, left of it against it; the whole width of a one-way road) and stands a metre
//! before its node, or before the crossing painted at or just before the node. Which traffic
//! halts: `direction` or `traffic_signals:direction` (`forward`, `backward`) when tagged;
//! otherwise signals and an all-way stop (`stop=all`) halt both, a sign halts the traffic
//! towards the nearer end of its way (it is mapped by the junction it guards). Where the node
//! stands in a junction, the line stands where the road's surface is cut back before it.

use super::crossings::{self, CrossingPaint};
use super::markings::{Marking, Paint, Pattern};
use super::road_network::RoadSurface;
use crate::geometry::{distance, Point};
use crate::osm::Tags;

/// Width of a stop or give-way line, metres.
pub const HALT_LINE_M: f64 = 0.5;
/// Paint left clear between a line and the road's edge or its centre line, metres.
const INSET_M: f64 = 0.15;
/// Distance between a line and the node or crossing it stands before, metres.
const BEFORE_M: f64 = 1.0;
/// Farthest a line is moved back from its node to where a junction's surface ends, metres.
const REACH_M: f64 = 25.0;
/// A crossing this near before a halt (metres) has the line stand before it instead.
const CROSSING_NEAR_M: f64 = 8.0;

/// What kind of line a node asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Halt {
    Stop,
    GiveWay,
}

impl Halt {
    /// The line a node's tags ask for, if any.
    pub fn from_tags(tags: &Tags) -> Option<Halt> {
        match tags.get("highway") {
            Some("traffic_signals" | "stop") => Some(Halt::Stop),
            Some("give_way") => Some(Halt::GiveWay),
            _ if tags.get("crossing") == Some("traffic_signals") => Some(Halt::Stop),
            _ => None,
        }
    }

    fn pattern(self) -> Pattern {
        match self {
            Halt::Stop => Pattern::Solid,
            Halt::GiveWay => Pattern::Dashed {
                dash_m: 0.5,
                gap_m: 0.25,
            },
        }
    }
}

/// The traffic a road carries: which way, and where its centre line lies across it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Flow {
    /// The share of the width (from the left) where the lanes against the way end; 0 for a
    /// road one-way along it, 1 for one one-way against it.
    pub split: f64,
    pub forward: bool,
    pub backward: bool,
}

impl Flow {
    /// The flow of a road from its `oneway` tag, its centre at `split`.
    pub fn of(tags: &Tags, split: f64) -> Flow {
        match tags.get("oneway") {
            Some("yes" | "1" | "true") => Flow {
                split: 0.0,
                forward: true,
                backward: false,
            },
            Some("-1" | "reverse") => Flow {
                split: 1.0,
                forward: false,
                backward: true,
            },
            _ if tags.get("highway") == Some("motorway") && tags.get("oneway") != Some("no") => {
                Flow {
                    split: 0.0,
                    forward: true,
                    backward: false,
                }
            }
            _ => Flow {
                split: split.clamp(0.0, 1.0),
                forward: true,
                backward: true,
            },
        }
    }
}

/// The senses (1 along the way, −1 against it) of the traffic a halt at the `k`-th of `count`
/// nodes of a way stops, from its node's tags.
fn senses(halt: Halt, tags: &Tags, k: usize, count: usize) -> &'static [f64] {
    let tagged = tags
        .get("traffic_signals:direction")
        .or_else(|| tags.get("direction"));
    let signals = tags.get("highway") != Some("stop") && tags.get("highway") != Some("give_way");
    match tagged {
        Some("forward") => &[1.0],
        Some("backward") => &[-1.0],
        Some("both") => &[1.0, -1.0],
        _ if halt == Halt::Stop && (signals || tags.get("stop") == Some("all")) => &[1.0, -1.0],
        _ if 2 * k >= count => &[1.0],
        _ => &[-1.0],
    }
}

/// A node on a road where traffic halts.
pub struct HaltAt<'a> {
    pub halt: Halt,
    pub tags: &'a Tags,
    /// The node's index among the `count` nodes of the way's line, and the distance along the
    /// line to it (tile units).
    pub k: usize,
    pub count: usize,
    pub station: f64,
}

/// The ends of the lines painted for a halt on one road: `crossings` the stations and paint of
/// the crossings painted on it, `width_m` the road's width and `metre` one metre in tile units
/// there.
pub fn lines(
    road: &RoadSurface,
    flow: Flow,
    halt: &HaltAt,
    crossings: &[(f64, CrossingPaint)],
    (width_m, metre): (f64, f64),
) -> Vec<[Point; 2]> {
    let mut out = Vec::new();
    for &sense in senses(halt.halt, halt.tags, halt.k, halt.count) {
        let runs = if sense > 0.0 {
            flow.forward
        } else {
            flow.backward
        };
        // No traffic comes that way: the way's first node halts nothing coming along it.
        let from_start = sense > 0.0 && halt.k == 0;
        let from_end = sense < 0.0 && halt.k + 1 == halt.count;
        if !runs || from_start || from_end {
            continue;
        }
        let Some(station) = stand(road, halt.station, sense, crossings, metre) else {
            continue;
        };
        let inset = INSET_M / width_m.max(1.0);
        let shares = if sense > 0.0 {
            [flow.split + inset, 1.0 - inset]
        } else {
            [inset, flow.split - inset]
        };
        if shares[1] - shares[0] <= 0.0 {
            continue;
        }
        out.extend(road.across_at(station, shares));
    }
    out
}

/// The line a halt paints between `ends`, as the feature `feature`.
pub fn marking(feature: u32, halt: Halt, [a, b]: [Point; 2], metre: f64) -> Marking {
    Marking {
        feature,
        line: vec![a, b],
        stations: vec![0.0, distance(a, b)],
        pattern: halt.pattern(),
        width_m: HALT_LINE_M,
        metre,
        paint: Paint::Line,
        tip: false,
    }
}

/// Where a line for traffic in `sense` stands before a halt at `at` (distances along the
/// way): a metre before it, or before a crossing painted there or just before it, and moved
/// back to where the drawn surface ends when that lies in a junction.
fn stand(
    road: &RoadSurface,
    at: f64,
    sense: f64,
    crossings: &[(f64, CrossingPaint)],
    metre: f64,
) -> Option<f64> {
    let before = |d: f64| at - sense * d;
    // The crossing nearest before the halt, within reach, the line clears.
    let clear = crossings
        .iter()
        .filter_map(|&(station, paint)| {
            let ahead = (at - station) * sense;
            (-0.5 * metre..=CROSSING_NEAR_M * metre)
                .contains(&ahead)
                .then_some(ahead + crossings::depth_m(paint) * metre)
        })
        .fold(0.0, f64::max);
    let station = before(clear + (BEFORE_M + HALT_LINE_M / 2.0) * metre);
    if road.across_at(station, [0.0, 1.0]).is_some() {
        return Some(station);
    }
    let end = road.drawn_end_before(at, -sense, REACH_M * metre)?;
    let station = end - sense * (HALT_LINE_M / 2.0 + INSET_M) * metre;
    road.across_at(station, [0.0, 1.0]).map(|_| station)
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::osm::tags;

    #[test]
    fn signals_halt_both_ways_a_sign_the_traffic_towards_its_junction() {
        let signals = tags(&[("highway", "traffic_signals")]);
        assert_eq!(senses(Halt::Stop, &signals, 3, 5), &[1.0, -1.0]);
        let stop = tags(&[("highway", "stop")]);
        assert_eq!(senses(Halt::Stop, &stop, 4, 5), &[1.0]);
        assert_eq!(senses(Halt::Stop, &stop, 0, 5), &[-1.0]);
        let all = tags(&[("highway", "stop"), ("stop", "all")]);
        assert_eq!(senses(Halt::Stop, &all, 0, 5), &[1.0, -1.0]);
        let one = tags(&[
            ("highway", "traffic_signals"),
            ("traffic_signals:direction", "backward"),
        ]);
        assert_eq!(senses(Halt::Stop, &one, 2, 5), &[-1.0]);
        let give_way = tags(&[("highway", "give_way"), ("direction", "forward")]);
        assert_eq!(Halt::from_tags(&give_way), Some(Halt::GiveWay));
        assert_eq!(senses(Halt::GiveWay, &give_way, 0, 5), &[1.0]);
        assert_eq!(Halt::from_tags(&tags(&[("highway", "crossing")])), None);
        assert_eq!(
            Halt::from_tags(&tags(&[
                ("highway", "crossing"),
                ("crossing", "traffic_signals")
            ])),
            Some(Halt::Stop)
        );
    }

    #[test]
    fn a_one_way_road_halts_across_its_whole_width() {
        let flow = Flow::of(&tags(&[("highway", "primary"), ("oneway", "yes")]), 0.5);
        assert_eq!(
            (flow.split, flow.forward, flow.backward),
            (0.0, true, false)
        );
        let flow = Flow::of(&tags(&[("highway", "primary"), ("oneway", "-1")]), 0.5);
        assert_eq!(
            (flow.split, flow.forward, flow.backward),
            (1.0, false, true)
        );
        let flow = Flow::of(&tags(&[("highway", "primary")]), 0.25);
        assert_eq!(
            (flow.split, flow.forward, flow.backward),
            (0.25, true, true)
        );
    }
}
