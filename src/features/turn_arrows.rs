//! Arrows painted in the lanes before the end of a road, from `turn:lanes` (one-way roads) and
//! `turn:lanes:forward`/`turn:lanes:backward`: each lane's entry (`|`-separated, left to right
//! as its traffic sees them) lists its turns (`;`-separated): `through`, `left`, `right`, their
//! `slight_` and `sharp_` kinds. `none`, an empty entry, `reverse` and the `merge_to_` kinds
//! paint nothing; an unknown value is logged and left out.
//!
//! An arrow is 5 m long (a shaft and a head per turn: straight on, or bent 35°, 65° or 100°
//! towards its side), in the middle of its lane, its tip 6 m before the end of the road's
//! drawn surface where the lane's traffic leaves it (cut back before a junction), laid from
//! the surface's own stations so every tile lays it alike.

use super::markings::{LanePlan, Marking, Paint, Pattern, Turn};
use super::road_network::RoadSurface;
use crate::geometry::Point;

/// Length of an arrow along its lane, and the gap between its tip and the surface's end,
/// metres.
const ARROW_M: f64 = 5.0;
const TIP_CLEAR_M: f64 = 6.0;
/// Width of a shaft, and of a head at its base, metres.
const SHAFT_M: f64 = 0.15;
const HEAD_M: f64 = 0.6;
/// Length of a head, and of a bent shaft past the bend, metres.
const HEAD_LENGTH_M: f64 = 1.2;
const BENT_M: f64 = 0.3;
/// How far before the straight head a turn's shaft bends off, metres.
const BEND_BEFORE_M: f64 = 0.6;
/// Farthest the drawn surface may end short of the way's node for its lanes to get arrows,
/// metres.
const REACH_M: f64 = 30.0;

/// The arrows painted in the lanes of `plan` on a road's surface `width_m` wide whose way's
/// line is `length` long (tile units), `metre` one metre there.
pub fn of_plan(
    feature: u32,
    road: &RoadSurface,
    plan: &LanePlan,
    (width_m, length, metre): (f64, f64, f64),
) -> Vec<Marking> {
    let (from, to) = plan.motor_lanes(width_m);
    let centre = plan.centre_share(width_m);
    let mut out = Vec::new();
    for (k, turns) in plan.turns.iter().enumerate() {
        let Some(turns) = turns else {
            continue;
        };
        let (sense, shares, end) = if k == 1 {
            (1.0, [centre, to], length)
        } else {
            (-1.0, [centre, from], 0.0)
        };
        let lanes = Lanes {
            sense,
            shares,
            turns,
        };
        out.extend(arrows(feature, road, &lanes, end, metre));
    }
    out
}

/// The lanes of one direction of a road and their turns.
#[derive(Debug, Clone, PartialEq)]
pub struct Lanes<'a> {
    /// 1 along the way, −1 against it.
    pub sense: f64,
    /// The shares of the width (from the way's left) the direction's lanes lie between, the
    /// first one the lanes' left as their traffic sees it.
    pub shares: [f64; 2],
    pub turns: &'a [Vec<Turn>],
}

/// The arrows of `lanes` on a road's surface, as strips of `feature`; `end` the station
/// (distance along the way's line) of the way's node the lanes' traffic drives to, `metre`
/// one metre in tile units.
pub fn arrows(
    feature: u32,
    road: &RoadSurface,
    lanes: &Lanes<'_>,
    end: f64,
    metre: f64,
) -> Vec<Marking> {
    let sense = lanes.sense;
    let Some(drawn_end) = road.drawn_end_before(end, -sense, REACH_M * metre) else {
        return Vec::new();
    };
    let tip = drawn_end - sense * TIP_CLEAR_M * metre;
    let start = tip - sense * ARROW_M * metre;
    let count = lanes.turns.len() as f64;
    let mut out = Vec::new();
    for (k, turns) in lanes.turns.iter().enumerate() {
        if turns.is_empty() {
            continue;
        }
        let share =
            lanes.shares[0] + (lanes.shares[1] - lanes.shares[0]) * (k as f64 + 0.5) / count;
        let (Some([from, _]), Some([to, _])) = (
            road.across_at(start, [share, share]),
            road.across_at(tip, [share, share]),
        ) else {
            continue;
        };
        out.extend(glyph(feature, from, to, turns, metre));
    }
    out
}

/// One lane's arrow from `from` to `to` (its length), with a head for each of `turns`.
fn glyph(feature: u32, from: Point, to: Point, turns: &[Turn], metre: f64) -> Vec<Marking> {
    let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
    let length = dx.hypot(dy);
    if length <= 0.0 {
        return Vec::new();
    }
    let (d, right) = ([dx / length, dy / length], [-dy / length, dx / length]);
    // A point `along` metres down the lane and `across` metres to the right of its middle.
    let at = |along: f64, across: f64| -> Point {
        [
            from[0] + (d[0] * along + right[0] * across) * metre,
            from[1] + (d[1] * along + right[1] * across) * metre,
        ]
    };
    let line = |points: Vec<Point>, width_m: f64, tip: bool| Marking {
        feature,
        stations: (0..points.len()).map(|k| k as f64).collect(),
        line: points,
        pattern: Pattern::Solid,
        width_m,
        metre,
        paint: Paint::Line,
        tip,
    };
    let straight = ARROW_M - HEAD_LENGTH_M;
    let bend = ARROW_M - HEAD_LENGTH_M - BENT_M - BEND_BEFORE_M;
    let mut out = Vec::new();
    let through = turns.iter().any(|t| t.0 == 0.0);
    let shaft_end = if through { straight } else { bend };
    out.push(line(vec![at(0.0, 0.0), at(shaft_end, 0.0)], SHAFT_M, false));
    for turn in turns {
        if turn.0 == 0.0 {
            out.push(line(
                vec![at(straight, 0.0), at(ARROW_M, 0.0)],
                HEAD_M,
                true,
            ));
            continue;
        }
        let (sin, cos) = turn.0.to_radians().sin_cos();
        let toward = |base: (f64, f64), m: f64| (base.0 + cos * m, base.1 + sin * m);
        let knee = toward((bend, 0.0), BENT_M);
        let head = toward(knee, HEAD_LENGTH_M);
        out.push(line(
            vec![at(bend, 0.0), at(knee.0, knee.1)],
            SHAFT_M,
            false,
        ));
        out.push(line(
            vec![at(knee.0, knee.1), at(head.0, head.1)],
            HEAD_M,
            true,
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::markings::parse_turns;

    #[test]
    fn turn_lanes_are_read_lane_by_lane_and_odd_values_paint_nothing() {
        let lanes = parse_turns("left|through;right|").unwrap();
        assert_eq!(lanes.len(), 3);
        assert_eq!(lanes[0], vec![Turn(-65.0)]);
        assert_eq!(lanes[1], vec![Turn(0.0), Turn(65.0)]);
        assert!(lanes[2].is_empty());
        assert_eq!(parse_turns("||"), None);
        assert_eq!(parse_turns("none|reverse|sideways"), None);
        assert_eq!(parse_turns(""), None);
    }

    #[test]
    fn a_through_arrow_is_a_shaft_and_a_head_ending_at_its_tip() {
        let arrow = glyph(0, [0.0, 0.0], [5.0, 0.0], &[Turn(0.0)], 1.0);
        assert_eq!(arrow.len(), 2);
        assert!(!arrow[0].tip && arrow[1].tip);
        assert_eq!(arrow[1].line.last(), Some(&[5.0, 0.0]));
        // A left turn bends its head to the left of the lane (north of an eastward lane).
        let left = glyph(0, [0.0, 0.0], [5.0, 0.0], &[Turn(-65.0)], 1.0);
        let head = left.iter().find(|m| m.tip).unwrap();
        assert!(head.line[1][1] < -1.0, "{:?}", head.line);
    }
}
