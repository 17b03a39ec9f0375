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
use crate::geometry::{signed_area2, Point};

/// A roof shape that the skeleton can build.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SkeletonRoof {
    Hipped,
    Gabled,
}

/// The triangles of a roof: `[x, y, height above the eaves]` corners.
#[derive(Debug, Clone, Default)]
pub struct RoofMesh {
    /// Sloped faces, wound counter-clockwise seen from above.
    pub slopes: Vec<[[f64; 3]; 3]>,
    /// Vertical gable triangles standing on footprint edges.
    pub gables: Vec<[[f64; 3]; 3]>,
    /// The highest point above the eaves.
    pub height: f64,
    /// The footprint the roof stands on, without repeated or collinear points: walls built on
    /// these rings meet the roof edge for edge.
    pub rings: Vec<Vec<Point>>,
}

/// The roof of a footprint (outer ring first, then holes) whose ridge stands `height` metres
/// above the eaves, or rises at `pitch` (rise per run) when no height is given.
pub fn skeleton_roof(
    rings: &[Vec<Point>],
    shape: SkeletonRoof,
    height: Option<f64>,
    pitch: f64,
) -> Result<RoofMesh, SkeletonError> {
    let skeleton = skeleton(rings)?;
    skeleton.verify()?;
    let top_time = skeleton.nodes.iter().map(|n| n.time).fold(0.0, f64::max);
    if top_time <= 0.0 {
        return Err(SkeletonError::Degenerate);
    }
    let scale = height.map_or(pitch, |h| h / top_time);
    let mut plan: Vec<Point> = skeleton.nodes.iter().map(|n| n.point).collect();
    let lift: Vec<f64> = skeleton.nodes.iter().map(|n| n.time * scale).collect();
    let mut gable_faces = vec![false; skeleton.faces.len()];
    if shape == SkeletonRoof::Gabled {
        gable(&skeleton, &mut plan, &mut gable_faces);
    }
    let mut mesh = RoofMesh {
        height: top_time * scale,
        rings: skeleton.rings.clone(),
        ..RoofMesh::default()
    };
    let corner = |n: usize| [plan[n][0], plan[n][1], lift[n]];
    for (face, nodes) in skeleton.faces.iter().enumerate() {
        if gable_faces[face] {
            mesh.gables
                .push([corner(nodes[0]), corner(nodes[1]), corner(nodes[2])]);
            continue;
        }
        let points: Vec<Point> = nodes.iter().map(|&n| plan[n]).collect();
        for [a, b, c] in ear_clip(&points).ok_or(SkeletonError::OpenFace(face))? {
            mesh.slopes
                .push([corner(nodes[a]), corner(nodes[b]), corner(nodes[c])]);
        }
    }
    Ok(mesh)
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
        gables: Vec::new(),
        height,
        rings: vec![ring],
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
const KNEE_RUN: f64 = 0.3;
/// Share of its height the steep lower slopes rise.
const KNEE_RISE: f64 = 0.7;

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
        // The same edge gives the same point whichever triangle asks.
        let (p, q) = if a.map(f64::to_bits) <= b.map(f64::to_bits) {
            (a, b)
        } else {
            (b, a)
        };
        let t = (knee - p[2]) / (q[2] - p[2]);
        [p[0] + (q[0] - p[0]) * t, p[1] + (q[1] - p[1]) * t, knee]
    };
    let split = |triangles: &[[[f64; 3]; 3]]| -> Vec<[[f64; 3]; 3]> {
        let mut out = Vec::with_capacity(triangles.len() * 2);
        for t in triangles {
            let mut polygons: [Vec<[f64; 3]>; 2] = [Vec::new(), Vec::new()];
            for i in 0..3 {
                let (a, b) = (t[i], t[(i + 1) % 3]);
                polygons[usize::from(a[2] > knee)].push(a);
                if (a[2] > knee) != (b[2] > knee) {
                    let x = cut(a, b);
                    polygons[0].push(x);
                    polygons[1].push(x);
                }
            }
            for polygon in polygons.iter().filter(|p| p.len() >= 3) {
                for i in 1..polygon.len() - 1 {
                    out.push([polygon[0], polygon[i], polygon[i + 1]]);
                }
            }
        }
        for t in &mut out {
            for c in t.iter_mut() {
                c[2] = lift(c[2]);
            }
        }
        out
    };
    mesh.slopes = split(&mesh.slopes);
    mesh.gables = split(&mesh.gables);
}

/// Moves the apex of each triangular face to the middle of its edge, where that apex belongs to
/// no other triangular face (a square's single apex stays: it is hipped).
fn gable(skeleton: &Skeleton, plan: &mut [Point], gables: &mut [bool]) {
    let triangles: Vec<usize> = (0..skeleton.faces.len())
        .filter(|&f| skeleton.faces[f].len() == 3)
        .collect();
    for &f in &triangles {
        let apex = skeleton.faces[f][2];
        let shared = triangles
            .iter()
            .filter(|&&g| skeleton.faces[g][2] == apex)
            .count();
        if shared != 1 {
            continue;
        }
        let (a, b) = (
            skeleton.nodes[skeleton.faces[f][0]].point,
            skeleton.nodes[skeleton.faces[f][1]].point,
        );
        plan[apex] = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
        gables[f] = true;
    }
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
mod tests {
    use super::*;

    /// The corners of the roof's slopes at one height above the eaves.
    fn corners_at(mesh: &RoofMesh, height: f64) -> Vec<[f64; 3]> {
        mesh.slopes
            .iter()
            .flatten()
            .copied()
            .filter(|c| (c[2] - height).abs() < 1e-9)
            .collect()
    }

    /// Twice the area of the roof's slopes seen from above, and the footprint's.
    fn plan_areas(mesh: &RoofMesh, rings: &[Vec<Point>]) -> (f64, f64) {
        let roof: f64 = mesh
            .slopes
            .iter()
            .map(|t| signed_area2(&[[t[0][0], t[0][1]], [t[1][0], t[1][1]], [t[2][0], t[2][1]]]))
            .sum();
        let footprint: f64 = rings.iter().map(|r| signed_area2(r).abs()).sum::<f64>()
            - 2.0
                * rings[1..]
                    .iter()
                    .map(|r| signed_area2(r).abs())
                    .sum::<f64>();
        (roof, footprint)
    }

    /// Every edge of the roof's triangles, by its end points, is used by exactly two
    /// triangles once the footprint's edges (where the walls close it) are counted too.
    fn is_closed_over_the_walls(mesh: &RoofMesh, rings: &[Vec<Point>]) -> bool {
        let mut edges: std::collections::HashMap<[u64; 6], i32> = Default::default();
        let key = |a: [f64; 3], b: [f64; 3]| {
            let (p, q) = if a.map(f64::to_bits) < b.map(f64::to_bits) {
                (a, b)
            } else {
                (b, a)
            };
            [p[0], p[1], p[2], q[0], q[1], q[2]].map(|c| (c + 0.0).to_bits())
        };
        for t in mesh.slopes.iter().chain(&mesh.gables) {
            for i in 0..3 {
                *edges.entry(key(t[i], t[(i + 1) % 3])).or_default() += 1;
            }
        }
        for ring in rings {
            for i in 0..ring.len() {
                let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
                *edges
                    .entry(key([a[0], a[1], 0.0], [b[0], b[1], 0.0]))
                    .or_default() += 1;
            }
        }
        edges.values().all(|&n| n == 2)
    }

    #[test]
    fn a_gabled_rectangle_has_one_ridge_of_its_length() {
        let rings = vec![vec![[0.0, 0.0], [10.0, 0.0], [10.0, 6.0], [0.0, 6.0]]];
        let mesh = skeleton_roof(&rings, SkeletonRoof::Gabled, Some(4.0), 0.0).expect("a roof");
        assert_eq!(mesh.gables.len(), 2);
        // The ridge: the corners at full height, at the two ends of the long axis.
        let mut ridge: Vec<[f64; 3]> = corners_at(&mesh, 4.0);
        ridge.sort_by(|a, b| a[0].total_cmp(&b[0]));
        ridge.dedup();
        assert_eq!(ridge, vec![[0.0, 3.0, 4.0], [10.0, 3.0, 4.0]]);
        let (roof, footprint) = plan_areas(&mesh, &rings);
        assert!((roof - footprint).abs() < 1e-9);
        assert!(is_closed_over_the_walls(&mesh, &mesh.rings));
    }

    #[test]
    fn a_hipped_rectangle_rises_at_its_pitch() {
        let rings = vec![vec![[0.0, 0.0], [10.0, 0.0], [10.0, 6.0], [0.0, 6.0]]];
        let mesh = skeleton_roof(&rings, SkeletonRoof::Hipped, None, 0.5).expect("a roof");
        assert!(mesh.gables.is_empty());
        assert!((mesh.height - 1.5).abs() < 1e-9);
        assert!(is_closed_over_the_walls(&mesh, &mesh.rings));
    }

    #[test]
    fn an_l_house_gets_a_ridge_per_wing() {
        let rings = vec![vec![
            [0.0, 0.0],
            [12.0, 0.0],
            [12.0, 6.0],
            [6.0, 6.0],
            [6.0, 14.0],
            [0.0, 14.0],
        ]];
        let mesh = skeleton_roof(&rings, SkeletonRoof::Gabled, Some(3.0), 0.0).expect("a roof");
        // Both wing ends are gables; the ridges run along the wings at x = 3 and y = 3.
        assert_eq!(mesh.gables.len(), 2);
        let top: Vec<[f64; 3]> = corners_at(&mesh, 3.0);
        assert!(top
            .iter()
            .any(|c| c[0] == 12.0 && (c[1] - 3.0).abs() < 1e-9));
        assert!(top
            .iter()
            .any(|c| c[1] == 14.0 && (c[0] - 3.0).abs() < 1e-9));
        let (roof, footprint) = plan_areas(&mesh, &rings);
        assert!((roof - footprint).abs() < 1e-9, "{roof} {footprint}");
        assert!(is_closed_over_the_walls(&mesh, &mesh.rings));
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(1000))]
        #[test]
        fn roofs_on_random_houses_cover_them_and_close_over_the_walls(
            columns in proptest::collection::vec((2u8..6, 2u8..7), 1..6),
            radii in proptest::collection::vec(5.0f64..15.0, 3..12),
            gabled in proptest::bool::ANY,
        ) {
            let shape = if gabled { SkeletonRoof::Gabled } else { SkeletonRoof::Hipped };
            // A rectilinear house of wings side by side, and a random star-shaped one.
            let wings = crate::mesh::skeleton::tests::skyline(&columns);
            let star = crate::mesh::skeleton::tests::star(&radii);
            for ring in [wings, star] {
                let rings = vec![ring];
                let mesh = skeleton_roof(&rings, shape, Some(3.0), 0.0).expect("a roof");
                let (roof, footprint) = plan_areas(&mesh, &rings);
                proptest::prop_assert!((roof - footprint).abs() < 1e-6 * footprint, "{} {}", roof, footprint);
                proptest::prop_assert!(mesh.slopes.iter().flatten().all(|c| c[2] >= -1e-9 && c[2] <= 3.0 + 1e-9));
                proptest::prop_assert!(is_closed_over_the_walls(&mesh, &mesh.rings));
            }
        }
    }

    #[test]
    fn centred_roofs_close_over_their_walls_and_reach_their_height() {
        let octagon: Vec<Point> = (0..8)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 8.0;
                [5.0 * a.cos(), 5.0 * a.sin()]
            })
            .collect();
        for shape in [CentredRoof::Pyramid, CentredRoof::Dome, CentredRoof::Onion] {
            let mesh = centred_roof(&octagon, shape, 4.0).expect("a roof");
            assert!(is_closed_over_the_walls(&mesh, &mesh.rings), "{shape:?}");
            let top = mesh
                .slopes
                .iter()
                .flatten()
                .map(|c| c[2])
                .fold(0.0, f64::max);
            assert!((top - 4.0).abs() < 1e-12, "{shape:?} {top}");
        }
        // An onion bulges out past its walls; a dome stays within them.
        let reach = |shape| {
            centred_roof(&octagon, shape, 4.0)
                .expect("a roof")
                .slopes
                .iter()
                .flatten()
                .map(|c| c[0].hypot(c[1]))
                .fold(0.0, f64::max)
        };
        assert!(reach(CentredRoof::Onion) > 5.5);
        assert!(reach(CentredRoof::Dome) <= 5.0 + 1e-9);
        // An L is not star-shaped around its centroid: no centred roof.
        let l = [
            [0.0, 0.0],
            [10.0, 0.0],
            [10.0, 1.0],
            [1.0, 1.0],
            [1.0, 10.0],
            [0.0, 10.0],
        ];
        assert!(centred_roof(&l, CentredRoof::Pyramid, 3.0).is_none());
        let (inner, outer) = spread(&octagon).expect("star-shaped");
        assert!((inner - 5.0 * (std::f64::consts::PI / 8.0).cos()).abs() < 1e-9);
        assert!((outer - 5.0).abs() < 1e-9);
    }

    #[test]
    fn mansard_and_gambrel_roofs_bend_and_stay_closed() {
        let rings = vec![vec![[0.0, 0.0], [12.0, 0.0], [12.0, 8.0], [0.0, 8.0]]];
        for shape in [SkeletonRoof::Hipped, SkeletonRoof::Gabled] {
            let mut mesh = skeleton_roof(&rings, shape, Some(4.0), 0.0).expect("a roof");
            bend(&mut mesh);
            assert!(is_closed_over_the_walls(&mesh, &mesh.rings), "{shape:?}");
            let (roof, footprint) = plan_areas(&mesh, &rings);
            assert!((roof - footprint).abs() < 1e-9);
            // The knee: 30 % of the way in (1.2 m from the long sides), 70 % up (2.8 m).
            let knee: Vec<[f64; 3]> = corners_at(&mesh, 2.8);
            assert!(!knee.is_empty(), "{shape:?}");
            assert!(knee.iter().all(|c| (c[1] - 1.2).abs() < 1e-9
                || (c[1] - 6.8).abs() < 1e-9
                || c[0] < 1.3
                || c[0] > 10.7));
            let top = mesh
                .slopes
                .iter()
                .flatten()
                .map(|c| c[2])
                .fold(0.0, f64::max);
            assert!((top - 4.0).abs() < 1e-9);
        }
    }

    #[test]
    fn a_courtyard_roof_is_closed() {
        let rings = vec![
            vec![[0.0, 0.0], [20.0, 0.0], [20.0, 16.0], [0.0, 16.0]],
            vec![[6.0, 5.0], [6.0, 11.0], [14.0, 11.0], [14.0, 5.0]],
        ];
        let mesh = skeleton_roof(&rings, SkeletonRoof::Hipped, Some(3.0), 0.0).expect("a roof");
        let (roof, footprint) = plan_areas(&mesh, &rings);
        assert!((roof - footprint).abs() < 1e-9, "{roof} {footprint}");
        assert!(is_closed_over_the_walls(&mesh, &mesh.rings));
    }
}
