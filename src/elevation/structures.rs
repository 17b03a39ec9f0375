//! Bridges and tunnels settled by the linear program, one structure group at a time.
//!
//! Each chain of a group (see [`crate::osm::structures`]) becomes a row of elevation
//! variables at its nodes and at stations at most [`BRIDGE_STATION_SPACING_M`] or
//! [`TUNNEL_STATION_SPACING_M`] apart (a long straight span gets room to curve). The variables are the deck's top for a bridge and the
//! floor for a tunnel. A chain end that meets no other chain meets the ground there (an
//! abutment or a portal) and is fixed to the terrain; chains that share a node are equal
//! there. Everything else is asked of the LP (thesis §4.2–4.3):
//!
//! - to stay near the straight line between its ends (a small weight: a deck does not follow
//!   the valley it spans, the flaw the thesis and OSM2World show), and to change its slope as
//!   little as possible (smoothness, so ramps and decks come out as smooth as the data lets
//!   them instead of peaked, §4.3.3 figure 4.9);
//! - soft constraints from tags and defaults: a bridge's underside above what it crosses by
//!   the clearance, its deck above the ground; a tunnel's roof under the ground with some
//!   cover, one tunnel under another with rock between them; no grade steeper than the class
//!   allows; the grade `incline=*` tags.
//!
//! A group is solved from the whole group alone, so every tile that shows a part of a bridge
//! gets the same elevations for it.

pub use crate::elevation::constraints::{ConstraintKind, ConstraintReport};

use std::collections::HashMap;

use crate::elevation::constraints::{ConstraintBuilder, GradeAsked};
use crate::elevation::lp::{Constraint, Relation};
use crate::elevation::settled::{Level, Rule, Stations};
use crate::elevation::solutions::Solutions;
use crate::features::structures::{self as tags, WayTraits};
use crate::features::{widened_surface, FeatureClass, FeatureSettings, Projection, Surface};
use crate::geometry::{distance, Point, Polygon, Rect};
use crate::osm::structures::{Chain, Crossed, Crossing, Group, StructureKind};
use crate::osm::Way;
use crate::terrain::Elevation;

mod ground_cuts;
pub use ground_cuts::{ground_cuts, GroundCut, GroundCuts};

/// Greatest distance between two stations of a bridge, metres: room for a deck to curve.
pub const BRIDGE_STATION_SPACING_M: f64 = 5.0;
/// Greatest distance between two stations of a tunnel, metres: tunnels are long and their
/// floors follow the terrain far less closely.
pub const TUNNEL_STATION_SPACING_M: f64 = 10.0;
/// Rock between a tunnel's roof and a tunnel under it, metres.
const ROCK_BETWEEN_TUNNELS_M: f64 = 1.0;
/// Ground over a tunnel's roof, metres, on top of the mesh's error bound.
pub const TUNNEL_COVER_M: f64 = 0.5;

/// Weight of the pull towards the line between a chain's ends, per metre of elevation and
/// metre of chain.
const CHORD_WEIGHT: f64 = 0.01;
/// Weight of a change of slope (rise per run) at a station.
const SMOOTHNESS_WEIGHT: f64 = 100.0;
/// Penalties per metre of violation: clearances are worth the most, grades (charged as
/// [`ConstraintBuilder`] charges them) less, the ground over a tunnel (which the portals'
/// approaches must break) and under a bridge least, per metre of chain.
const CLEARANCE_PENALTY: f64 = 10_000.0;
const GROUND_PENALTY_PER_M: f64 = 10.0;

/// A chain settled: its stations and their elevations.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    pub kind: StructureKind,
    pub layer: i32,
    /// Stations in global tile units.
    pub points: Vec<Point>,
    /// Distance of each station from the chain's start, metres.
    pub along_m: Vec<f64>,
    /// The deck's top (a bridge) or the floor (a tunnel), metres.
    pub elevations: Vec<f64>,
    /// The terrain at each station, metres.
    pub terrain: Vec<f64>,
    /// For each station, the index (into all ways) of the way of the segment that starts
    /// there; the last station repeats the last segment's.
    pub ways: Vec<u32>,
    /// Whether the first and the last station meet the ground (an abutment or a portal).
    pub grounded: [bool; 2],
    /// Where the chain crosses over something (metres from its start).
    pub crossings_m: Vec<f64>,
}

/// One point of a settled chain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Station {
    /// Global tile units.
    pub point: Point,
    pub along_m: f64,
    pub elevation: f64,
    pub terrain: f64,
    /// Index (into all ways) of the way the station lies on.
    pub way: u32,
}

impl Profile {
    /// The stations between `from_m` and `to_m` along the chain, with the two ends
    /// interpolated.
    pub fn stretch(&self, from_m: f64, to_m: f64) -> Vec<Station> {
        let n = self.points.len();
        let at = |i: usize| Station {
            point: self.points[i],
            along_m: self.along_m[i],
            elevation: self.elevations[i],
            terrain: self.terrain[i],
            way: self.ways[i],
        };
        let between = |along: f64| -> Station {
            let k = self
                .along_m
                .partition_point(|&a| a <= along)
                .clamp(1, n - 1);
            let (a, b) = (at(k - 1), at(k));
            let span = b.along_m - a.along_m;
            let t = if span > 0.0 {
                ((along - a.along_m) / span).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let lerp = |x: f64, y: f64| x + t * (y - x);
            Station {
                point: [lerp(a.point[0], b.point[0]), lerp(a.point[1], b.point[1])],
                along_m: along,
                elevation: lerp(a.elevation, b.elevation),
                terrain: lerp(a.terrain, b.terrain),
                way: a.way,
            }
        };
        if n < 2 || to_m <= from_m {
            return Vec::new();
        }
        let mut out = vec![between(from_m)];
        out.extend(
            (0..n)
                .filter(|&i| self.along_m[i] > from_m && self.along_m[i] < to_m)
                .map(at),
        );
        out.push(between(to_m));
        out
    }
}

/// A group settled, with what its LP took.
#[derive(Debug, Clone, Default)]
pub struct Settled {
    pub profiles: Vec<Profile>,
    pub variables: usize,
    pub constraints: usize,
    pub components: usize,
    /// Every soft constraint with its violation (0 for those that hold).
    pub reports: Vec<ConstraintReport>,
    /// Components the solver failed on (they keep the line between their ends).
    pub failed: usize,
}

impl Settled {
    /// The soft constraints that had to give way by more than `tolerance` metres.
    pub fn violations(&self, tolerance: f64) -> impl Iterator<Item = &ConstraintReport> {
        self.reports.iter().filter(move |r| r.violation > tolerance)
    }
}

/// How elevation is read along a chain: the variable at each station.
struct Row {
    first: usize,
    /// Station index of each node of the chain.
    node_station: Vec<usize>,
}

/// Settles one group. `terrain` is read in the projection's global tile units;
/// `surface_margin_m` is how far the drawn ground may lie above the terrain (the mesh's error
/// bound), kept as extra room under bridges and over tunnels.
pub fn settle(
    group: &Group,
    ways: &[Way],
    terrain: &dyn Elevation,
    projection: &Projection,
    settings: &FeatureSettings,
    surface_margin_m: f64,
    memo: &Solutions,
) -> Settled {
    let mut settling = Settling {
        group,
        ways,
        terrain,
        projection,
        settings,
        surface_margin_m,
        traits: group_traits(group, ways, settings),
        builder: ConstraintBuilder::default(),
        profiles: Vec::new(),
        rows: Vec::new(),
    };
    for chain in &group.chains {
        settling.add_chain(chain);
    }
    settling.join_chains();
    let foundations = Foundations::new(group, projection);
    for c in 0..group.chains.len() {
        settling.add_grades_and_smoothness(c);
        settling.add_ground_bounds(c, &foundations);
    }
    for crossing in &group.crossings {
        settling.add_crossing(crossing);
    }
    settling.solve(memo)
}

/// A group on its way to the LP: what it is settled from, the problem so far, and each chain's
/// stations and variables (the profiles wait for their elevations until the problem is solved).
struct Settling<'a> {
    group: &'a Group,
    ways: &'a [Way],
    terrain: &'a dyn Elevation,
    projection: &'a Projection,
    settings: &'a FeatureSettings,
    surface_margin_m: f64,
    /// What the tags say of each way the group is made of or crosses, read once.
    traits: HashMap<u32, WayTraits>,
    builder: ConstraintBuilder,
    profiles: Vec<Profile>,
    rows: Vec<Row>,
}

impl Settling<'_> {
    /// What the tags say of way `way` (an index into the ways).
    fn traits(&self, way: u32) -> WayTraits {
        self.traits
            .get(&way)
            .copied()
            .unwrap_or_else(|| WayTraits::of(&self.ways[way as usize], self.settings))
    }

    /// A chain's stations and their variables, with targets on the line between the chain's
    /// ends and weights by the length each station stands for.
    fn add_chain(&mut self, chain: &Chain) {
        let (profile, node_station) = stations(chain, self.terrain, self.projection);
        let problem = &mut self.builder.problem;
        self.rows.push(Row {
            first: problem.targets.len(),
            node_station,
        });
        let n = profile.points.len();
        let (h0, h1) = (profile.terrain[0], profile.terrain[n - 1]);
        let length = profile.along_m[n - 1].max(1e-9);
        for i in 0..n {
            let share = profile.along_m[i] / length;
            let before = if i > 0 {
                profile.along_m[i] - profile.along_m[i - 1]
            } else {
                0.0
            };
            let after = if i + 1 < n {
                profile.along_m[i + 1] - profile.along_m[i]
            } else {
                0.0
            };
            problem.variable(
                h0 + share * (h1 - h0),
                CHORD_WEIGHT * (before + after) / 2.0,
            );
        }
        self.profiles.push(profile);
    }

    /// Chains that share a node are equal there; an end that meets no other chain is on the
    /// ground (an abutment or a portal).
    fn join_chains(&mut self) {
        let chains = &self.group.chains;
        let problem = &mut self.builder.problem;
        let mut at_node: std::collections::HashMap<i64, usize> = std::collections::HashMap::new();
        for (c, chain) in chains.iter().enumerate() {
            for (k, &node) in chain.nodes.iter().enumerate() {
                let variable = self.rows[c].first + self.rows[c].node_station[k];
                match at_node.get(&node) {
                    Some(&other) => problem.constraints.push(Constraint {
                        terms: vec![(variable, 1.0), (other, -1.0)],
                        kind: Relation::Equal,
                        rhs: 0.0,
                        penalty: None,
                        label: u32::MAX,
                    }),
                    None => {
                        at_node.insert(node, variable);
                    }
                }
            }
        }
        for (c, chain) in chains.iter().enumerate() {
            let shared = |node: i64| {
                chains
                    .iter()
                    .enumerate()
                    .any(|(d, other)| d != c && other.nodes.contains(&node))
            };
            let last = chain.nodes.len() - 1;
            for (end, k) in [(0, 0), (1, last)] {
                if !shared(chain.nodes[k]) {
                    let station = self.rows[c].node_station[k];
                    self.profiles[c].grounded[end] = true;
                    problem.fix(
                        self.rows[c].first + station,
                        self.profiles[c].terrain[station],
                    );
                }
            }
        }
    }

    /// The grade each way of chain `c` asks along it, and its change of slope at each station.
    fn add_grades_and_smoothness(&mut self, c: usize) {
        let (profile, first) = (&self.profiles[c], self.rows[c].first);
        let n = profile.points.len();
        for i in 0..n.saturating_sub(1) {
            let way = &self.ways[profile.ways[i] as usize];
            let run = profile.along_m[i + 1] - profile.along_m[i];
            let reversed = self.group.chains[c]
                .ways
                .iter()
                .find(|w| w.way == profile.ways[i])
                .is_some_and(|w| w.reversed);
            let asked = GradeAsked::of(self.traits(profile.ways[i]).slope, reversed);
            self.builder.grade(
                &asked,
                (way.id, profile.points[i]),
                [first + i, first + i + 1],
                run,
            );
        }
        for i in 1..n.saturating_sub(1) {
            self.builder.smoothness(
                [first + i - 1, first + i, first + i + 1],
                [
                    profile.along_m[i] - profile.along_m[i - 1],
                    profile.along_m[i + 1] - profile.along_m[i],
                ],
                SMOOTHNESS_WEIGHT,
            );
        }
    }

    /// At each inner station of chain `c`, a bridge's deck above the ground, or a tunnel's roof
    /// under it with its cover (or under the foundations over it); charged by the length the
    /// station stands for.
    fn add_ground_bounds(&mut self, c: usize, foundations: &Foundations) {
        let (profile, first) = (&self.profiles[c], self.rows[c].first);
        let n = profile.points.len();
        for i in 1..n.saturating_sub(1) {
            let l1 = profile.along_m[i] - profile.along_m[i - 1];
            let l2 = profile.along_m[i + 1] - profile.along_m[i];
            if l1 <= 0.0 || l2 <= 0.0 {
                continue;
            }
            let way = &self.ways[profile.ways[i] as usize];
            let penalty = GROUND_PENALTY_PER_M * (l1 + l2) / 2.0;
            let (kind, relation, bound) = match profile.kind {
                StructureKind::Bridge => (
                    ConstraintKind::AboveGround,
                    Relation::AtLeast,
                    profile.terrain[i],
                ),
                StructureKind::Tunnel => {
                    // Under a building or a tree, the roof stays below its foundations.
                    let (kind, cover) = match foundations.depth_at(profile.points[i]) {
                        Some(depth) if depth > TUNNEL_COVER_M => {
                            (ConstraintKind::Foundations, depth)
                        }
                        _ => (ConstraintKind::Cover, TUNNEL_COVER_M),
                    };
                    (
                        kind,
                        Relation::AtMost,
                        profile.terrain[i]
                            - self.traits(profile.ways[i]).tunnel_height_m
                            - tags::TUNNEL_ROOF_M
                            - cover
                            - self.surface_margin_m,
                    )
                }
            };
            self.builder.soft(
                (kind, way.id, profile.points[i]),
                vec![(first + i, 1.0)],
                relation,
                bound,
                penalty,
            );
        }
    }

    /// Where on chain `c` a crossing at share `t` of node segment `segment` lies: its elevation
    /// as a combination of the two stations around it, the point, and the way there.
    fn point_on(&self, c: usize, segment: u32, t: f64) -> (Vec<(usize, f64)>, Point, u32) {
        let (row, profile) = (&self.rows[c], &self.profiles[c]);
        let (s0, s1) = (
            row.node_station[segment as usize],
            row.node_station[segment as usize + 1],
        );
        let pieces = (s1 - s0) as f64;
        let position = (t * pieces).clamp(0.0, pieces);
        let j = (position.floor() as usize).min(s1 - s0 - 1);
        let local = position - j as f64;
        let (a, b) = (profile.points[s0 + j], profile.points[s0 + j + 1]);
        let at = [a[0] + local * (b[0] - a[0]), a[1] + local * (b[1] - a[1])];
        let terms = vec![
            (row.first + s0 + j, 1.0 - local),
            (row.first + s0 + j + 1, local),
        ];
        (terms, at, profile.ways[s0 + j])
    }

    /// What a chain crosses: a bridge's underside over the way below it by that way's
    /// clearance, a bridge over a bridge likewise, a tunnel over a tunnel with rock between.
    fn add_crossing(&mut self, crossing: &Crossing) {
        let c = crossing.chain as usize;
        let (terms, at, way) = self.point_on(c, crossing.segment, crossing.t);
        let first = self.rows[c].first;
        let along = terms
            .iter()
            .map(|&(v, share)| share * self.profiles[c].along_m[v - first])
            .sum();
        self.profiles[c].crossings_m.push(along);
        let upper = &self.ways[way as usize];
        let (kind, terms, bound) = match (self.profiles[c].kind, crossing.other) {
            (StructureKind::Bridge, Crossed::Way(below)) => {
                let below_traits = self.traits(below);
                let below = &self.ways[below as usize];
                let Some(clearance) = below_traits.clearance_m else {
                    return;
                };
                if below_traits.layer >= self.profiles[c].layer {
                    return;
                }
                let ground = ground_under(
                    at,
                    self.terrain,
                    self.projection,
                    below,
                    below_traits.width_m,
                ) + self.surface_margin_m;
                let deck = self.traits(way).deck_thickness_m;
                (ConstraintKind::Clearance, terms, ground + clearance + deck)
            }
            (upper_kind, Crossed::Chain { chain, segment, t }) => {
                let (lower_terms, _, lower_way) = self.point_on(chain as usize, segment, t);
                let (kind, gap) = match (upper_kind, self.profiles[chain as usize].kind) {
                    (StructureKind::Bridge, StructureKind::Bridge) => {
                        let Some(clearance) = self.traits(lower_way).clearance_m else {
                            return;
                        };
                        (
                            ConstraintKind::Clearance,
                            clearance + self.traits(way).deck_thickness_m,
                        )
                    }
                    (StructureKind::Tunnel, StructureKind::Tunnel) => (
                        ConstraintKind::TunnelOverTunnel,
                        self.traits(lower_way).tunnel_height_m
                            + tags::TUNNEL_ROOF_M
                            + ROCK_BETWEEN_TUNNELS_M,
                    ),
                    _ => return,
                };
                let mut all = terms;
                all.extend(lower_terms.into_iter().map(|(v, k)| (v, -k)));
                (kind, all, gap)
            }
            (StructureKind::Tunnel, Crossed::Way(_)) => return,
        };
        self.builder.soft(
            (kind, upper.id, at),
            terms,
            Relation::AtLeast,
            bound,
            CLEARANCE_PENALTY,
        );
    }

    /// Solves the group; each profile reads its elevations back from its variables.
    fn solve(mut self, memo: &Solutions) -> Settled {
        let outcome = self.builder.solve(memo);
        for (profile, row) in self.profiles.iter_mut().zip(&self.rows) {
            let first = row.first;
            profile.elevations = outcome.values[first..first + profile.points.len()].to_vec();
        }
        Settled {
            profiles: self.profiles,
            variables: self.builder.problem.targets.len(),
            constraints: self.builder.problem.constraints.len(),
            components: outcome.components,
            reports: self.builder.reports,
            failed: outcome.failed,
        }
    }
}

/// A chain's stations: its nodes, and more between them at most the kind's station spacing
/// apart, each with the terrain under it; and the station of each node.
fn stations(
    chain: &Chain,
    terrain: &dyn Elevation,
    projection: &Projection,
) -> (Profile, Vec<usize>) {
    let mut profile = Profile {
        kind: chain.kind,
        layer: chain.layer,
        points: Vec::new(),
        along_m: Vec::new(),
        elevations: Vec::new(),
        terrain: Vec::new(),
        ways: Vec::new(),
        grounded: [false; 2],
        crossings_m: Vec::new(),
    };
    let mut node_station = Vec::with_capacity(chain.nodes.len());
    let mut along = 0.0;
    for k in 0..chain.positions.len() {
        node_station.push(profile.points.len());
        let a = projection.point(chain.positions[k]);
        let way = chain.ways[chain.segment_way[k.min(chain.segment_way.len() - 1)] as usize].way;
        let Some(&next) = chain.positions.get(k + 1) else {
            profile.points.push(a);
            profile.along_m.push(along);
            profile.ways.push(way);
            break;
        };
        let b = projection.point(next);
        let metre = projection.metres(1.0, (chain.positions[k].lat + next.lat) / 2.0);
        let length_m = (b[0] - a[0]).hypot(b[1] - a[1]) / metre;
        let spacing = match chain.kind {
            StructureKind::Bridge => BRIDGE_STATION_SPACING_M,
            StructureKind::Tunnel => TUNNEL_STATION_SPACING_M,
        };
        let pieces = (length_m / spacing).ceil().max(1.0) as usize;
        for j in 0..pieces {
            let t = j as f64 / pieces as f64;
            profile
                .points
                .push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            profile.along_m.push(along + t * length_m);
            profile.ways.push(way);
        }
        along += length_m;
    }
    profile.terrain = profile
        .points
        .iter()
        .map(|&p| terrain.elevation_uv(p))
        .collect();
    (profile, node_station)
}

/// What reaches down into the ground over a group's tunnels, in tile units.
struct Foundations {
    outlines: Vec<(Polygon, Rect, f64)>,
    points: Vec<(Point, f64)>,
    /// How near a tree a station is under it.
    root_radius: f64,
}

/// A tree's roots reach this far around its trunk, metres.
const ROOT_RADIUS_M: f64 = 3.0;

impl Foundations {
    fn new(group: &Group, projection: &Projection) -> Foundations {
        let mut out = Foundations {
            outlines: Vec::new(),
            points: Vec::new(),
            root_radius: 0.0,
        };
        for above in &group.above {
            let points = projection.points(&above.positions);
            match points.as_slice() {
                [] => {}
                [p] => out.points.push((*p, above.depth_m)),
                _ => {
                    let bounds = Rect::around(&points);
                    let outline = Polygon {
                        outer: points,
                        holes: Vec::new(),
                    };
                    out.outlines.push((outline, bounds, above.depth_m));
                }
            }
        }
        let lat = group.bounds.south;
        out.root_radius = projection.metres(ROOT_RADIUS_M, lat);
        out
    }

    /// How deep the deepest foundation over `p` reaches, metres.
    fn depth_at(&self, p: Point) -> Option<f64> {
        let outlines = self
            .outlines
            .iter()
            .filter(|(outline, bounds, _)| bounds.contains(p) && outline.contains(p))
            .map(|&(_, _, depth)| depth);
        let trees = self
            .points
            .iter()
            .filter(|(q, _)| (q[0] - p[0]).hypot(q[1] - p[1]) <= self.root_radius)
            .map(|&(_, depth)| depth);
        outlines.chain(trees).reduce(f64::max)
    }
}

/// What the tags say of the ways a group is made of and of those it crosses.
fn group_traits(
    group: &Group,
    ways: &[Way],
    settings: &FeatureSettings,
) -> HashMap<u32, WayTraits> {
    let made_of = group
        .chains
        .iter()
        .flat_map(|c| c.ways.iter().map(|w| w.way));
    let crossed = group.crossings.iter().filter_map(|c| match c.other {
        Crossed::Way(way) => Some(way),
        Crossed::Chain { .. } => None,
    });
    made_of
        .chain(crossed)
        .map(|way| (way, WayTraits::of(&ways[way as usize], settings)))
        .collect()
}

/// The highest terrain under a crossed way near a crossing: at the crossing and half the
/// way's width to either side along the chain's normal.
fn ground_under(
    at: Point,
    terrain: &dyn Elevation,
    projection: &Projection,
    below: &Way,
    width_m: f64,
) -> f64 {
    let lat = below.positions.first().map_or(0.0, |p| p.lat);
    let half = projection.metres(width_m / 2.0, lat);
    [
        [0.0, 0.0],
        [half, 0.0],
        [-half, 0.0],
        [0.0, half],
        [0.0, -half],
    ]
    .iter()
    .map(|d| terrain.elevation_uv([at[0] + d[0], at[1] + d[1]]))
    .fold(f64::NEG_INFINITY, f64::max)
}

/// Free length between the end of a tunnel's approach cut and its tube, metres: the steep face
/// of the portal.
pub const PORTAL_FACE_M: f64 = 0.5;
/// Length over which the ground is kept over a tunnel's roof past its portal, metres.
pub const PORTAL_COVER_M: f64 = 6.0;

/// How a tunnel meets the ground along its length, in metres from its start.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TunnelPlan {
    /// Open cuts down to the floor, from a portal end to where the tube fits under the terrain.
    pub ramps: Vec<(f64, f64)>,
    /// Where the ground is raised over the tube's roof (past a portal, and where the LP could
    /// not put the tube deep enough).
    pub raised: Vec<(f64, f64)>,
    /// Where the tube is drawn.
    pub tube: Vec<(f64, f64)>,
    /// Where a portal's opening stands (the inner end of a ramp).
    pub portals: Vec<f64>,
}

/// The height from a tunnel's floor to the top of its roof at each station, metres.
pub fn tube_heights(profile: &Profile, ways: &[Way]) -> Vec<f64> {
    profile
        .ways
        .iter()
        .map(|&w| tags::tunnel_height_of(&ways[w as usize]) + tags::TUNNEL_ROOF_M)
        .collect()
}

/// Plans where a settled tunnel is open, covered and raised. A ramp runs from a portal end
/// until the tube fits under the terrain; if it never does, the whole tunnel is an open cut.
pub fn plan_tunnel(profile: &Profile, ways: &[Way], surface_margin_m: f64) -> TunnelPlan {
    let n = profile.points.len();
    let heights = tube_heights(profile, ways);
    // Room above the roof at each station: negative where the tube would stick out.
    let room: Vec<f64> = (0..n)
        .map(|i| profile.terrain[i] - profile.elevations[i] - heights[i])
        .collect();
    let length = profile.along_m[n - 1];
    let fits_from = |order: &mut dyn Iterator<Item = usize>| -> Option<f64> {
        let mut last: Option<usize> = None;
        for i in order {
            if room[i] >= 0.0 {
                return Some(match last {
                    None => profile.along_m[i],
                    Some(j) => {
                        let share = -room[j] / (room[i] - room[j]);
                        profile.along_m[j] + share * (profile.along_m[i] - profile.along_m[j])
                    }
                });
            }
            last = Some(i);
        }
        None
    };
    let mut plan = TunnelPlan::default();
    // From each end (a portal on the ground, or where the tunnel goes on from a bridge or
    // another tunnel) the way runs in the open until the tube fits under the terrain.
    let (Some(start), Some(end)) = (fits_from(&mut (0..n)), fits_from(&mut (0..n).rev())) else {
        plan.ramps.push((0.0, length));
        return plan;
    };
    // A portal stands where a way comes in from the open; an end joined to another chain
    // deep enough underground has none.
    let portal = [
        profile.grounded[0] || start > 0.0,
        profile.grounded[1] || end < length,
    ];
    let face = |portal: bool| if portal { PORTAL_FACE_M } else { 0.0 };
    let (tube_start, tube_end) = (start + face(portal[0]), end - face(portal[1]));
    if tube_end <= tube_start {
        plan.ramps.push((0.0, length));
        return plan;
    }
    if portal[0] {
        if start > 0.0 {
            plan.ramps.push((0.0, start));
        }
        plan.portals.push(start);
        plan.raised
            .push((tube_start, (tube_start + PORTAL_COVER_M).min(tube_end)));
    }
    if portal[1] {
        if end < length {
            plan.ramps.push((end, length));
        }
        plan.portals.push(end);
        plan.raised
            .push(((tube_end - PORTAL_COVER_M).max(tube_start), tube_end));
    }
    plan.tube.push((tube_start, tube_end));
    // Stretches of the tube without the cover it asked for.
    let covered = |i: usize| room[i] >= TUNNEL_COVER_M + surface_margin_m - 0.01;
    let mut i = 0;
    while i < n {
        if covered(i) {
            i += 1;
            continue;
        }
        let first = i;
        while i < n && !covered(i) {
            i += 1;
        }
        let from = profile.along_m[first.saturating_sub(1)].max(tube_start);
        let to = profile.along_m[i.min(n - 1)].min(tube_end);
        if to > from {
            plan.raised.push((from, to));
        }
    }
    plan.raised.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut merged: Vec<(f64, f64)> = Vec::new();
    for (a, b) in plan.raised.drain(..) {
        match merged.last_mut() {
            Some(last) if a <= last.1 => last.1 = last.1.max(b),
            _ => merged.push((a, b)),
        }
    }
    plan.raised = merged;
    plan
}

#[cfg(test)]
mod tests;
