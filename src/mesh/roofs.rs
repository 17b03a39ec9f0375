//! Roofs built on the straight skeleton (paper 003 §5.1).
//!
//! A hipped roof is the skeleton raised: each face of an edge becomes a plane rising with the
//! distance from that edge. A gabled roof moves the apex of every triangular face (where the
//! bisectors from an edge's two corners meet) to the middle of that edge (§5.1.1): the triangle
//! stands up as a vertical gable and the faces beside it reach the footprint there. Because the
//! skeleton follows the footprint, an L, T or U house gets one ridge per wing, meeting in
//! valleys, where a single ridge through a bounding box would be wrong.
//!
//! Everything here is in the footprint's own plane, metres, with `(x, y)` the plan and the
//! height third; the caller places it.

use super::skeleton::{skeleton, Skeleton, SkeletonError};
use crate::geometry::constrained::triangulate_polygon;
use crate::geometry::{convex_hull, dedup_ring, lerp, signed_area2, Point, Polygon};

/// How the end of a wing is finished, where a hipped roof has a triangular hip.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RoofEnd {
    /// Sloped like the long sides.
    Hip,
    /// A vertical gable up to the ridge (§5.1.1).
    Gable,
    /// A gable up to [`HALF_HIP_GABLE`] of the height, a small hip above it (`half-hipped`).
    HalfHip,
    /// A hip up to [`GABLET_HIP`] of the height, a small gable above it (`hipped-and-gabled`,
    /// the dutch hip of §5.1.4).
    Gablet,
}

/// A roof shape that the skeleton can build: how the ends of its wings are finished.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkeletonRoof {
    pub ends: RoofEnd,
    /// One end finished otherwise: the one whose outside faces most nearly along this plan
    /// direction (`side_hipped`: gabled, with the hip on the side `roof:direction` names).
    pub one_end: Option<(Point, RoofEnd)>,
}

impl SkeletonRoof {
    pub const HIPPED: SkeletonRoof = SkeletonRoof::ends(RoofEnd::Hip);
    pub const GABLED: SkeletonRoof = SkeletonRoof::ends(RoofEnd::Gable);

    pub const fn ends(ends: RoofEnd) -> SkeletonRoof {
        SkeletonRoof {
            ends,
            one_end: None,
        }
    }
}

/// Share of a half-hipped end's height taken by its gable.
pub const HALF_HIP_GABLE: f64 = 0.65;
/// Share of a hipped-and-gabled end's height taken by its hip.
pub const GABLET_HIP: f64 = 0.5;

/// The triangles of a roof: `[x, y, height above the eaves]` corners.
#[derive(Debug, Clone, Default)]
pub struct RoofMesh {
    /// Sloped faces, wound counter-clockwise seen from above.
    pub slopes: Vec<[[f64; 3]; 3]>,
    /// Vertical faces standing on footprint edges above the eaves (gables, the high sides of a
    /// skillion), convex, wound counter-clockwise seen from outside.
    pub sides: Vec<Vec<[f64; 3]>>,
    /// The highest point above the eaves.
    pub height: f64,
    /// The footprint the roof stands on, outer ring counter-clockwise and holes clockwise:
    /// walls built on these rings meet the roof and its sides edge for edge.
    pub rings: Vec<Vec<Point>>,
    /// Points along each edge of the rings (in order from its start; by ring, then edge) where
    /// the roof above it bends: the tops of the walls pass through them. Empty when none.
    pub edge_points: Vec<Vec<Vec<Point>>>,
}

impl RoofMesh {
    /// The points along edge `edge` of ring `ring` where the roof above it bends.
    pub fn edge_points(&self, ring: usize, edge: usize) -> &[Point] {
        self.edge_points
            .get(ring)
            .and_then(|r| r.get(edge))
            .map_or(&[], Vec::as_slice)
    }
}

/// Why a roof could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RoofError {
    #[error(transparent)]
    Skeleton(#[from] SkeletonError),
    #[error("the footprint has no width across the roof")]
    NoWidth,
    #[error("face {0} could not be triangulated")]
    OpenFace(usize),
}

/// The roof of a footprint (outer ring first, then holes) whose ridge stands `height` metres
/// above the eaves, or rises at `pitch` (rise per run) when no height is given.
pub fn skeleton_roof(
    rings: &[Vec<Point>],
    shape: SkeletonRoof,
    height: Option<f64>,
    pitch: f64,
) -> Result<RoofMesh, RoofError> {
    let skeleton = skeleton(rings)?;
    skeleton.verify()?;
    let top_time = skeleton.nodes.iter().map(|n| n.time).fold(0.0, f64::max);
    if top_time <= 0.0 {
        return Err(SkeletonError::Degenerate.into());
    }
    let scale = height.map_or(pitch, |h| h / top_time);
    let mut plan: Vec<Point> = skeleton.nodes.iter().map(|n| n.point).collect();
    let mut lift: Vec<f64> = skeleton.nodes.iter().map(|n| n.time * scale).collect();
    let mut faces: Vec<(Vec<usize>, bool)> =
        skeleton.faces.iter().map(|f| (f.clone(), false)).collect();
    finish_ends(&skeleton, shape, &mut plan, &mut lift, &mut faces);
    let mut mesh = RoofMesh {
        height: top_time * scale,
        rings: skeleton.rings.clone(),
        ..RoofMesh::default()
    };
    let corner = |n: usize| [plan[n][0], plan[n][1], lift[n]];
    for (face, (nodes, vertical)) in faces.iter().enumerate() {
        if *vertical {
            mesh.sides.push(nodes.iter().map(|&n| corner(n)).collect());
            continue;
        }
        let points: Vec<Point> = nodes.iter().map(|&n| plan[n]).collect();
        for [a, b, c] in ear_clip(&points).ok_or(RoofError::OpenFace(face))? {
            mesh.slopes
                .push([corner(nodes[a]), corner(nodes[b]), corner(nodes[c])]);
        }
    }
    Ok(mesh)
}

/// Finishes the end of every wing: the triangular faces whose apex no other triangle shares (a
/// square's single apex stays: it is hipped). A gable moves the apex to the middle of its edge
/// (§5.1.1) and the face stands up; a half hip or a gablet cuts the face where the gable meets
/// the hip, adding that corner to the faces beside it.
fn finish_ends(
    skeleton: &Skeleton,
    shape: SkeletonRoof,
    plan: &mut Vec<Point>,
    lift: &mut Vec<f64>,
    faces: &mut Vec<(Vec<usize>, bool)>,
) {
    let triangles: Vec<usize> = (0..skeleton.faces.len())
        .filter(|&f| skeleton.faces[f].len() == 3)
        .collect();
    let ends: Vec<usize> = triangles
        .iter()
        .copied()
        .filter(|&f| {
            let apex = skeleton.faces[f][2];
            triangles
                .iter()
                .filter(|&&g| skeleton.faces[g][2] == apex)
                .count()
                == 1
        })
        .collect();
    // Outside of an end: to the right of its edge.
    let outward = |f: usize| {
        let (a, b) = (plan[skeleton.faces[f][0]], plan[skeleton.faces[f][1]]);
        let d = [b[0] - a[0], b[1] - a[1]];
        let length = d[0].hypot(d[1]).max(f64::MIN_POSITIVE);
        [d[1] / length, -d[0] / length]
    };
    let special = shape.one_end.and_then(|(towards, _)| {
        ends.iter().copied().max_by(|&f, &g| {
            let (u, v) = (outward(f), outward(g));
            (u[0] * towards[0] + u[1] * towards[1])
                .total_cmp(&(v[0] * towards[0] + v[1] * towards[1]))
        })
    });
    for &f in &ends {
        let end = match shape.one_end {
            Some((_, end)) if special == Some(f) => end,
            _ => shape.ends,
        };
        let [a, b, apex] = [0, 1, 2].map(|k| skeleton.faces[f][k]);
        let middle = lerp(plan[a], plan[b], 0.5);
        let (top, rise) = (plan[apex], lift[apex]);
        let add = |plan: &mut Vec<Point>, lift: &mut Vec<f64>, point: Point, height: f64| {
            plan.push(point);
            lift.push(height);
            plan.len() - 1
        };
        match end {
            RoofEnd::Hip => {}
            RoofEnd::Gable => {
                plan[apex] = middle;
                faces[f].1 = true;
            }
            RoofEnd::HalfHip => {
                let share = HALF_HIP_GABLE;
                let a2 = add(plan, lift, lerp(plan[a], middle, share), share * rise);
                let b2 = add(plan, lift, lerp(plan[b], middle, share), share * rise);
                plan[apex] = lerp(middle, top, 1.0 - share);
                faces[f] = (vec![a, b, b2, a2], true);
                insert_between(faces, [a, apex], a2);
                insert_between(faces, [apex, b], b2);
                faces.push((vec![a2, b2, apex], false));
            }
            RoofEnd::Gablet => {
                let share = GABLET_HIP;
                let a2 = add(plan, lift, lerp(plan[a], top, share), share * rise);
                let b2 = add(plan, lift, lerp(plan[b], top, share), share * rise);
                plan[apex] = lerp(plan[a2], plan[b2], 0.5);
                faces[f] = (vec![a, b, b2, a2], false);
                insert_between(faces, [a, apex], a2);
                insert_between(faces, [apex, b], b2);
                faces.push((vec![a2, b2, apex], true));
            }
        }
    }
}

/// Puts `node` between the two ends of an arc in every face that runs along it.
fn insert_between(faces: &mut [(Vec<usize>, bool)], arc: [usize; 2], node: usize) {
    for (nodes, _) in faces.iter_mut() {
        let n = nodes.len();
        if let Some(i) = (0..n).find(|&i| {
            let (x, y) = (nodes[i], nodes[(i + 1) % n]);
            (x, y) == (arc[0], arc[1]) || (y, x) == (arc[0], arc[1])
        }) {
            nodes.insert(i + 1, node);
        }
    }
}

/// A roof whose section across the footprint follows a profile: `(share of the width, share of
/// the height)` points from one side to the other along `across` (a unit vector in the plan).
/// Skillion, saltbox, round, sawtooth and butterfly roofs, and gabled roofs whose ridge the tags
/// turn. The footprint's triangles are cut along every bend of the profile so that each piece
/// lies in one plane; vertical sides close the roof over the walls where it stands above the
/// eaves. Every edge is cut at points computed from its two ends alone, so the triangles on
/// both sides of it, and the side above a footprint edge, share them exactly.
pub fn profile_roof(
    rings: &[Vec<Point>],
    across: Point,
    profile: &[(f64, f64)],
    height: f64,
) -> Result<RoofMesh, RoofError> {
    let mut rings: Vec<Vec<Point>> = rings.iter().map(|r| dedup_ring(r)).collect();
    rings.retain(|r| r.len() >= 3);
    for (index, ring) in rings.iter_mut().enumerate() {
        if (index == 0) == (signed_area2(ring) < 0.0) {
            ring.reverse();
        }
    }
    let s = |p: Point| p[0] * across[0] + p[1] * across[1];
    let Some(outer) = rings.first() else {
        return Err(RoofError::NoWidth);
    };
    let low = outer.iter().map(|&p| s(p)).fold(f64::INFINITY, f64::min);
    let high = outer
        .iter()
        .map(|&p| s(p))
        .fold(f64::NEG_INFINITY, f64::max);
    let width = high - low;
    if width.is_nan() || width <= 0.0 {
        return Err(RoofError::NoWidth);
    }
    let breaks: Vec<f64> = profile[1..profile.len().saturating_sub(1)]
        .iter()
        .map(|&(share, _)| low + share * width)
        .collect();
    // Heights under a micrometre are the eaves: a side that thin is none.
    let lift = |along: f64| {
        let h = height * profile_at(profile, (along - low) / width);
        if h < 1e-6 {
            0.0
        } else {
            h
        }
    };
    // The points of edge a–b from a to b: its ends and where it crosses a bend, each with its
    // position across the roof (a crossing's is its bend's, exactly).
    let edge_points = |a: Point, b: Point| -> Vec<(Point, f64)> {
        let (p, q) = if a.map(f64::to_bits) <= b.map(f64::to_bits) {
            (a, b)
        } else {
            (b, a)
        };
        let (sp, sq) = (s(p), s(q));
        let mut cuts: Vec<(f64, Point, f64)> = breaks
            .iter()
            .filter(|&&c| (sp - c) * (sq - c) < 0.0)
            .map(|&c| {
                let t = (c - sp) / (sq - sp);
                (t, lerp(p, q, t), c)
            })
            .collect();
        cuts.sort_by(|x, y| x.0.total_cmp(&y.0));
        if p != a {
            cuts.reverse();
        }
        let mut points = vec![(a, s(a))];
        points.extend(cuts.into_iter().map(|(_, point, c)| (point, c)));
        points
    };
    let polygon = Polygon {
        outer: rings[0].clone(),
        holes: rings[1..].to_vec(),
    };
    let mut mesh = RoofMesh {
        height: height * profile.iter().map(|&(_, h)| h).fold(0.0, f64::max),
        ..RoofMesh::default()
    };
    let corner = |(p, along): (Point, f64)| [p[0], p[1], lift(along)];
    let strips: Vec<(f64, f64)> = std::iter::once(f64::NEG_INFINITY)
        .chain(breaks.iter().copied())
        .zip(breaks.iter().copied().chain(std::iter::once(f64::INFINITY)))
        .collect();
    for triangle in triangulate_polygon(&polygon) {
        let [a, b, c] = [triangle[0], triangle[1], triangle[2]];
        let [a, b, c] = if signed_area2(&[a, b, c]) >= 0.0 {
            [a, b, c]
        } else {
            [a, c, b]
        };
        let boundary: Vec<(Point, f64)> = [(a, b), (b, c), (c, a)]
            .iter()
            .flat_map(|&(x, y)| edge_points(x, y))
            .collect();
        // The triangle within each strip between two bends is convex: its corners are the
        // boundary points in the strip, in order.
        for &(from, to) in &strips {
            let piece: Vec<[f64; 3]> = boundary
                .iter()
                .filter(|(_, along)| (from..=to).contains(along))
                .map(|&point| corner(point))
                .collect();
            for i in 1..piece.len().saturating_sub(1) {
                mesh.slopes.push([piece[0], piece[i], piece[i + 1]]);
            }
        }
    }
    if mesh.slopes.is_empty() {
        return Err(RoofError::NoWidth);
    }
    // The crossing points along each edge of the footprint; a side above each piece.
    mesh.edge_points = rings
        .iter()
        .map(|ring| {
            let n = ring.len();
            (0..n)
                .map(|i| {
                    edge_points(ring[i], ring[(i + 1) % n])[1..]
                        .iter()
                        .map(|&(p, _)| p)
                        .collect()
                })
                .collect()
        })
        .collect();
    for ring in &rings {
        let n = ring.len();
        let points: Vec<(Point, f64)> = (0..n)
            .flat_map(|i| edge_points(ring[i], ring[(i + 1) % n]))
            .collect();
        for i in 0..points.len() {
            let (a, b) = (points[i], points[(i + 1) % points.len()]);
            let (ha, hb) = (lift(a.1), lift(b.1));
            let mut side = vec![[a.0[0], a.0[1], 0.0], [b.0[0], b.0[1], 0.0]];
            if hb > 0.0 {
                side.push([b.0[0], b.0[1], hb]);
            }
            if ha > 0.0 {
                side.push([a.0[0], a.0[1], ha]);
            }
            if side.len() >= 3 {
                mesh.sides.push(side);
            }
        }
    }
    mesh.rings = rings;
    Ok(mesh)
}

/// The profile's height share at `share` of the width (linear between its points).
fn profile_at(profile: &[(f64, f64)], share: f64) -> f64 {
    let share = share.clamp(0.0, 1.0);
    for pair in profile.windows(2) {
        let ((s0, h0), (s1, h1)) = (pair[0], pair[1]);
        if share <= s1 {
            if s1 <= s0 {
                return h1;
            }
            return h0 + (h1 - h0) * (share - s0) / (s1 - s0);
        }
    }
    profile.last().map_or(0.0, |&(_, h)| h)
}

/// The direction along the longer side of the smallest rectangle around a ring (a unit
/// vector): where the ridge of a house runs unless tagged otherwise.
pub fn long_axis(ring: &[Point]) -> Option<Point> {
    let hull = convex_hull(ring);
    let n = hull.len();
    let mut best: Option<(f64, Point)> = None;
    for i in 0..n {
        let (a, b) = (hull[i], hull[(i + 1) % n]);
        let d = [b[0] - a[0], b[1] - a[1]];
        let length = d[0].hypot(d[1]);
        if length == 0.0 {
            continue;
        }
        let u = [d[0] / length, d[1] / length];
        let v = [-u[1], u[0]];
        let extent = |axis: Point| {
            let values = hull.iter().map(|p| p[0] * axis[0] + p[1] * axis[1]);
            let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                (lo.min(x), hi.max(x))
            });
            hi - lo
        };
        let (eu, ev) = (extent(u), extent(v));
        let area = eu * ev;
        let long = if eu >= ev { u } else { v };
        if best.is_none_or(|(a, _)| area < a) {
            best = Some((area, long));
        }
    }
    best.map(|(_, axis)| axis)
}

/// A roof that rises from the footprint to one point over its centroid, along a profile.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CentredRoof {
    /// Straight faces to the apex (`pyramidal`, and `cone` on a round footprint).
    Pyramid,
    /// A quarter circle in section.
    Dome,
    /// Bulging out past the walls, then drawn in to a point.
    Onion,
}

impl CentredRoof {
    /// The profile as (scale of the footprint about its centroid, share of the height), from
    /// the eaves to the apex.
    fn profile(self) -> Vec<(f64, f64)> {
        match self {
            CentredRoof::Pyramid => vec![(1.0, 0.0), (0.0, 1.0)],
            CentredRoof::Dome => (0..=DOME_STEPS)
                .map(|k| {
                    if k == DOME_STEPS {
                        return (0.0, 1.0);
                    }
                    let angle = std::f64::consts::FRAC_PI_2 * k as f64 / DOME_STEPS as f64;
                    (angle.cos(), angle.sin())
                })
                .collect(),
            CentredRoof::Onion => vec![
                (1.0, 0.0),
                (1.12, 0.12),
                (1.18, 0.28),
                (1.08, 0.45),
                (0.8, 0.6),
                (0.45, 0.74),
                (0.2, 0.86),
                (0.06, 0.95),
                (0.0, 1.0),
            ],
        }
    }
}

/// Rings of a dome between its eaves and its top.
const DOME_STEPS: usize = 6;

/// A roof rising to a point over the centroid of a footprint without holes, `None` when the
/// footprint is not star-shaped around its centroid (the caller then builds a hipped roof).
/// `height` is the apex above the eaves; untagged, the caller derives it from [`spread`].
pub fn centred_roof(ring: &[Point], shape: CentredRoof, height: f64) -> Option<RoofMesh> {
    let (centre, ring) = star_centre(ring)?;
    let profile = shape.profile();
    let level = |(scale, rise): (f64, f64)| -> Vec<[f64; 3]> {
        ring.iter()
            .map(|p| {
                [
                    centre[0] + (p[0] - centre[0]) * scale,
                    centre[1] + (p[1] - centre[1]) * scale,
                    rise * height,
                ]
            })
            .collect()
    };
    let mut slopes = Vec::new();
    let n = ring.len();
    let mut below: Vec<[f64; 3]> = ring.iter().map(|p| [p[0], p[1], 0.0]).collect();
    for &step in &profile[1..] {
        let above = level(step);
        for i in 0..n {
            let j = (i + 1) % n;
            if step.0 == 0.0 {
                slopes.push([below[i], below[j], above[i]]);
            } else {
                slopes.push([below[i], below[j], above[j]]);
                slopes.push([below[i], above[j], above[i]]);
            }
        }
        below = above;
    }
    Some(RoofMesh {
        slopes,
        sides: Vec::new(),
        height,
        rings: vec![ring],
        edge_points: Vec::new(),
    })
}

/// How far a footprint reaches from its centroid: the least distance to its sides and the mean
/// distance to its corners, `None` if it is not star-shaped around the centroid.
pub fn spread(ring: &[Point]) -> Option<(f64, f64)> {
    let (centre, ring) = star_centre(ring)?;
    let n = ring.len();
    let inner = (0..n)
        .map(|i| crate::geometry::distance_to_segment(centre, ring[i], ring[(i + 1) % n]))
        .fold(f64::INFINITY, f64::min);
    let outer = ring
        .iter()
        .map(|p| (p[0] - centre[0]).hypot(p[1] - centre[1]))
        .sum::<f64>()
        / n as f64;
    Some((inner, outer))
}

/// The area centroid of a ring and the ring turned counter-clockwise, when every side faces the
/// centroid (star-shaped around it).
fn star_centre(ring: &[Point]) -> Option<(Point, Vec<Point>)> {
    let mut ring = crate::geometry::dedup_ring(ring);
    let area2 = signed_area2(&ring);
    if ring.len() < 3 || area2 == 0.0 {
        return None;
    }
    if area2 < 0.0 {
        ring.reverse();
    }
    let n = ring.len();
    let (mut cx, mut cy, mut a) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let (p, q) = (ring[i], ring[(i + 1) % n]);
        let w = p[0] * q[1] - q[0] * p[1];
        cx += (p[0] + q[0]) * w;
        cy += (p[1] + q[1]) * w;
        a += w;
    }
    let centre = [cx / (3.0 * a), cy / (3.0 * a)];
    let facing = (0..n).all(|i| {
        let (p, q) = (ring[i], ring[(i + 1) % n]);
        (q[0] - p[0]) * (centre[1] - p[1]) - (q[1] - p[1]) * (centre[0] - p[0]) > 0.0
    });
    facing.then_some((centre, ring))
}

/// Share of a mansard or gambrel roof's run taken by its steep lower slopes (paper 003
/// §5.1.2–5.1.3: a shrunken copy of the footprint where the slope changes).
pub const KNEE_RUN: f64 = 0.3;
/// Share of its height the steep lower slopes rise.
pub const KNEE_RISE: f64 = 0.7;

/// Bends a hipped or gabled roof into a mansard or gambrel: every face is cut where the
/// shrinking footprint has run [`KNEE_RUN`] of the way to the ridge, the steep part below rising
/// [`KNEE_RISE`] of the height and the rest above. Neighbouring faces are cut at the same points
/// (computed from the shared edge's ends in a fixed order), so the roof stays closed.
pub fn bend(mesh: &mut RoofMesh) {
    let height = mesh.height;
    if height <= 0.0 {
        return;
    }
    let knee = KNEE_RUN * height;
    let lift = |z: f64| {
        if z <= knee {
            z / knee * KNEE_RISE * height
        } else {
            KNEE_RISE * height + (z - knee) / (height - knee) * (1.0 - KNEE_RISE) * height
        }
    };
    let cut = |a: [f64; 3], b: [f64; 3]| {
        // The same edge gives the same point whichever face asks.
        let (p, q) = if a.map(f64::to_bits) <= b.map(f64::to_bits) {
            (a, b)
        } else {
            (b, a)
        };
        let t = (knee - p[2]) / (q[2] - p[2]);
        [p[0] + (q[0] - p[0]) * t, p[1] + (q[1] - p[1]) * t, knee]
    };
    // A convex face cut at the knee: the part below and the part above (a corner at the knee
    // belongs to both).
    let split = |face: &[[f64; 3]]| -> [Vec<[f64; 3]>; 2] {
        let mut parts: [Vec<[f64; 3]>; 2] = [Vec::new(), Vec::new()];
        for i in 0..face.len() {
            let (a, b) = (face[i], face[(i + 1) % face.len()]);
            if a[2] <= knee {
                parts[0].push(a);
            }
            if a[2] >= knee {
                parts[1].push(a);
            }
            if (a[2] < knee && b[2] > knee) || (a[2] > knee && b[2] < knee) {
                let x = cut(a, b);
                parts[0].push(x);
                parts[1].push(x);
            }
        }
        parts.map(|mut part| {
            for c in &mut part {
                c[2] = lift(c[2]);
            }
            part
        })
    };
    let mut slopes = Vec::with_capacity(mesh.slopes.len() * 2);
    for triangle in &mesh.slopes {
        for part in split(triangle).iter().filter(|p| p.len() >= 3) {
            for i in 1..part.len() - 1 {
                slopes.push([part[0], part[i], part[i + 1]]);
            }
        }
    }
    let mut sides = Vec::with_capacity(mesh.sides.len() * 2);
    for side in &mesh.sides {
        sides.extend(split(side).into_iter().filter(|p| p.len() >= 3));
    }
    mesh.slopes = slopes;
    mesh.sides = sides;
}

/// Triangles of a simple polygon given counter-clockwise, as index triples (ear clipping);
/// `None` if it is not simple enough to clip.
fn ear_clip(points: &[Point]) -> Option<Vec<[usize; 3]>> {
    let mut left: Vec<usize> = (0..points.len()).collect();
    // Points repeated in a row (a zero-length arc) add nothing.
    left.dedup_by(|b, a| points[*a] == points[*b]);
    while left.len() > 1 && points[left[0]] == points[left[left.len() - 1]] {
        left.pop();
    }
    let mut out = Vec::with_capacity(left.len().saturating_sub(2));
    let area: f64 = signed_area2(&left.iter().map(|&i| points[i]).collect::<Vec<_>>());
    if area <= 0.0 {
        return (area == 0.0).then_some(out);
    }
    let orient = |a: Point, b: Point, c: Point| {
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    };
    let mut guard = 0;
    while left.len() > 3 {
        guard += 1;
        if guard > 4 * points.len() * points.len() + 16 {
            return None;
        }
        let n = left.len();
        let mut clipped = false;
        for k in 0..n {
            let (i, j, l) = (left[(k + n - 1) % n], left[k], left[(k + 1) % n]);
            let (a, b, c) = (points[i], points[j], points[l]);
            // A straight point is no ear: it stays, so the faces beside it share its edges.
            if orient(a, b, c) <= 0.0 {
                continue;
            }
            let blocked = left.iter().any(|&m| {
                if m == i || m == j || m == l {
                    return false;
                }
                let p = points[m];
                p != a
                    && p != b
                    && p != c
                    && orient(a, b, p) >= 0.0
                    && orient(b, c, p) >= 0.0
                    && orient(c, a, p) >= 0.0
            });
            if !blocked {
                out.push([i, j, l]);
                left.remove(k);
                clipped = true;
                break;
            }
        }
        if !clipped {
            // Only straight points left: nothing more to cover.
            let all_straight = (0..left.len()).all(|k| {
                let n = left.len();
                orient(
                    points[left[(k + n - 1) % n]],
                    points[left[k]],
                    points[left[(k + 1) % n]],
                ) == 0.0
            });
            return all_straight.then_some(out);
        }
    }
    if left.len() == 3 {
        let [i, j, l] = [left[0], left[1], left[2]];
        if orient(points[i], points[j], points[l]) > 0.0 {
            out.push([i, j, l]);
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests;
