//! Roads on the ground keep to the grade of their class (thesis §4.2, inclines), lie level
//! with the junctions they leave, and stay down under the bridges that cross them.
//!
//! A road on the ground follows the terrain, but the terrain approximates SRTM (a surface model
//! of 30 m cells, with buildings and trees in it): it has bumps no road has and slopes steeper
//! than a road of the class is built. Each ground road way is cut at its joints (nodes it shares
//! with another road or a railway, [`crate::osm::Joints`]), which stay at the terrain. Between
//! two joints the way has a station at each node, where each bend the network rounds begins and
//! ends, and every [`STATION_SPACING_M`] at most. Where the terrain along it is steeper than
//! the class allows ([`crate::features::structures::max_incline`]), where the way is tagged
//! `incline=*`, where the level part at a junction (as far as the network cuts the road back
//! there) would leave a step, or where a bridge over it was settled from lower ground, the
//! stretch is settled by the LP: near the terrain, smooth, level with the junction over the
//! cut, with the class's steepest grade, the tagged grade and the bridge's ground as soft
//! constraints that report what they could not hold; grades are measured along the road as
//! drawn. Stretches within their grade keep the terrain and need no LP. Everything is decided
//! from the whole way and every way at its joints, so two tiles that share a road draw it alike
//! to the bit.

use std::collections::HashMap;

use super::constraints::{ConstraintBuilder, ConstraintKind, ConstraintReport, GradeAsked};
use super::lp::Relation;
use super::solutions::Solutions;
use crate::features::carriageways::road_line;
use crate::features::road_network::{self, Cut, RoadLine, StretchLine};
use crate::features::structures::Slope;
use crate::features::{FeatureSettings, Projection};
use crate::geometry::{bracket, distance_to_segment, distances_along, interpolate, Point, Rect};
use crate::osm::{Joints, RoadGraph, Way};
use crate::terrain::Elevation;

/// Spacing of the stations along a road, metres.
pub const STATION_SPACING_M: f64 = 10.0;
/// Weight of the pull towards the terrain, per metre of elevation and metre of road.
const TERRAIN_WEIGHT: f64 = 1.0;
/// Weight of a change of slope (rise per run) at a station.
const SMOOTHNESS_WEIGHT: f64 = 20.0;
/// Penalty per metre a road under a bridge rises above the ground the bridge cleared (grades
/// are charged as [`ConstraintBuilder`] charges them).
const CLEARANCE_PENALTY: f64 = 10_000.0;
/// The level part at a junction reaches this far beyond the network's cut, metres: the cut is
/// measured along the smoothed line, the level part along the way's own.
const LEVEL_BEYOND_CUT_M: f64 = 0.5;
/// How far along a stretch's line its centre line may begin (the longest cut at a junction,
/// and some), metres.
const FIRST_SAMPLE_REACH_M: f64 = 30.0;
/// A grade within this of the bound holds (rounding of the terrain's samples).
const GRADE_TOLERANCE: f64 = 1e-6;

/// The settled profile of one ground road way.
#[derive(Debug, Clone, PartialEq)]
pub struct WayProfile {
    /// Stations in global tile units: every node and points at most [`STATION_SPACING_M`]
    /// apart between them.
    pub points: Vec<Point>,
    /// Distance of each station from the way's start, tile units.
    pub along: Vec<f64>,
    pub elevations: Vec<f64>,
    pub terrain: Vec<f64>,
    /// One metre in tile units along the way.
    pub metre: f64,
}

impl WayProfile {
    /// The elevation at a distance along the way (tile units), interpolated between stations.
    pub fn at(&self, along: f64) -> f64 {
        interpolate(&self.along, &self.elevations, along)
    }

    /// Where `p` lies along the way (tile units): its nearest point on the segments that
    /// start in `window` (the first of equally near ones).
    fn locate(&self, p: Point, window: std::ops::Range<f64>) -> Option<f64> {
        let mut best: Option<(f64, f64)> = None;
        let first = self
            .along
            .partition_point(|&a| a < window.start)
            .saturating_sub(1);
        for i in first..self.points.len().saturating_sub(1) {
            if self.along[i] > window.end {
                break;
            }
            let (a, b) = (self.points[i], self.points[i + 1]);
            let d = distance_to_segment(p, a, b);
            if best.is_some_and(|(bd, _)| bd <= d) {
                continue;
            }
            let t = share_along(p, a, b);
            best = Some((d, self.along[i] + t * (self.along[i + 1] - self.along[i])));
        }
        best.map(|(_, along)| along)
    }

    /// The profile under a stretch the network drew: `line` is the stretch from node to
    /// node with its bends rounded (and what each of its points stands for along the way),
    /// `centre` the part of it left after the cuts at junctions (the strip's centre line).
    /// Returns elevations every `step` (tile units) or less along `centre`, by distance along
    /// it, each read where on the way its point stands, so a road that comes back near itself
    /// (a hairpin) is never read on its other leg.
    pub fn along_stretch(
        &self,
        line: &StretchLine,
        centre: &[Point],
        step: f64,
    ) -> Vec<(f64, f64)> {
        let points = &line.points;
        let (Some(&first), Some(&total)) = (points.first(), self.along.last()) else {
            return Vec::new();
        };
        if line.stations.len() != points.len() {
            return Vec::new();
        }
        let start = self.locate(first, 0.0..total).unwrap_or(0.0);
        let lengths = distances_along(points);
        // How far along `line` the centre line begins: where its first point falls on the
        // first stretch of `line` (the longest cut is well within that).
        let cut = centre.first().map_or(0.0, |&c| {
            let mut best = (f64::INFINITY, 0.0);
            for k in 0..points.len() - 1 {
                if lengths[k] > FIRST_SAMPLE_REACH_M * self.metre {
                    break;
                }
                let (a, b) = (points[k], points[k + 1]);
                let d = distance_to_segment(c, a, b);
                if d < best.0 {
                    best = (
                        d,
                        lengths[k] + share_along(c, a, b) * (lengths[k + 1] - lengths[k]),
                    );
                }
            }
            best.1
        });
        // Where on the way a distance along `line` stands.
        let station = |at: f64| interpolate(&lengths, &line.stations, at);
        super::settled::samples_along(centre, step)
            .into_iter()
            .map(|(along, _)| (along, self.at(start + station(cut + along))))
            .collect()
    }
}

/// The share of the way from `a` to `b` of the point of the segment nearest `p`.
fn share_along(p: Point, a: Point, b: Point) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1]];
    let len2 = ab[0] * ab[0] + ab[1] * ab[1];
    if len2 > 0.0 {
        (((p[0] - a[0]) * ab[0] + (p[1] - a[1]) * ab[1]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// The ground roads of a tile settled, with what the LP took.
#[derive(Debug, Clone, Default)]
pub struct RoadProfiles {
    pub profiles: HashMap<i64, WayProfile>,
    /// The soft constraints that had to give way.
    pub violations: Vec<ConstraintReport>,
    /// Stretches between joints, and those settled by the LP.
    pub stretches: usize,
    pub settled: usize,
    pub variables: usize,
    pub constraints: usize,
    pub components: usize,
    pub failed: usize,
}

/// The whole data's ways and the joints between them: what a way's junctions are drawn from.
struct Network<'a> {
    all_ways: &'a [Way],
    joints: &'a Joints,
}

/// One way's stations before settling.
struct Draft<'a> {
    way: &'a Way,
    profile: WayProfile,
    stretches: Vec<Stretch>,
}

/// Settles the stretches near `area` (global tile units) of the ground road ways among `ways`
/// (other ways are skipped; stretches away from `area` keep the terrain, as nothing there is
/// drawn from them). `all_ways` and `graph` are the whole data's, so the cut at a junction
/// far from the tile is the one the tiles around that junction draw.
#[allow(clippy::too_many_arguments)]
pub fn settle(
    area: Rect,
    ways: &[&Way],
    all_ways: &[Way],
    graph: &RoadGraph,
    terrain: &dyn Elevation,
    projection: &Projection,
    settings: &FeatureSettings,
    memo: &Solutions,
) -> RoadProfiles {
    let mut builder = ConstraintBuilder::default();
    let mut out = RoadProfiles::default();
    // Per LP stretch: the way, and the range of its variables and stations.
    let mut solved: Vec<(i64, usize, std::ops::Range<usize>)> = Vec::new();
    let mut drafts: Vec<Draft> = Vec::new();

    let joints = &graph.joints;
    let network = Network { all_ways, joints };
    for &way in ways {
        let Some(mut draft) = draft(way, &network, terrain, projection, settings) else {
            continue;
        };
        let bridges = graph
            .under_bridges
            .get(&way.id)
            .map_or(&[][..], Vec::as_slice);
        let under = under_bridges(&draft.profile, bridges, terrain, projection);
        for stretch in std::mem::take(&mut draft.stretches) {
            let near = Rect::around(&draft.profile.points[stretch.stations.clone()]);
            if !near.intersects(&area) {
                continue;
            }
            out.stretches += 1;
            let stations = stretch.stations.clone();
            let stretch = Stretch {
                under: under
                    .iter()
                    .filter(|u| {
                        stations.contains(&u.station) && stations.contains(&(u.station + 1))
                    })
                    .copied()
                    .collect(),
                ..stretch
            };
            if let Some(first) = add_stretch(&mut builder, &mut draft, &stretch) {
                out.settled += 1;
                solved.push((draft.way.id, first, stretch.stations.clone()));
            }
        }
        drafts.push(draft);
    }

    let outcome = builder.solve(memo);
    out.violations = builder
        .reports
        .into_iter()
        .filter(|r| r.violation > 0.0)
        .collect();
    let mut by_way: HashMap<i64, Draft> = drafts.into_iter().map(|d| (d.way.id, d)).collect();
    for (way, first, stations) in solved {
        if let Some(draft) = by_way.get_mut(&way) {
            let values = &outcome.values[first..first + stations.len()];
            draft.profile.elevations[stations].copy_from_slice(values);
        }
    }
    out.profiles = by_way
        .into_iter()
        .map(|(id, draft)| (id, draft.profile))
        .collect();
    out.variables = builder.problem.targets.len();
    out.constraints = builder.problem.constraints.len();
    out.components = outcome.components;
    out.failed = outcome.failed;
    out
}

/// A way's stations, at the terrain, by stretch between joints. A stretch has a station at
/// each of its nodes and where each bend the network rounds begins and ends (so the drawn
/// road's length between two stations is in one proportion to the way's), and more between
/// them at most [`STATION_SPACING_M`] apart.
fn draft<'a>(
    way: &'a Way,
    network: &Network,
    terrain: &dyn Elevation,
    projection: &Projection,
    settings: &FeatureSettings,
) -> Option<Draft<'a>> {
    let joints = network.joints;
    let line = road_line(way, projection, settings)?;
    let cuts = junction_cuts(way, &line, network.all_ways, joints, projection, settings);
    let step = STATION_SPACING_M * line.metre;
    let node_along = distances_along(&line.points);
    // The point at a distance along the line.
    let point_at = |along: f64| -> Point {
        let (k, t) = bracket(&node_along, along);
        let (a, b) = (line.points[k - 1], line.points[k]);
        [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
    };
    let n = line.points.len();
    let mut points: Vec<Point> = Vec::new();
    let mut along: Vec<f64> = Vec::new();
    let mut stretches = Vec::new();
    let mut start = 0;
    for k in 1..n {
        if k + 1 < n && !joints.contains_key(&line.nodes[k]) {
            continue;
        }
        let drawn = road_network::stretch_line(&line.points[start..=k], line.half_width);
        let origin = node_along[start];
        let length = node_along[k] - origin;
        let fixed = [start, k].map(|i| joints.contains_key(&line.nodes[i]));
        // The level parts at the joints, each ending at a station of its own (no further than
        // halfway): the road leaves the level part where the junction's polygon ends.
        let level = [
            level_length(&cuts, start, true, line.metre),
            level_length(&cuts, k, false, line.metre),
        ]
        .map(|l| l.min(length / 2.0));
        let mut breaks: Vec<f64> = node_along[start..=k].iter().map(|a| a - origin).collect();
        breaks.extend(drawn.bends.iter().flat_map(|&(a, b)| [a, b]));
        for (end, at) in [(0, level[0]), (1, length - level[1])] {
            if fixed[end] && level[end] > 0.0 {
                breaks.push(at);
            }
        }
        breaks.sort_by(f64::total_cmp);
        breaks.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
        let first = points.len().saturating_sub(1);
        let mut relative: Vec<f64> = Vec::new();
        for pair in breaks.windows(2) {
            let pieces = ((pair[1] - pair[0]) / step).ceil().max(1.0) as usize;
            relative.extend(
                (0..pieces).map(|j| pair[0] + (pair[1] - pair[0]) * j as f64 / pieces as f64),
            );
        }
        relative.extend(breaks.last().copied());
        // A stretch starts at the station the one before ended at.
        let skip = usize::from(!points.is_empty());
        for &s in &relative[skip..] {
            points.push(point_at(origin + s));
            along.push(origin + s);
        }
        stretches.push(Stretch {
            stations: first..points.len(),
            runs_m: drawn_runs(&drawn, &relative, line.metre),
            fixed,
            level,
            under: Vec::new(),
        });
        start = k;
    }
    let terrain: Vec<f64> = points.iter().map(|&p| terrain.elevation_uv(p)).collect();
    Some(Draft {
        way,
        profile: WayProfile {
            metre: line.metre,
            elevations: terrain.clone(),
            terrain,
            points,
            along,
        },
        stretches,
    })
}

/// How far the network cuts the way back at each of its junctions, drawn from the way and
/// every ground road through its joints.
fn junction_cuts(
    way: &Way,
    line: &RoadLine,
    all_ways: &[Way],
    joints: &Joints,
    projection: &Projection,
    settings: &FeatureSettings,
) -> Vec<Cut> {
    let mut others: Vec<u32> = line
        .nodes
        .iter()
        .filter_map(|node| joints.get(node))
        .flatten()
        .copied()
        .collect();
    others.sort_unstable();
    others.dedup();
    let mut lines = vec![line.clone()];
    lines.extend(
        others
            .into_iter()
            .filter_map(|i| all_ways.get(i as usize))
            .filter(|w| w.id != way.id)
            .filter_map(|w| road_line(w, projection, settings)),
    );
    road_network::cuts(&lines, 0)
}

/// The length (tile units) of the level part at point `index` of the line, on the side the
/// stretch leaves it (`forward`): the network's cut and a little more, or 0 where no junction
/// polygon is drawn.
fn level_length(cuts: &[Cut], index: usize, forward: bool, metre: f64) -> f64 {
    cuts.iter()
        .find(|c| c.index == index && c.forward == forward)
        .map_or(0.0, |c| c.distance + LEVEL_BEYOND_CUT_M * metre)
}

/// How long the road is drawn between each station and the next, metres, for stations at
/// distances `relative` along a stretch whose drawn line is `drawn`: its rounded bends are
/// shorter than the corners they replace, so a grade held along the drawn road holds along
/// the way's own line too.
fn drawn_runs(drawn: &StretchLine, relative: &[f64], metre: f64) -> Vec<f64> {
    let lengths = distances_along(&drawn.points);
    let drawn_at = |s: f64| interpolate(&drawn.stations, &lengths, s);
    relative
        .windows(2)
        .map(|pair| (drawn_at(pair[1]) - drawn_at(pair[0])) / metre)
        .collect()
}

/// A stretch of a way between two joints (or its ends).
struct Stretch {
    stations: std::ops::Range<usize>,
    /// Length of the drawn road from each station to the next, metres.
    runs_m: Vec<f64>,
    /// Whether each end is a joint, held at the terrain.
    fixed: [bool; 2],
    /// Length of the level part at each end, tile units (no more than half the stretch; a
    /// station ends each).
    level: [f64; 2],
    /// Where bridges pass over it.
    under: Vec<Under>,
}

/// Where a bridge passes over a road: between station `station` and the next, at share `t`,
/// no higher than `bound` (the terrain there, which the bridge's clearance was settled from).
#[derive(Debug, Clone, Copy)]
struct Under {
    station: usize,
    t: f64,
    at: Point,
    bound: f64,
}

/// Where the bridges at `crossings` pass over a way.
fn under_bridges(
    profile: &WayProfile,
    crossings: &[crate::osm::LonLat],
    terrain: &dyn Elevation,
    projection: &Projection,
) -> Vec<Under> {
    let Some(&total) = profile.along.last() else {
        return Vec::new();
    };
    crossings
        .iter()
        .filter_map(|&position| {
            let at = projection.point(position);
            let along = profile.locate(at, 0.0..total)?;
            let n = profile.along.len();
            let k = profile
                .along
                .partition_point(|&a| a <= along)
                .clamp(1, n - 1)
                - 1;
            let span = profile.along[k + 1] - profile.along[k];
            let t = if span > 0.0 {
                ((along - profile.along[k]) / span).clamp(0.0, 1.0)
            } else {
                0.0
            };
            Some(Under {
                station: k,
                t,
                at,
                bound: terrain.elevation_uv(at),
            })
        })
        .collect()
}

/// Settles a stretch: at the terrain with its level parts where that keeps the grade (no LP),
/// else as variables of the problem; returns the first variable in that case.
fn add_stretch(
    builder: &mut ConstraintBuilder,
    draft: &mut Draft,
    stretch: &Stretch,
) -> Option<usize> {
    let profile = &mut draft.profile;
    let (s0, s1) = (stretch.stations.start, stretch.stations.end - 1);
    let length = profile.along[s1] - profile.along[s0];
    let along = &profile.along;
    let terrain = &profile.terrain;
    // The stations within the level parts (the one that ends each included: its distance
    // was added to the way's, so it may be off by a rounding).
    let reach = |end: usize| stretch.level[end].min(length / 2.0) * (1.0 + 1e-9);
    let level_at = |i: usize| -> Option<f64> {
        let (from_start, from_end) = (along[i] - along[s0], along[s1] - along[i]);
        if stretch.fixed[0] && (i == s0 || from_start <= reach(0)) {
            Some(terrain[s0])
        } else if stretch.fixed[1] && (i == s1 || from_end <= reach(1)) {
            Some(terrain[s1])
        } else {
            None
        }
    };
    let candidate: Vec<f64> = (s0..=s1)
        .map(|i| level_at(i).unwrap_or(terrain[i]))
        .collect();
    let asked = GradeAsked::of(Slope::of(draft.way), false);
    let run_m = |i: usize| stretch.runs_m[i - s0];
    let too_steep = asked.steepest.is_some_and(|max| {
        (s0..s1).any(|i| {
            (candidate[i + 1 - s0] - candidate[i - s0]).abs() > max * run_m(i) + GRADE_TOLERANCE
        })
    });
    let blocked = stretch.under.iter().any(|u| {
        let (a, b) = (candidate[u.station - s0], candidate[u.station + 1 - s0]);
        a + u.t * (b - a) > u.bound + GRADE_TOLERANCE
    });
    if asked.tagged.is_none() && !too_steep && !blocked {
        profile.elevations[s0..=s1].copy_from_slice(&candidate);
        return None;
    }

    let first = builder.problem.targets.len();
    for (i, &target) in terrain.iter().enumerate().take(s1 + 1).skip(s0) {
        let before = if i > s0 { run_m(i - 1) } else { 0.0 };
        let after = if i < s1 { run_m(i) } else { 0.0 };
        let variable = builder
            .problem
            .variable(target, TERRAIN_WEIGHT * (before + after) / 2.0);
        if let Some(level) = level_at(i) {
            builder.problem.fix(variable, level);
        }
    }
    let var = |i: usize| first + i - s0;
    let way = draft.way.id;
    for i in s0..s1 {
        builder.grade(
            &asked,
            (way, profile.points[i]),
            [var(i), var(i + 1)],
            run_m(i),
        );
    }
    for u in &stretch.under {
        builder.soft(
            (ConstraintKind::Clearance, way, u.at),
            vec![(var(u.station), 1.0 - u.t), (var(u.station + 1), u.t)],
            Relation::AtMost,
            u.bound,
            CLEARANCE_PENALTY,
        );
    }
    for i in s0 + 1..s1 {
        builder.smoothness(
            [var(i - 1), var(i), var(i + 1)],
            [run_m(i - 1), run_m(i)],
            SMOOTHNESS_WEIGHT,
        );
    }
    Some(first)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::osm::LonLat;

    const LAT: f64 = 43.74;
    const LON: f64 = 7.42;

    /// A degree of longitude here, metres (the projection's scale at `LAT`).
    fn metres_per_degree() -> f64 {
        let projection = Projection::new(14);
        let a = projection.point(LonLat { lon: LON, lat: LAT });
        let b = projection.point(LonLat {
            lon: LON + 0.001,
            lat: LAT,
        });
        (b[0] - a[0]) / projection.metres(1.0, LAT) * 1000.0
    }

    /// Terrain as a function of metres east of `LON`.
    struct East(fn(f64) -> f64);
    impl Elevation for East {
        fn elevation_uv(&self, p: [f64; 2]) -> f64 {
            let projection = Projection::new(14);
            let origin = projection.point(LonLat { lon: LON, lat: LAT });
            (self.0)((p[0] - origin[0]) / projection.metres(1.0, LAT))
        }
    }

    /// A way through `(node, metres east, metres north)` points.
    /// A way with its nodes given in metres east and north of (`LON`, `LAT`).
    fn way(id: i64, tags: &[(&str, &str)], nodes: &[(i64, f64, f64)]) -> Way {
        let degree = metres_per_degree();
        let nodes: Vec<(i64, f64, f64)> = nodes
            .iter()
            .map(|&(node, east, north)| (node, LON + east / degree, LAT + north / 111_195.0))
            .collect();
        crate::osm::fixture::way(id, tags, &nodes)
    }

    fn joints(ways: &[Way]) -> Joints {
        let mut out = Joints::new();
        for (i, w) in ways.iter().enumerate() {
            for &node in &w.nodes {
                out.entry(node).or_default().push(i as u32);
            }
        }
        out.retain(|_, ways| ways.len() > 1);
        out
    }

    fn settle_all(ways: &[Way], joints: &Joints, terrain: &dyn Elevation) -> RoadProfiles {
        let graph = RoadGraph {
            joints: joints.clone(),
            under_bridges: Default::default(),
        };
        settle_graph(ways, &graph, terrain)
    }

    fn settle_graph(ways: &[Way], graph: &RoadGraph, terrain: &dyn Elevation) -> RoadProfiles {
        let refs: Vec<&Way> = ways.iter().collect();
        let everywhere = Rect {
            min: [f64::NEG_INFINITY; 2],
            max: [f64::INFINITY; 2],
        };
        settle(
            everywhere,
            &refs,
            ways,
            graph,
            terrain,
            &Projection::new(14),
            &FeatureSettings::default(),
            &Solutions::default(),
        )
    }

    /// A residential street 200 m east (way 1) with a short side street at each end, so both
    /// its ends are joints.
    fn street_with_side_streets() -> Vec<Way> {
        vec![
            way(
                1,
                &[("highway", "residential")],
                &[(1, 0.0, 0.0), (2, 200.0, 0.0)],
            ),
            way(
                2,
                &[("highway", "service")],
                &[(1, 0.0, 0.0), (3, 0.0, 40.0)],
            ),
            way(
                3,
                &[("highway", "service")],
                &[(2, 200.0, 0.0), (4, 200.0, 40.0)],
            ),
        ]
    }

    fn grades(profile: &WayProfile) -> Vec<f64> {
        (0..profile.points.len() - 1)
            .map(|i| {
                let run = (profile.along[i + 1] - profile.along[i]) / profile.metre;
                (profile.elevations[i + 1] - profile.elevations[i]) / run
            })
            .collect()
    }

    /// A residential street rising 10 % end to end over a 6 m hump (a building in the
    /// surface model): the hump's 30 % flanks give way to the class's 15 %, the ends stay at
    /// the terrain, and nothing is reported.
    #[test]
    fn a_bump_steeper_than_the_class_is_smoothed_to_its_grade() {
        let hump = |x: f64| 0.1 * x + (6.0 - 0.3 * (x - 100.0).abs()).max(0.0);
        let terrain = East(hump);
        let ways = street_with_side_streets();
        let settled = settle_all(&ways, &joints(&ways), &terrain);
        let profile = &settled.profiles[&1];
        assert!(settled.settled >= 1);
        assert!(settled.violations.is_empty(), "{:?}", settled.violations);
        let steepest = grades(profile)
            .into_iter()
            .map(f64::abs)
            .fold(0.0, f64::max);
        assert!(steepest <= 0.15 + 1e-4, "steepest grade {steepest}");
        let last = profile.points.len() - 1;
        assert_eq!(profile.elevations[0], profile.terrain[0]);
        assert_eq!(profile.elevations[last], profile.terrain[last]);
        // The hump is cut down, not followed.
        let top = profile.elevations.iter().copied().fold(f64::MIN, f64::max);
        assert!(top < 20.0 + 6.0 - 1.0, "top {top}");
        // The side streets are within their grade: they keep the terrain.
        assert_eq!(
            settled.profiles[&2].elevations,
            settled.profiles[&2].terrain
        );
    }

    /// A street tagged `incline=10%` between two level joints lies level: the tag is the
    /// steepest it gets, not a grade it must keep.
    #[test]
    fn a_tagged_grade_bounds_a_street_between_level_joints() {
        let ways = vec![
            way(
                1,
                &[("highway", "residential"), ("incline", "10%")],
                &[(1, 0.0, 0.0), (2, 100.0, 0.0)],
            ),
            way(
                2,
                &[("highway", "residential")],
                &[(1, 0.0, 0.0), (3, 0.0, 60.0)],
            ),
        ];
        let settled = settle_all(&ways, &joints(&ways), &East(|_| 10.0));
        assert!(settled.violations.is_empty(), "{:?}", settled.violations);
        for id in [1, 2] {
            let profile = &settled.profiles[&id].elevations;
            assert!(
                profile.iter().all(|&h| (h - 10.0).abs() < 1e-6),
                "{profile:?}"
            );
        }
    }

    /// A street tagged `incline=up` whose far joint lies 3 m lower cannot rise: the tag
    /// gives way and is reported, on that way only; the streets beside it keep the ground.
    #[test]
    fn a_contradicted_incline_bends_only_its_way() {
        let terrain = East(|x| 10.0 - 0.03 * x);
        let ways = vec![
            way(
                1,
                &[("highway", "residential"), ("incline", "up")],
                &[(1, 0.0, 0.0), (2, 100.0, 0.0)],
            ),
            way(
                2,
                &[("highway", "residential")],
                &[(1, 0.0, 0.0), (3, 0.0, 60.0)],
            ),
            way(
                3,
                &[("highway", "residential")],
                &[(2, 100.0, 0.0), (4, 100.0, 60.0)],
            ),
            way(
                4,
                &[("highway", "residential")],
                &[(3, 0.0, 60.0), (4, 100.0, 60.0)],
            ),
        ];
        let settled = settle_all(&ways, &joints(&ways), &terrain);
        assert!(!settled.violations.is_empty());
        assert!(settled
            .violations
            .iter()
            .all(|r| r.way == 1 && r.kind == ConstraintKind::TaggedIncline));
        // The other ways keep the terrain, but for their level parts at the junctions.
        for id in [2, 3, 4] {
            let profile = &settled.profiles[&id];
            let ends = [profile.terrain[0], *profile.terrain.last().unwrap()];
            for (i, (&h, &t)) in profile.elevations.iter().zip(&profile.terrain).enumerate() {
                assert!(
                    h == t || ends.contains(&h),
                    "way {id} station {i}: {h} against the terrain's {t}"
                );
            }
            let kept = profile.elevations.iter().zip(&profile.terrain);
            assert!(kept.filter(|(h, t)| h == t).count() * 2 > profile.terrain.len());
        }
        let profile = &settled.profiles[&1];
        assert_eq!(profile.elevations[0], 10.0);
        assert!((profile.elevations.last().unwrap() - 7.0).abs() < 1e-9);
    }

    /// Where a street leaves a junction the network cuts it back; over the cut it lies at
    /// the junction's level, and beyond it keeps its grade.
    #[test]
    fn a_street_lies_level_over_the_cut_at_a_junction() {
        let terrain = East(|x| 0.12 * x);
        let ways = vec![
            way(
                1,
                &[("highway", "primary")],
                &[(1, 0.0, -50.0), (2, 0.0, 0.0), (3, 0.0, 50.0)],
            ),
            way(
                2,
                &[("highway", "residential")],
                &[(2, 0.0, 0.0), (4, 120.0, 0.0)],
            ),
        ];
        let joints = joints(&ways);
        let settled = settle_all(&ways, &joints, &terrain);
        let profile = &settled.profiles[&2];
        let projection = Projection::new(14);
        let settings = FeatureSettings::default();
        let lines: Vec<RoadLine> = ways
            .iter()
            .filter_map(|w| road_line(w, &projection, &settings))
            .collect();
        let cut = road_network::cuts(&lines, 1)
            .into_iter()
            .find(|c| c.index == 0 && c.forward)
            .expect("a cut at the junction")
            .distance;
        assert!(
            cut > 3.0 * profile.metre,
            "the primary's half width, at least"
        );
        let level = profile.terrain[0];
        let reach = cut + (LEVEL_BEYOND_CUT_M + 0.1) * profile.metre;
        let within = profile.along.iter().filter(|&&a| a <= reach).count();
        assert!(within >= 2, "a station ends the level part beyond the node");
        for (i, &along) in profile.along.iter().enumerate() {
            if along <= cut {
                assert_eq!(profile.elevations[i], level, "station {i}");
            }
        }
        // Between the stations too: level all the way to the cut and a little beyond.
        let beyond = cut + 0.4 * profile.metre;
        for k in 0..=20 {
            let along = beyond * f64::from(k) / 20.0;
            let h = profile.at(along);
            assert!((h - level).abs() < 1e-9, "{h} at {along} of the cut {cut}");
        }
        let steepest = grades(profile)
            .into_iter()
            .map(f64::abs)
            .fold(0.0, f64::max);
        assert!(steepest <= 0.15 + 1e-4, "steepest grade {steepest}");
        assert!(settled.violations.is_empty(), "{:?}", settled.violations);
    }

    /// A street across a valley whose 30 % flanks are too steep for it would be filled in,
    /// but a bridge passes over the valley floor: there the street stays down on the ground
    /// the bridge's clearance was settled from.
    #[test]
    fn a_road_under_a_bridge_stays_on_the_ground() {
        let terrain = East(|x| (0.3 * (x - 100.0).abs()).min(15.0));
        let ways = street_with_side_streets();
        let mut graph = RoadGraph {
            joints: joints(&ways),
            under_bridges: Default::default(),
        };
        let floor = |settled: &RoadProfiles| {
            let profile = &settled.profiles[&1];
            profile
                .along
                .iter()
                .zip(&profile.elevations)
                .filter(|(a, _)| (*a / profile.metre - 100.0).abs() < 5.0)
                .map(|(_, &h)| h)
                .fold(f64::INFINITY, f64::min)
        };
        let filled = settle_graph(&ways, &graph, &terrain);
        assert!(
            floor(&filled) > 3.0,
            "the valley filled: {}",
            floor(&filled)
        );
        graph.under_bridges.insert(1, vec![ways[0].positions[0]]);
        graph.under_bridges.get_mut(&1).unwrap()[0].lon =
            (ways[0].positions[0].lon + ways[0].positions[1].lon) / 2.0;
        let bridged = settle_graph(&ways, &graph, &terrain);
        assert!(
            floor(&bridged) < 0.5,
            "under the bridge: {}",
            floor(&bridged)
        );
        assert!(
            bridged
                .violations
                .iter()
                .all(|r| r.kind != ConstraintKind::Clearance || r.violation < 1e-3),
            "{:?}",
            bridged.violations
        );
    }

    /// A stretch that comes back beside itself (a hairpin), drawn with its corners cut and
    /// cut back at its start, reads the profile along its own legs: rising all the way, from
    /// the level at the cut to the way's end.
    #[test]
    fn a_hairpin_is_read_along_its_own_legs() {
        let terrain = East(|_| 0.0);
        let ways = vec![way(
            1,
            &[("highway", "steps")],
            &[(1, 0.0, 0.0), (2, 60.0, 0.0), (3, 60.0, 8.0), (4, 0.0, 8.0)],
        )];
        let mut settled = settle_all(&ways, &Joints::new(), &terrain);
        let profile = settled.profiles.get_mut(&1).expect("profile");
        // A profile rising 1 m per metre along the way.
        profile.elevations = profile.along.iter().map(|a| a / profile.metre).collect();
        let m = profile.metre;
        let projection = Projection::new(14);
        let [a, b, c, d] = [0, 1, 2, 3].map(|k| projection.point(ways[0].positions[k]));
        // Corners rounded as the network rounds them, and the start cut back by 4 m.
        let line = road_network::smooth_along(&[a, b, c, d], 3.0 * m);
        let centre: Vec<Point> = std::iter::once([a[0] + 4.0 * m, a[1]])
            .chain(line.points[1..].iter().copied())
            .collect();
        let read = profile.along_stretch(&line, &centre, 2.0 * m);
        let heights: Vec<f64> = read.iter().map(|&(_, h)| h).collect();
        assert!(heights.windows(2).all(|w| w[1] > w[0]), "{heights:?}");
        assert!((heights[0] - 4.0).abs() < 1e-6, "{heights:?}");
        let end = profile.along.last().unwrap() / m;
        assert!((heights.last().unwrap() - end).abs() < 1e-6, "{heights:?}");
    }
}
