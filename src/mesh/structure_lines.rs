//! The lines painted on bridge decks and tunnel floors: the lane plan of the structure's way
//! ([`crate::features::markings`]) laid across the top of each run of its settled stations, as
//! on a road on the ground. Dashes are laid by the distance along the way's own line from its
//! first node, as on the ground, so a line keeps its rhythm from the road onto the deck and
//! every tile lays the same dashes.

use crate::elevation::settled::Stations;
use crate::features::markings::{LanePlan, Marking};
use crate::geometry::{distance, distances_along, interpolate, lerp, share_along_segment, Point};
use crate::terrain::Elevation;

/// The top of a run of stations: level across, linear in elevation between its stations.
pub struct Top<'a> {
    /// The stations' points along the way (global tile units).
    pub centre: &'a [Point],
    /// The run's edges, one point per station (the way's line widened).
    pub left: &'a [Point],
    pub right: &'a [Point],
    pub elevations: &'a [f64],
    /// Where a point lies along the centre: in the band between two stations' bisectors, as
    /// the deck's faces between them are.
    along: Stations,
    /// The station of each point of the centre.
    starts: Vec<f64>,
}

impl<'a> Top<'a> {
    pub fn new(
        centre: &'a [Point],
        (left, right): (&'a [Point], &'a [Point]),
        elevations: &'a [f64],
    ) -> Top<'a> {
        Top {
            centre,
            left,
            right,
            elevations,
            along: Stations::new(centre),
            starts: distances_along(centre),
        }
    }
}

impl Elevation for Top<'_> {
    /// The elevation of the station line at the station of `p`.
    fn elevation_uv(&self, p: [f64; 2]) -> f64 {
        if self.starts.len() < 2 || self.elevations.len() != self.starts.len() {
            return self.elevations.first().copied().unwrap_or(0.0);
        }
        interpolate(&self.starts, self.elevations, self.along.at(p))
    }
}

/// The lines of `plan` across `top`, a run of stations on a way whose own line is `way_line`
/// (global tile units), the road `width_m` wide and `metre` tile units to the metre there.
pub fn lines(
    feature: u32,
    plan: &LanePlan,
    top: &Top<'_>,
    way_line: &[Point],
    (width_m, metre): (f64, f64),
) -> Vec<Marking> {
    let n = top.centre.len();
    if n < 2 || top.left.len() != n || top.right.len() != n || way_line.len() < 2 {
        return Vec::new();
    }
    let first = station_on(way_line, top.centre[0]);
    let reversed = station_on(way_line, top.centre[n - 1]) < first;
    // Stations follow the way's segments, so the distance along the run is the distance along
    // the way from the run's first point.
    let mut stations: Vec<f64> = distances_along(top.centre)
        .into_iter()
        .map(|d| if reversed { first - d } else { first + d })
        .collect();
    if reversed {
        stations.reverse();
    }
    plan.lines(width_m)
        .into_iter()
        .map(|plan_line| {
            // The plan's shares run from the way's left, which is the run's right when the
            // run goes against the way.
            let share = if reversed {
                1.0 - plan_line.share
            } else {
                plan_line.share
            };
            let mut line: Vec<Point> = top
                .left
                .iter()
                .zip(top.right)
                .map(|(&l, &r)| lerp(l, r, share))
                .collect();
            if reversed {
                line.reverse();
            }
            plan_line.painted(feature, line, stations.clone(), metre)
        })
        .collect()
}

/// The distance along `line` from its first point to the point of it nearest `p`.
fn station_on(line: &[Point], p: Point) -> f64 {
    let along = distances_along(line);
    let mut best = (f64::INFINITY, 0.0);
    for (k, pair) in line.windows(2).enumerate() {
        let t = share_along_segment(p, pair[0], pair[1]);
        let gap = distance(p, lerp(pair[0], pair[1], t));
        if gap < best.0 {
            best = (gap, along[k] + (along[k + 1] - along[k]) * t);
        }
    }
    best.1
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::features::markings::{lane_plan, Pattern};
    use crate::osm::tags;

    /// A straight run 100 units long from west to east, 10 wide, rising 1 per 10 units.
    struct Run {
        centre: Vec<Point>,
        left: Vec<Point>,
        right: Vec<Point>,
        elevations: Vec<f64>,
    }

    impl Run {
        fn new() -> Run {
            let centre: Vec<Point> = (0..=10).map(|k| [f64::from(k) * 10.0, 0.0]).collect();
            // Left of the direction of travel, in a plane whose second axis points south.
            let left = centre.iter().map(|p| [p[0], p[1] - 5.0]).collect();
            let right = centre.iter().map(|p| [p[0], p[1] + 5.0]).collect();
            let elevations = (0..=10).map(f64::from).collect();
            Run {
                centre,
                left,
                right,
                elevations,
            }
        }

        fn top(&self) -> Top<'_> {
            Top::new(&self.centre, (&self.left, &self.right), &self.elevations)
        }
    }

    /// Two lanes forward, one backward: the centre line a third of the way from the way's
    /// left.
    fn three_lanes() -> LanePlan {
        lane_plan(&tags(&[
            ("highway", "primary"),
            ("lanes", "3"),
            ("lanes:forward", "2"),
            ("lanes:backward", "1"),
        ]))
        .unwrap()
    }

    #[test]
    fn a_deck_carries_its_ways_lines_at_their_shares_and_heights() {
        let run = Run::new();
        let top = run.top();
        let plan = three_lanes();
        let way_line = vec![[-50.0, 0.0], [200.0, 0.0]];
        let lines = lines(7, &plan, &top, &way_line, (10.0, 1.0));
        assert_eq!(lines.len(), 2);
        let centre_line = lines
            .iter()
            .find(|m| m.pattern == plan.centre && m.width_m > 0.14)
            .unwrap();
        let offset = centre_line.line[0][1];
        assert!((offset - (-5.0 + 10.0 / 3.0)).abs() < 1e-9, "{offset}");
        assert_eq!(centre_line.stations[0], 50.0);
        assert_eq!(centre_line.stations[10], 150.0);
        assert!((top.elevation_uv([45.0, 2.0]) - 4.5).abs() < 1e-9);
    }

    #[test]
    fn a_run_against_its_way_puts_the_lines_on_the_ways_sides_and_its_dashes_in_order() {
        let run = Run::new();
        // The way runs east to west: its left is the run's right (south, +v).
        let way_line = vec![[200.0, 0.0], [-50.0, 0.0]];
        let lines = lines(7, &three_lanes(), &run.top(), &way_line, (10.0, 1.0));
        let centre_line = lines.iter().find(|m| m.width_m > 0.14).unwrap();
        let offset = centre_line.line[0][1];
        assert!((offset - (5.0 - 10.0 / 3.0)).abs() < 1e-9, "{offset}");
        // Listed along the way: from the run's east end, rising.
        assert_eq!(centre_line.line[0][0], 100.0);
        assert_eq!(centre_line.stations[0], 100.0);
        assert_eq!(centre_line.stations[10], 200.0);
        let lane_line = lines.iter().find(|m| m.width_m < 0.14).unwrap();
        assert!(matches!(lane_line.pattern, Pattern::Dashed { .. }));
    }
}
