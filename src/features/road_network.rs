//! The road network on the ground: ways split where they meet, bends smoothed, and junctions
//! drawn as polygons of their own (thesis §2.3.2 and figure 4.1).
//!
//! Ways meet where they share a node. At such a junction every arm is cut back until the side
//! edges of neighbouring arms have met (the inner corners), and the junction polygon fills the
//! space between the cut ends: its sides are the arms' end caps and the road edges up to the
//! corners, so road surfaces neither overlap nor leave gaps. Where arms meet at so sharp an angle
//! that the corner lies far out, the cut is limited and the arms' surfaces overlap a little,
//! resolved by the ground priority. Bends between junctions become curves
//! (seed 001 §4.4 uses quadratic Bézier curves; circular arcs, as roads are designed, turn evenly) whose radius grows with the road's width, so a road has no sawtooth edges.
//!
//! Everything is decided from the ways alone, in global tile units, so two tiles that see the
//! same junction draw it the same.

use std::collections::HashMap;

use crate::geometry::{self, distance, Point, Polygon, Ring};

/// One road way on the ground, as the network sees it.
#[derive(Debug, Clone)]
pub struct RoadLine {
    /// The way's node ids, one per point.
    pub nodes: Vec<i64>,
    pub points: Vec<Point>,
    /// Half the road's width, tile units.
    pub half_width: f64,
    /// One metre in tile units where the road is.
    pub metre: f64,
}

/// Farthest an arm is cut back from its junction node, metres: junctions of arms that meet at a
/// very sharp angle stop here and let the arms overlap.
const MAX_CUT_BACK_M: f64 = 25.0;
/// Radius of a bend as a multiple of the road's half width.
const BEND_RADIUS_PER_HALF_WIDTH: f64 = 3.0;

/// The surface of one road: its pieces between junctions, widened.
#[derive(Debug, Clone, Default)]
pub struct RoadSurface {
    pub pieces: Vec<Polygon>,
    pub outline: Vec<Vec<Point>>,
    /// The line each run of `pieces` is widened from (a stretch between junctions, from node
    /// to node before its ends are cut back): the left and right corners of a piece lie on
    /// the same bisector of it.
    pub lines: Vec<(std::ops::Range<usize>, StretchLine)>,
    /// For each run of `lines`, the distance along the way's own line (from its first node,
    /// tile units) each boundary of its pieces stands for: one more than the run's pieces. The
    /// same in every tile that draws the way, wherever the tile sees its junctions.
    pub stations: Vec<Vec<f64>>,
}

impl RoadSurface {
    /// The line at `share` of the width across the pieces of `run` (0 its left side, 1 its
    /// right; below 0 or above 1 beside it), from the run's start to its end; `None` for a run
    /// whose pieces are not quads.
    pub fn line_at(&self, run: std::ops::Range<usize>, share: f64) -> Option<Vec<Point>> {
        let pieces = self.pieces.get(run)?;
        if pieces.is_empty() || pieces.iter().any(|p| p.outer.len() != 4) {
            return None;
        }
        let across = |left: Point, right: Point| {
            [
                left[0] + (right[0] - left[0]) * share,
                left[1] + (right[1] - left[1]) * share,
            ]
        };
        // A piece is [left start, left end, right end, right start].
        let mut line = vec![across(pieces[0].outer[0], pieces[0].outer[3])];
        line.extend(pieces.iter().map(|p| across(p.outer[1], p.outer[2])));
        Some(line)
    }

    /// The points at `shares` of the width across the surface where it stands for `station`
    /// (a distance along the way's own line); `None` where no run of quads covers it (inside
    /// a junction, or off the drawn part of the way).
    pub fn across_at(&self, station: f64, shares: [f64; 2]) -> Option<[Point; 2]> {
        self.lines
            .iter()
            .zip(&self.stations)
            .find_map(|((range, _), stations)| {
                let (&first, &last) = (stations.first()?, stations.last()?);
                if station < first || station > last || stations.len() != range.len() + 1 {
                    return None;
                }
                let (k, t) = crate::geometry::bracket(stations, station);
                let piece = self.pieces.get(range.start + k - 1)?;
                if piece.outer.len() != 4 {
                    return None;
                }
                let left = crate::geometry::lerp(piece.outer[0], piece.outer[1], t);
                let right = crate::geometry::lerp(piece.outer[3], piece.outer[2], t);
                Some(shares.map(|share| crate::geometry::lerp(left, right, share)))
            })
    }

    /// The end of the drawn surface nearest `station` on the side `sense` comes from (−1:
    /// lower stations, the way's traffic approaching forward; 1: higher ones), within `reach`:
    /// where a surface cut back before a junction at `station` ends.
    pub fn drawn_end_before(&self, station: f64, sense: f64, reach: f64) -> Option<f64> {
        let ends = self.stations.iter().filter_map(|s| {
            let end = if sense < 0.0 { *s.last()? } else { *s.first()? };
            let gap = (station - end) * -sense;
            (-1e-9..=reach).contains(&gap).then_some((gap, end))
        });
        ends.min_by(|a, b| a.0.total_cmp(&b.0)).map(|(_, end)| end)
    }
}

/// A stretch's line as drawn: from node to node with its bends rounded, and for each point
/// the distance along the way's own line (from the stretch's first node, tile units) it stands
/// for: a rounded bend stands for the corner it replaces.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StretchLine {
    pub points: Vec<Point>,
    pub stations: Vec<f64>,
    /// Where each rounded bend begins and ends, as distances along the way's own line.
    pub bends: Vec<(f64, f64)>,
}

/// A junction's polygon and the roads that meet there (indices into the network's lines).
#[derive(Debug, Clone)]
pub struct Junction {
    pub node: i64,
    pub ring: Ring,
    pub roads: Vec<usize>,
}

/// The network drawn: one surface per input line (possibly empty) and the junction polygons.
#[derive(Debug, Clone, Default)]
pub struct Network {
    pub roads: Vec<RoadSurface>,
    pub junctions: Vec<Junction>,
}

/// Where a piece of a road leaves a junction: the road, the index of the junction's point in
/// it, and whether the piece runs towards higher indices.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
struct ArmKey {
    road: usize,
    index: usize,
    forward: bool,
}

/// The end of a widened piece at a junction.
#[derive(Debug, Clone, Copy)]
struct Cap {
    /// Unit direction away from the junction.
    direction: Point,
    /// The cap's corner on the side a quarter turn counter-clockwise of `direction` (in the
    /// plane's own orientation) and the one clockwise of it.
    plus: Point,
    minus: Point,
    /// The corners the arm would have at the junction node itself, were it not cut back.
    base_plus: Point,
    base_minus: Point,
}

/// A stretch of one road between two break points (junctions or the road's ends).
struct Piece {
    road: usize,
    line: StretchLine,
    /// Distance along the way's own line from its first node to the piece's, tile units.
    offset: f64,
    start: Option<ArmKey>,
    end: Option<ArmKey>,
}

/// Where a piece of a road is cut back at a junction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cut {
    /// The index of the junction's point in the road's line.
    pub index: usize,
    /// Whether the piece runs from there towards higher indices.
    pub forward: bool,
    /// How far along the piece it is cut back, tile units.
    pub distance: f64,
}

/// How far the pieces of `lines[road]` are cut back at its junctions: the cuts [`build`]
/// makes, as long as `lines` holds every line that meets those junctions.
pub fn cuts(lines: &[RoadLine], road: usize) -> Vec<Cut> {
    let arms_at = arms_by_node(lines);
    let (_, cut) = split_and_cut(lines, &arms_at);
    let mut out: Vec<Cut> = cut
        .into_iter()
        .filter(|(arm, _)| arm.road == road)
        .map(|(arm, distance)| Cut {
            index: arm.index,
            forward: arm.forward,
            distance,
        })
        .collect();
    out.sort_by_key(|c| (c.index, c.forward));
    out
}

/// The line a stretch of road between junctions is drawn along: its bends rounded with a
/// radius that grows with the road's half width.
pub fn stretch_line(points: &[Point], half_width: f64) -> StretchLine {
    smooth_along(points, half_width * BEND_RADIUS_PER_HALF_WIDTH)
}

/// Draws the network of `lines`.
pub fn build(lines: &[RoadLine]) -> Network {
    let arms_at = arms_by_node(lines);
    let (pieces, cut) = split_and_cut(lines, &arms_at);
    widen(lines, &arms_at, &pieces, &cut)
}

/// 1–2: the pieces between junctions and how far each arm is cut back.
fn split_and_cut(
    lines: &[RoadLine],
    arms_at: &HashMap<i64, Vec<ArmKey>>,
) -> (Vec<Piece>, HashMap<ArmKey, f64>) {
    let junction_at = |node: i64| arms_at.get(&node).is_some_and(|arms| is_junction(arms));

    // 1. Split at junctions and smooth the bends in between.
    let mut pieces: Vec<Piece> = Vec::new();
    for (road, line) in lines.iter().enumerate() {
        let n = line.points.len();
        let mut start = 0;
        for i in 1..n {
            if i + 1 < n && !junction_at(line.nodes[i]) {
                continue;
            }
            pieces.push(Piece {
                road,
                line: stretch_line(&line.points[start..=i], line.half_width),
                offset: geometry::polyline_length(&line.points[..=start]),
                start: junction_at(line.nodes[start]).then_some(ArmKey {
                    road,
                    index: start,
                    forward: true,
                }),
                end: junction_at(line.nodes[i]).then_some(ArmKey {
                    road,
                    index: i,
                    forward: false,
                }),
            });
            start = i;
        }
    }

    // 2. How far each arm is cut back: to the inner corners with its neighbours, no farther
    //    than the limit, and leaving most of the piece.
    let mut cut: HashMap<ArmKey, f64> = HashMap::new();
    for arms in arms_at.values().filter(|arms| is_junction(arms)) {
        let centre = lines[arms[0].road].points[arms[0].index];
        let rays: Vec<(Point, f64)> = arms
            .iter()
            .map(|a| {
                (
                    arm_direction(&lines[a.road].points, a),
                    lines[a.road].half_width,
                )
            })
            .collect();
        for (arm, distance) in arms.iter().zip(cut_backs(centre, &rays)) {
            cut.insert(*arm, distance.min(MAX_CUT_BACK_M * lines[arm.road].metre));
        }
    }
    for piece in &pieces {
        let length = geometry::polyline_length(&piece.line.points);
        let share = if piece.start.is_some() && piece.end.is_some() {
            0.45
        } else {
            0.9
        };
        for key in [piece.start, piece.end].into_iter().flatten() {
            if let Some(d) = cut.get_mut(&key) {
                *d = d.min(share * length);
            }
        }
    }
    (pieces, cut)
}

/// 3–4: the pieces trimmed and widened, and the junction polygons between them.
fn widen(
    lines: &[RoadLine],
    arms_at: &HashMap<i64, Vec<ArmKey>>,
    pieces: &[Piece],
    cut: &HashMap<ArmKey, f64>,
) -> Network {
    // 3. Trim and widen the pieces, keeping their caps at junctions.
    let mut network = Network {
        roads: vec![RoadSurface::default(); lines.len()],
        junctions: Vec::new(),
    };
    let mut caps: HashMap<ArmKey, Cap> = HashMap::new();
    for piece in pieces {
        let cut_of = |key: Option<ArmKey>| key.and_then(|k| cut.get(&k)).copied().unwrap_or(0.0);
        let Some(trimmed) = trim(&piece.line.points, cut_of(piece.start), cut_of(piece.end)) else {
            continue;
        };
        let half_width = lines[piece.road].half_width;
        let Some((left, right)) = geometry::offset_polyline(&trimmed, half_width) else {
            continue;
        };
        let last = left.len() - 1;
        let base = |at: Point, towards: Point| {
            let side = turn(unit(at, towards));
            (
                [at[0] + side[0] * half_width, at[1] + side[1] * half_width],
                [at[0] - side[0] * half_width, at[1] - side[1] * half_width],
            )
        };
        if let Some(key) = piece.start {
            let (base_plus, base_minus) = base(piece.line.points[0], piece.line.points[1]);
            caps.insert(
                key,
                Cap {
                    direction: unit(trimmed[0], trimmed[1]),
                    plus: right[0],
                    minus: left[0],
                    base_plus,
                    base_minus,
                },
            );
        }
        if let Some(key) = piece.end {
            let (n, m) = (trimmed.len(), piece.line.points.len());
            let (base_plus, base_minus) = base(piece.line.points[m - 1], piece.line.points[m - 2]);
            caps.insert(
                key,
                Cap {
                    direction: unit(trimmed[n - 1], trimmed[n - 2]),
                    plus: left[last],
                    minus: right[last],
                    base_plus,
                    base_minus,
                },
            );
        }
        let surface = &mut network.roads[piece.road];
        let first = surface.pieces.len();
        surface
            .lines
            .push((first..first + last, piece.line.clone()));
        surface.stations.push(
            stations_of(&piece.line, &trimmed)
                .into_iter()
                .map(|s| piece.offset + s)
                .collect(),
        );
        surface.pieces.extend((0..last).map(|i| Polygon {
            outer: vec![left[i], left[i + 1], right[i + 1], right[i]],
            holes: Vec::new(),
        }));
        surface.outline.push(left.clone());
        surface.outline.push(right.clone());
        surface.outline.push(vec![left[0], right[0]]);
        surface.outline.push(vec![left[last], right[last]]);
    }

    // 4. The junction polygons from the caps around each junction node.
    let mut nodes: Vec<(&i64, &Vec<ArmKey>)> = arms_at
        .iter()
        .filter(|(_, arms)| is_junction(arms))
        .collect();
    nodes.sort_by_key(|(node, _)| **node);
    // Each junction's ring is its own: shared out over threads, back in the nodes' order.
    let threads =
        crate::parallel::threads_for(nodes.len(), JUNCTIONS_PER_THREAD, MAX_JUNCTION_THREADS);
    let rings = crate::parallel::map_chunks(&nodes, threads, &|chunk| {
        chunk
            .iter()
            .map(|(_, arms)| {
                let around: Vec<Cap> = arms.iter().filter_map(|a| caps.get(a)).copied().collect();
                let centre = lines[arms[0].road].points[arms[0].index];
                junction_ring(centre, &around)
            })
            .collect()
    });
    for ((&node, arms), ring) in nodes.into_iter().zip(rings) {
        if let Some(ring) = ring {
            let mut roads: Vec<usize> = arms.iter().map(|a| a.road).collect();
            roads.dedup();
            network.junctions.push(Junction { node, ring, roads });
        }
    }
    network
}

/// Junctions below this many get their rings on the calling thread.
const JUNCTIONS_PER_THREAD: usize = 256;
/// Most threads one tile's junctions are spread over.
const MAX_JUNCTION_THREADS: usize = 4;

/// The arms at every node, in road order.
fn arms_by_node(lines: &[RoadLine]) -> HashMap<i64, Vec<ArmKey>> {
    let mut arms: HashMap<i64, Vec<ArmKey>> = HashMap::new();
    for (road, line) in lines.iter().enumerate() {
        let n = line.points.len();
        for (index, &node) in line.nodes.iter().enumerate() {
            let entry = arms.entry(node).or_default();
            if index > 0 {
                entry.push(ArmKey {
                    road,
                    index,
                    forward: false,
                });
            }
            if index + 1 < n {
                entry.push(ArmKey {
                    road,
                    index,
                    forward: true,
                });
            }
        }
    }
    arms
}

/// A node is a junction when more than two arms meet there, or two that are not the two sides
/// of one road's inner vertex (two roads end to end, or a closed road's start).
fn is_junction(arms: &[ArmKey]) -> bool {
    match arms {
        [a, b] => !(a.road == b.road && a.index == b.index),
        arms => arms.len() > 2,
    }
}

fn arm_direction(points: &[Point], arm: &ArmKey) -> Point {
    let next = if arm.forward {
        arm.index + 1
    } else {
        arm.index - 1
    };
    unit(points[arm.index], points[next])
}

fn unit(from: Point, to: Point) -> Point {
    let d = [to[0] - from[0], to[1] - from[1]];
    let len = d[0].hypot(d[1]);
    if len > 0.0 {
        [d[0] / len, d[1] / len]
    } else {
        [1.0, 0.0]
    }
}

/// A quarter turn from the first axis towards the second.
fn turn(d: Point) -> Point {
    [-d[1], d[0]]
}

fn angle(d: Point) -> f64 {
    d[1].atan2(d[0])
}

/// Where the lines `p + s·d` and `q + t·e` meet, as `(s, t)`; `None` when parallel.
fn meet(p: Point, d: Point, q: Point, e: Point) -> Option<(f64, f64)> {
    let det = d[0] * -e[1] + e[0] * d[1];
    if det.abs() < 1e-12 {
        return None;
    }
    let r = [q[0] - p[0], q[1] - p[1]];
    let s = (r[0] * -e[1] + e[0] * r[1]) / det;
    let t = (d[0] * r[1] - d[1] * r[0]) / det;
    Some((s, t))
}

/// Arms this far apart (radians) or more are nearly straight on.
const STRAIGHT_ON: f64 = 5.0 * std::f64::consts::PI / 6.0;
/// Farthest an arm is cut back, in half widths of the junction's widest arm.
const MAX_CUT_BACK_HALF_WIDTHS: f64 = 4.0;

/// How far each ray (a unit direction and a half width from `centre`) must be cut back so that
/// its end cap reaches the inner corners it forms with its neighbours in angular order. Every
/// arm is cut back at least a quarter of the widest half width, so a junction has an area, and
/// at most [`MAX_CUT_BACK_HALF_WIDTHS`].
fn cut_backs(centre: Point, rays: &[(Point, f64)]) -> Vec<f64> {
    let widest = rays.iter().map(|r| r.1).fold(0.0, f64::max);
    let mut cut = vec![widest * 0.25; rays.len()];
    let mut order: Vec<usize> = (0..rays.len()).collect();
    order.sort_by(|&a, &b| angle(rays[a].0).total_cmp(&angle(rays[b].0)));
    for k in 0..order.len() {
        let (i, j) = (order[k], order[(k + 1) % order.len()]);
        if i == j {
            continue;
        }
        let (di, hi) = rays[i];
        let (dj, hj) = rays[j];
        let mut between = angle(dj) - angle(di);
        if between <= 0.0 {
            between += std::f64::consts::TAU;
        }
        if between >= std::f64::consts::PI - 1e-3 {
            continue;
        }
        // Ray i's edge on the side of ray j, and ray j's edge on the side of ray i.
        let (ni, nj) = (turn(di), turn(dj));
        let pi = [centre[0] + ni[0] * hi, centre[1] + ni[1] * hi];
        let pj = [centre[0] - nj[0] * hj, centre[1] - nj[1] * hj];
        if let Some((s, t)) = meet(pi, di, pj, dj) {
            if between > STRAIGHT_ON && s.max(t) > 2.0 * widest {
                // Nearly straight on, the edges of arms of different widths meet far out: the
                // road just changes width there.
                continue;
            }
            cut[i] = cut[i].max(s);
            cut[j] = cut[j].max(t);
        }
    }
    for c in &mut cut {
        *c = c.min(widest * MAX_CUT_BACK_HALF_WIDTHS);
    }
    cut
}

/// The junction polygon around the caps of the arms meeting at `centre`: the union of the parts
/// cut off the arms (each from the node to its cap) and, on the outer side of a bend, the mitre
/// between two arms' edges when it is not too far out, less what the arms beyond their caps
/// cover. Every part touches the node, so the region is star-shaped around it and
/// [`star_union`] traces it. Falls back to the convex hull of the parts, which overlaps the arms
/// but leaves no gap, should that fail.
fn junction_ring(centre: Point, caps: &[Cap]) -> Option<Ring> {
    if caps.len() < 2 {
        return None;
    }
    let mut caps = caps.to_vec();
    caps.sort_by(|a, b| angle(a.direction).total_cmp(&angle(b.direction)));
    let mut parts: Vec<Vec<Point>> = caps
        .iter()
        .map(|c| vec![c.base_minus, c.base_plus, c.plus, c.minus])
        .collect();
    for k in 0..caps.len() {
        let (a, b) = (caps[k], caps[(k + 1) % caps.len()]);
        let mut between = angle(b.direction) - angle(a.direction);
        if between <= 0.0 {
            between += std::f64::consts::TAU;
        }
        if between > std::f64::consts::PI {
            if let Some(mitre) = edge_corner(&a, &b, between) {
                parts.push(vec![centre, a.base_plus, mitre, b.base_minus]);
            }
        }
    }
    // The arms beyond their caps, as long straight strips: the junction stops where it meets
    // them.
    // No part reaches farther from the node than this, so the strips need reach no farther.
    let reach = 2.0
        * parts
            .iter()
            .flatten()
            .map(|&p| distance(p, centre))
            .fold(0.0, f64::max);
    let beyond: Vec<Vec<Point>> = caps
        .iter()
        .map(|c| {
            let far = |p: Point| [p[0] + c.direction[0] * reach, p[1] + c.direction[1] * reach];
            vec![c.minus, c.plus, far(c.plus), far(c.minus)]
        })
        .collect();
    if let Some(ring) = star_union(centre, &parts, &beyond) {
        if ring.len() >= 3 && !geometry::ring_self_intersects(&ring) {
            return Some(ring);
        }
    }
    let corners: Vec<Point> = parts.iter().flatten().copied().collect();
    let hull = geometry::convex_hull(&corners);
    (hull.len() >= 3).then_some(hull)
}

/// The outline of the union of convex `parts` that touch `centre`, cut short along a direction
/// from the centre where it would end inside one of the convex `obstacles` (which do not contain
/// the centre): there it stops where the obstacles holding its end begin. Seen from the centre,
/// the boundary in any direction is the farthest part edge or the nearest obstacle edge; which
/// edge that is changes only at vertices and where two edges cross, so tracing it between those
/// directions gives the outline.
fn star_union(centre: Point, parts: &[Vec<Point>], obstacles: &[Vec<Point>]) -> Option<Ring> {
    let star = Star::new(centre, parts, obstacles)?;
    let angles = star.turning_angles();
    if angles.len() < 2 {
        return None;
    }
    let ring = star.trace(&angles);
    simplified(ring, star.tiny)
}

/// An edge relative to the centre, with the number of the polygon it belongs to.
type StarEdge = (Point, Point, usize);

/// The parts and obstacles of [`star_union`] as edges relative to its centre.
struct Star {
    centre: Point,
    /// The parts' edges, their polygons numbered from 0.
    edges: Vec<StarEdge>,
    /// The obstacles' edges, their polygons numbered after the parts'.
    walls: Vec<StarEdge>,
    /// The parts' edges, then the obstacles'.
    everything: Vec<StarEdge>,
    /// The input vertices as given, in the order of the edges that start at them.
    originals: Vec<Point>,
    /// The numbers of the obstacles.
    obstacle_numbers: std::ops::Range<usize>,
    /// Lengths below this are zero: a billionth of the parts' reach from the centre.
    tiny: f64,
    /// A traced point this close to an input vertex is that vertex.
    snap: f64,
}

impl Star {
    /// `None` when every part's corner is the centre.
    fn new(centre: Point, parts: &[Vec<Point>], obstacles: &[Vec<Point>]) -> Option<Star> {
        let local = |p: &Point| [p[0] - centre[0], p[1] - centre[1]];
        let edges_of = |polygons: &[Vec<Point>], first: usize| -> Vec<StarEdge> {
            polygons
                .iter()
                .enumerate()
                .flat_map(|(k, polygon)| {
                    (0..polygon.len()).map(move |i| {
                        (
                            local(&polygon[i]),
                            local(&polygon[(i + 1) % polygon.len()]),
                            first + k,
                        )
                    })
                })
                .collect()
        };
        let edges = edges_of(parts, 0);
        let walls = edges_of(obstacles, parts.len());
        let everything: Vec<StarEdge> = edges.iter().chain(&walls).copied().collect();
        let originals: Vec<Point> = parts.iter().chain(obstacles).flatten().copied().collect();
        let scale = edges
            .iter()
            .map(|(a, _, _)| a[0].hypot(a[1]))
            .fold(0.0, f64::max);
        if scale == 0.0 {
            return None;
        }
        Some(Star {
            centre,
            edges,
            walls,
            everything,
            originals,
            obstacle_numbers: parts.len()..parts.len() + obstacles.len(),
            tiny: scale * 1e-9,
            snap: scale * 1e-6,
        })
    }

    /// The directions, sorted and distinct, at which the bounding edge may change: towards
    /// every vertex and every crossing of edges of different polygons.
    fn turning_angles(&self) -> Vec<f64> {
        let tiny = self.tiny;
        let everything = &self.everything;
        let mut angles: Vec<f64> = everything
            .iter()
            .filter(|(a, _, _)| a[0].hypot(a[1]) > tiny)
            .map(|(a, _, _)| angle(*a))
            .collect();
        for (i, &(a, b, k)) in everything.iter().enumerate() {
            for &(c, d, l) in &everything[i + 1..] {
                if k == l {
                    continue;
                }
                let (ab, cd) = ([b[0] - a[0], b[1] - a[1]], [d[0] - c[0], d[1] - c[1]]);
                if let Some((s, t)) = meet(a, ab, c, cd) {
                    if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t) {
                        let x = [a[0] + ab[0] * s, a[1] + ab[1] * s];
                        if x[0].hypot(x[1]) > tiny {
                            angles.push(angle(x));
                        }
                    }
                }
            }
        }
        angles.sort_by(f64::total_cmp);
        angles.dedup_by(|b, a| *b - *a < 1e-12);
        angles
    }

    /// The edge that bounds the region along `direction`, and how far it is: the farthest part
    /// edge, cut short by the obstacles.
    fn farthest(&self, direction: Point) -> Option<(f64, Point, Point)> {
        let (mut reach, mut a, mut ab, _) = hits(direction, &self.edges)
            .into_iter()
            .max_by(|x, y| x.0.total_cmp(&y.0))?;
        // Where an obstacle holds the far end, the region stops where that obstacle begins
        // along the direction (and so on while that point lies in another): the stretch cut off
        // is covered by obstacles. Where the far end lies behind an obstacle but outside all,
        // the region keeps its reach and overlaps the obstacle rather than leave a gap.
        let wall_hits = hits(direction, &self.walls);
        let mut spans: Vec<(f64, f64, Point, Point)> = Vec::new();
        for k in self.obstacle_numbers.clone() {
            let mine = wall_hits.iter().filter(|h| h.3 == k);
            let first = mine.clone().min_by(|x, y| x.0.total_cmp(&y.0));
            let last = mine.max_by(|x, y| x.0.total_cmp(&y.0));
            if let (Some(first), Some(last)) = (first, last) {
                spans.push((first.0, last.0, first.1, first.2));
            }
        }
        while let Some(span) = spans
            .iter()
            .find(|span| span.0 < reach * (1.0 - 1e-9) && reach * (1.0 - 1e-7) < span.1)
        {
            (reach, a, ab) = (span.0, span.2, span.3);
        }
        Some((reach, a, ab))
    }

    /// The outline, in the plan: between each two turning angles, where the bounding edge's line
    /// crosses them (the centre where nothing bounds the region).
    fn trace(&self, angles: &[f64]) -> Ring {
        let centre = self.centre;
        let mut ring: Ring = Vec::with_capacity(angles.len() * 2);
        for k in 0..angles.len() {
            let from = angles[k];
            let to = if k + 1 < angles.len() {
                angles[k + 1]
            } else {
                angles[0] + std::f64::consts::TAU
            };
            let ray = |theta: f64| [theta.cos(), theta.sin()];
            let Some((reach, a, ab)) = self.farthest(ray((from + to) / 2.0)) else {
                ring.push(centre);
                continue;
            };
            // Where the farthest edge's line crosses the two bounding directions.
            for theta in [from, to] {
                let point = match meet([0.0, 0.0], ray(theta), a, ab) {
                    Some((t, _)) if t > 0.0 && t < reach * 1e3 => {
                        [t * theta.cos(), t * theta.sin()]
                    }
                    _ => {
                        let mid = ray((from + to) / 2.0);
                        [mid[0] * reach, mid[1] * reach]
                    }
                };
                // A point that is one of the input vertices (a cap corner) takes its exact bits,
                // so the junction and the arm share the edge.
                let exact = self
                    .everything
                    .iter()
                    .position(|e| distance(e.0, point) <= self.snap)
                    .map(|i| self.originals[i]);
                ring.push(exact.unwrap_or([centre[0] + point[0], centre[1] + point[1]]));
            }
        }
        ring
    }
}

/// Where the ray from the centre along `direction` crosses each of `edges`: how far along the
/// ray, the edge's start and direction, and its polygon.
fn hits(direction: Point, edges: &[StarEdge]) -> Vec<(f64, Point, Point, usize)> {
    edges
        .iter()
        .filter_map(move |&(a, b, k)| {
            let ab = [b[0] - a[0], b[1] - a[1]];
            let (t, s) = meet([0.0, 0.0], direction, a, ab)?;
            ((0.0..=1.0).contains(&s) && t > 0.0).then_some((t, a, ab, k))
        })
        .collect::<Vec<_>>()
}

/// The traced ring without repeated points (within `tiny`, the closing one too) and without the
/// points in the middle of a straight stretch; `None` if fewer than three are left.
fn simplified(ring: Ring, tiny: f64) -> Option<Ring> {
    let mut out: Ring = Vec::with_capacity(ring.len());
    for p in ring {
        let repeated = out
            .last()
            .is_some_and(|q: &Point| (q[0] - p[0]).abs() <= tiny && (q[1] - p[1]).abs() <= tiny);
        if !repeated {
            out.push(p);
        }
    }
    while out.len() > 1 && {
        let (f, l) = (out[0], out[out.len() - 1]);
        (f[0] - l[0]).abs() <= tiny && (f[1] - l[1]).abs() <= tiny
    } {
        out.pop();
    }
    let mut i = 0;
    while out.len() > 3 && i < out.len() {
        let n = out.len();
        let (a, b, c) = (out[(i + n - 1) % n], out[i], out[(i + 1) % n]);
        if geometry::orient(a, b, c).abs() <= tiny * distance(a, c) {
            out.remove(i);
        } else {
            i += 1;
        }
    }
    (out.len() >= 3).then_some(out)
}

/// Longest the mitre on the outer side of a bend may reach beyond the cap corners, in half
/// widths of the wider arm.
const MITRE_LIMIT: f64 = 2.0;

/// Where the edge of arm `a` on the side of `b` meets the edge of `b` on the side of `a`, when
/// that point lies inward of both caps (and, on the outer side of a bend, not too far out).
fn edge_corner(a: &Cap, b: &Cap, between: f64) -> Option<Point> {
    let (s, t) = meet(a.plus, a.direction, b.minus, b.direction)?;
    let tolerance = 1e-9;
    let corner = [
        a.plus[0] + a.direction[0] * s,
        a.plus[1] + a.direction[1] * s,
    ];
    let reach = MITRE_LIMIT * distance(a.plus, a.minus).max(distance(b.plus, b.minus)) / 2.0;
    let near = between < std::f64::consts::PI
        || (distance(corner, a.plus) <= reach && distance(corner, b.minus) <= reach);
    (s < -tolerance && t < -tolerance && near).then_some(corner)
}

/// The stations of `points` (a part of `line`'s points in order, as [`trim`] leaves them):
/// each found on the segment of `line` it lies on, between its ends' stations.
fn stations_of(line: &StretchLine, points: &[Point]) -> Vec<f64> {
    let mut segment = 0;
    points
        .iter()
        .map(|&p| {
            let last = line.points.len().saturating_sub(2);
            // The first segment from here whose far end is not behind `p`.
            while segment < last && !ahead(line.points[segment], line.points[segment + 1], p) {
                segment += 1;
            }
            let (a, b) = (line.points[segment], line.points[segment + 1]);
            let t = geometry::share_along_segment(p, a, b);
            let (sa, sb) = (line.stations[segment], line.stations[segment + 1]);
            sa + (sb - sa) * t
        })
        .collect()
}

/// Whether `p` lies before or on `b` along the segment `a`–`b`.
fn ahead(a: Point, b: Point, p: Point) -> bool {
    (p[0] - b[0]) * (b[0] - a[0]) + (p[1] - b[1]) * (b[1] - a[1]) <= 0.0
}

/// The polyline without its first `start` and last `end` units of length; `None` when nothing
/// is left.
pub fn trim(points: &[Point], start: f64, end: f64) -> Option<Vec<Point>> {
    let length = geometry::polyline_length(points);
    if start + end >= length || points.len() < 2 {
        return None;
    }
    let mut out = Vec::with_capacity(points.len());
    let (from, to) = (start, length - end);
    let mut walked = 0.0;
    for w in points.windows(2) {
        let segment = (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
        let (a, b) = (walked, walked + segment);
        let at = |d: f64| {
            let t = if segment > 0.0 {
                (d - a) / segment
            } else {
                0.0
            };
            [
                w[0][0] + (w[1][0] - w[0][0]) * t,
                w[0][1] + (w[1][1] - w[0][1]) * t,
            ]
        };
        if out.is_empty() && from <= b {
            out.push(if from <= a { w[0] } else { at(from) });
        }
        if !out.is_empty() {
            if to <= b {
                out.push(if to >= b { w[1] } else { at(to) });
                break;
            }
            out.push(w[1]);
        }
        walked = b;
    }
    let out = geometry::dedup_ring(&out);
    (out.len() >= 2).then_some(out)
}

/// Smallest turn (radians) worth rounding.
const MIN_BEND: f64 = 0.3;
/// Largest angle (radians) one segment of an arc turns through.
const BEND_STEP: f64 = 0.35;

/// Rounds every inner vertex of a polyline into a circular arc that touches both segments, of
/// `radius` unless that would reach past half of either segment (then tighter), so neighbouring
/// bends never overlap. The ends of the polyline stay.
pub fn smooth(points: &[Point], radius: f64) -> Vec<Point> {
    smooth_along(points, radius).points
}

/// [`smooth`], with the distance along `points` each point of the result stands for.
pub fn smooth_along(points: &[Point], radius: f64) -> StretchLine {
    let n = points.len();
    let along = geometry::distances_along(points);
    let total = along.last().copied().unwrap_or(0.0);
    if n < 3 || radius <= 0.0 {
        return StretchLine {
            points: points.to_vec(),
            stations: along,
            bends: Vec::new(),
        };
    }
    let mut bends = Vec::new();
    let mut out: Vec<(Point, f64)> = Vec::with_capacity(n * 3);
    out.push((points[0], 0.0));
    for i in 1..n - 1 {
        let (p, v, q) = (points[i - 1], points[i], points[i + 1]);
        let (din, dout) = (unit(p, v), unit(v, q));
        let cos = (din[0] * dout[0] + din[1] * dout[1]).clamp(-1.0, 1.0);
        let bend = cos.acos();
        let len_in = (v[0] - p[0]).hypot(v[1] - p[1]);
        let len_out = (q[0] - v[0]).hypot(q[1] - v[1]);
        if bend < MIN_BEND || len_in == 0.0 || len_out == 0.0 {
            out.push((v, along[i]));
            continue;
        }
        let cut = (radius * (bend / 2.0).tan())
            .min(len_in / 2.0)
            .min(len_out / 2.0);
        let a = [v[0] - din[0] * cut, v[1] - din[1] * cut];
        let b = [v[0] + dout[0] * cut, v[1] + dout[1] * cut];
        // The arc's centre lies a radius to the inside of the bend from where it touches.
        let side = if din[0] * dout[1] - din[1] * dout[0] > 0.0 {
            1.0
        } else {
            -1.0
        };
        let r = cut / (bend / 2.0).tan();
        let normal = turn(din);
        let centre = [a[0] + normal[0] * side * r, a[1] + normal[1] * side * r];
        let start = [a[0] - centre[0], a[1] - centre[1]];
        let steps = ((bend / BEND_STEP).ceil() as usize).max(1);
        // The arc stands for the corner from `a` to `b`, evenly.
        out.push((a, along[i] - cut));
        for k in 1..steps {
            let share = k as f64 / steps as f64;
            let phi = side * bend * share;
            let (sin, cos) = phi.sin_cos();
            out.push((
                [
                    centre[0] + start[0] * cos - start[1] * sin,
                    centre[1] + start[0] * sin + start[1] * cos,
                ],
                along[i] - cut + 2.0 * cut * share,
            ));
        }
        out.push((b, along[i] + cut));
        bends.push((along[i] - cut, along[i] + cut));
    }
    out.push((points[n - 1], total));
    let mut deduped = StretchLine {
        bends,
        ..StretchLine::default()
    };
    for (p, station) in out {
        let near = deduped
            .points
            .last()
            .is_some_and(|l: &Point| (l[0] - p[0]).abs() < 1e-12 && (l[1] - p[1]).abs() < 1e-12);
        if !near {
            deduped.points.push(p);
            deduped.stations.push(station);
        }
    }
    if deduped.points.len() < 2 {
        return StretchLine {
            points: points.to_vec(),
            stations: along,
            bends: Vec::new(),
        };
    }
    deduped
}

#[cfg(test)]
mod tests;
