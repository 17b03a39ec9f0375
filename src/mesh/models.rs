//! The models drawn as instances (`EXT_mesh_gpu_instancing`): trees, and the objects of street
//! level a simple shape describes well enough (street lamps, benches, bollards, street
//! furniture, signals and signs, power poles and towers, wind turbines). Each model is built
//! once, foot at the origin, `y` up and its front towards `-z` (north before it is turned), in
//! metres (trees one unit tall, scaled per instance), from surfaces of revolution, boxes and
//! flat plates.

use std::f64::consts::TAU;

use super::{MeshBuffers, Part};
use crate::features::objects::ObjectKind;
use crate::features::vegetation::TreeKind;

/// A model drawn as instances.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Model {
    /// A tree of a kind in one of [`crate::features::vegetation::SHADES`] shades.
    Tree(TreeKind, u8),
    Object(ObjectKind),
}

impl Model {
    /// The model's name (its glTF node and mesh).
    pub fn name(self) -> &'static str {
        match self {
            Model::Tree(kind, shade) => Part::TreeCrown(kind, shade).name(),
            Model::Object(kind) => kind.as_str(),
        }
    }

    /// The model's primitives, each with its part (material).
    pub fn parts(self) -> Vec<(Part, MeshBuffers)> {
        match self {
            Model::Tree(kind, shade) => {
                let (trunk, crown) = tree(kind);
                vec![
                    (Part::TreeTrunk, trunk),
                    (Part::TreeCrown(kind, shade), crown),
                ]
            }
            Model::Object(kind) => vec![(Part::Object(kind), object(kind))],
        }
    }
}

/// Sides of round shapes.
const SIDES: usize = 7;

/// The model of a tree one unit tall, foot at the origin, `y` up: its trunk and its crown.
fn tree(kind: TreeKind) -> (MeshBuffers, MeshBuffers) {
    let mut trunk = MeshBuffers::default();
    let mut crown = MeshBuffers::default();
    match kind {
        TreeKind::Broadleaved => {
            lathe(&mut trunk, &[(0.045, -0.05), (0.035, 0.45)]);
            // A rounded crown: an ellipsoid-like profile from bottom to top.
            lathe(
                &mut crown,
                &[
                    (0.0, 0.32),
                    (0.26, 0.40),
                    (0.36, 0.58),
                    (0.33, 0.78),
                    (0.20, 0.94),
                    (0.0, 1.0),
                ],
            );
        }
        TreeKind::Needleleaved => {
            lathe(&mut trunk, &[(0.035, -0.05), (0.025, 0.30)]);
            lathe(
                &mut crown,
                &[
                    (0.0, 0.18),
                    (0.24, 0.22),
                    (0.16, 0.55),
                    (0.11, 0.62),
                    (0.0, 1.0),
                ],
            );
        }
    }
    (trunk, crown)
}

/// An object's shape, in metres.
fn object(kind: ObjectKind) -> MeshBuffers {
    let mut b = MeshBuffers::default();
    match kind {
        ObjectKind::StreetLamp => {
            lathe(&mut b, &[(0.09, -0.3), (0.06, 5.8)]);
            lathe(
                &mut b,
                &[(0.0, 5.75), (0.32, 5.85), (0.26, 6.05), (0.0, 6.1)],
            );
        }
        ObjectKind::Bench => {
            cuboid(&mut b, [-0.9, 0.42, -0.25], [0.9, 0.48, 0.25]);
            cuboid(&mut b, [-0.9, 0.48, 0.2], [0.9, 0.9, 0.25]);
            cuboid(&mut b, [-0.85, -0.2, -0.2], [-0.75, 0.42, 0.2]);
            cuboid(&mut b, [0.75, -0.2, -0.2], [0.85, 0.42, 0.2]);
        }
        ObjectKind::Bollard => lathe(&mut b, &[(0.1, -0.2), (0.1, 0.9), (0.0, 1.0)]),
        ObjectKind::PowerPole => {
            lathe(&mut b, &[(0.14, -0.5), (0.1, 10.0)]);
            cuboid(&mut b, [-1.0, 9.3, -0.06], [1.0, 9.45, 0.06]);
        }
        ObjectKind::PowerTower => {
            lathe(&mut b, &[(2.5, -0.5), (0.6, 28.0), (0.0, 32.0)]);
            cuboid(&mut b, [-7.0, 24.0, -0.3], [7.0, 24.8, 0.3]);
            cuboid(&mut b, [-5.0, 19.0, -0.3], [5.0, 19.8, 0.3]);
        }
        ObjectKind::WindTurbine => {
            lathe(&mut b, &[(2.2, -1.0), (1.2, 80.0)]);
            cuboid(&mut b, [-1.5, 79.0, -2.0], [1.5, 82.5, 8.0]);
            // Three blades in the plane in front of the hub, 40 m long.
            for k in 0..3 {
                let angle = TAU * k as f64 / 3.0;
                let (c, s) = (angle.cos(), angle.sin());
                let blade = |r: f64, w: f64| [r * c - w * s, 80.75 + r * s + w * c];
                let (p0, p1, p2, p3) = (
                    blade(1.5, -0.9),
                    blade(40.0, -0.3),
                    blade(40.0, 0.3),
                    blade(1.5, 0.9),
                );
                for (z, facing) in [(-2.3, -1.0), (-2.1, 1.0)] {
                    b.push_flat_polygon(
                        &[
                            [p0[0], p0[1], z],
                            [p1[0], p1[1], z],
                            [p2[0], p2[1], z],
                            [p3[0], p3[1], z],
                        ],
                        [0.0, 0.0, facing],
                        0,
                    );
                }
            }
        }
        other => furniture(&mut b, other),
    }
    b
}

/// Street furniture, signals and signs, in metres.
fn furniture(b: &mut MeshBuffers, kind: ObjectKind) {
    match kind {
        ObjectKind::WasteBasket => lathe(b, &[(0.2, -0.05), (0.22, 0.85), (0.0, 0.85)]),
        ObjectKind::PostBox => {
            cuboid(b, [-0.06, -0.2, -0.06], [0.06, 0.8, 0.06]);
            cuboid(b, [-0.22, 0.8, -0.18], [0.22, 1.35, 0.18]);
        }
        ObjectKind::FireHydrant => {
            lathe(b, &[(0.13, -0.05), (0.11, 0.55), (0.09, 0.62), (0.0, 0.72)]);
            cuboid(b, [-0.2, 0.35, -0.05], [0.2, 0.45, 0.05]);
        }
        ObjectKind::BusStop => {
            lathe(b, &[(0.045, -0.3), (0.04, 2.7)]);
            cuboid(b, [-0.25, 2.15, -0.07], [0.25, 2.7, -0.04]);
        }
        ObjectKind::BusShelter => {
            // A roof on four posts, closed at the back and one side, open to the road (north).
            cuboid(b, [-1.6, 2.35, -0.8], [1.6, 2.5, 0.8]);
            for x in [-1.55, 1.5] {
                for z in [-0.75, 0.7] {
                    cuboid(b, [x, -0.1, z], [x + 0.05, 2.35, z + 0.05]);
                }
            }
            cuboid(b, [-1.55, 0.1, 0.7], [1.55, 2.3, 0.74]);
            cuboid(b, [-1.55, 0.1, -0.75], [-1.51, 2.3, 0.7]);
            cuboid(b, [-1.2, 0.42, 0.3], [1.2, 0.47, 0.65]);
        }
        ObjectKind::BicycleParking => {
            // Three stands, each an inverted U of tube.
            for x in [-0.8, 0.0, 0.8] {
                cuboid(b, [x - 0.03, -0.2, -0.4], [x + 0.03, 0.8, -0.34]);
                cuboid(b, [x - 0.03, -0.2, 0.34], [x + 0.03, 0.8, 0.4]);
                cuboid(b, [x - 0.03, 0.8, -0.4], [x + 0.03, 0.86, 0.4]);
            }
        }
        ObjectKind::Flagpole => lathe(b, &[(0.07, -0.3), (0.04, 8.0), (0.06, 8.05), (0.0, 8.12)]),
        ObjectKind::Memorial => {
            cuboid(b, [-0.55, -0.2, -0.3], [0.55, 0.25, 0.3]);
            cuboid(b, [-0.4, 0.25, -0.15], [0.4, 1.7, 0.15]);
        }
        ObjectKind::TrafficSignals => {
            lathe(b, &[(0.07, -0.3), (0.06, 3.3)]);
            cuboid(b, [-0.17, 2.2, -0.3], [0.17, 3.1, -0.07]);
        }
        ObjectKind::StopSign => {
            lathe(b, &[(0.03, -0.3), (0.03, 2.3)]);
            // An octagon 0.7 m across, facing north.
            let corners: Vec<[f64; 3]> = (0..8)
                .map(|k| {
                    let angle = TAU * (k as f64 + 0.5) / 8.0;
                    [0.38 * angle.cos(), 2.05 + 0.38 * angle.sin(), -0.05]
                })
                .collect();
            plate(b, &corners, 0.02);
        }
        ObjectKind::Door => {
            // A door leaf in its frame, 1 m by 2.1 m, facing north out of a wall just behind
            // the foot (at z = 0.05), standing 6 cm out of it.
            cuboid(b, [-0.5, -0.15, -0.01], [0.5, 2.1, 0.1]);
        }
        ObjectKind::GiveWaySign => {
            lathe(b, &[(0.03, -0.3), (0.03, 2.2)]);
            // A triangle point down, 0.8 m a side, facing north.
            plate(
                b,
                &[[-0.4, 2.55, -0.05], [0.4, 2.55, -0.05], [0.0, 1.86, -0.05]],
                0.02,
            );
        }
        _ => {}
    }
}

/// A flat plate: `corners` (a convex polygon in a plane of constant `z`) facing `-z`, and its
/// back `thickness` metres behind facing `+z`.
fn plate(b: &mut MeshBuffers, corners: &[[f64; 3]], thickness: f64) {
    b.push_flat_polygon(corners, [0.0, 0.0, -1.0], 0);
    let back: Vec<[f64; 3]> = corners
        .iter()
        .map(|c| [c[0], c[1], c[2] + thickness])
        .collect();
    b.push_flat_polygon(&back, [0.0, 0.0, 1.0], 0);
}

/// A surface of revolution about `y` through the profile points `(radius, height)`, bottom to
/// top, with smooth normals around and flat steps between rings.
fn lathe(buffers: &mut MeshBuffers, profile: &[(f64, f64)]) {
    for pair in profile.windows(2) {
        let ((r0, y0), (r1, y1)) = (pair[0], pair[1]);
        // The normal of a cone band: outward, tilted by the band's slope.
        let (dr, dy) = (r1 - r0, y1 - y0);
        let length = (dr * dr + dy * dy).sqrt();
        if length == 0.0 {
            continue;
        }
        let (nr, ny) = (dy / length, -dr / length);
        let first = buffers.positions.len() as u32;
        for k in 0..=SIDES {
            let angle = TAU * k as f64 / SIDES as f64;
            let (c, s) = (angle.cos(), angle.sin());
            let normal = [nr * c, ny, nr * s];
            buffers.push_vertex([r0 * c, y0, r0 * s], normal, 0);
            buffers.push_vertex([r1 * c, y1, r1 * s], normal, 0);
        }
        for k in 0..SIDES as u32 {
            let (a, b, c, d) = (
                first + 2 * k,
                first + 2 * k + 1,
                first + 2 * k + 2,
                first + 2 * k + 3,
            );
            // Counter-clockwise seen from outside.
            if r0 > 0.0 {
                buffers.indices.extend_from_slice(&[a, b, c]);
            }
            if r1 > 0.0 {
                buffers.indices.extend_from_slice(&[c, b, d]);
            }
        }
    }
    // Close a trunk's bottom so it is solid from below too.
    if let Some(&(r, y)) = profile.first() {
        if r > 0.0 {
            let centre = buffers.push_vertex([0.0, y, 0.0], [0.0, -1.0, 0.0], 0);
            let first = buffers.positions.len() as u32;
            for k in 0..SIDES {
                let angle = TAU * k as f64 / SIDES as f64;
                buffers.push_vertex([r * angle.cos(), y, r * angle.sin()], [0.0, -1.0, 0.0], 0);
            }
            for k in 0..SIDES as u32 {
                let next = (k + 1) % SIDES as u32;
                buffers
                    .indices
                    .extend_from_slice(&[centre, first + k, first + next]);
            }
        }
    }
}

/// An axis-aligned box from `min` to `max`.
fn cuboid(buffers: &mut MeshBuffers, min: [f64; 3], max: [f64; 3]) {
    let [x0, y0, z0] = min;
    let [x1, y1, z1] = max;
    let faces = [
        (
            [[x0, y0, z0], [x0, y1, z0], [x0, y1, z1], [x0, y0, z1]],
            [-1.0, 0.0, 0.0],
        ),
        (
            [[x1, y0, z0], [x1, y1, z0], [x1, y1, z1], [x1, y0, z1]],
            [1.0, 0.0, 0.0],
        ),
        (
            [[x0, y0, z0], [x1, y0, z0], [x1, y0, z1], [x0, y0, z1]],
            [0.0, -1.0, 0.0],
        ),
        (
            [[x0, y1, z0], [x1, y1, z0], [x1, y1, z1], [x0, y1, z1]],
            [0.0, 1.0, 0.0],
        ),
        (
            [[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0]],
            [0.0, 0.0, -1.0],
        ),
        (
            [[x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]],
            [0.0, 0.0, 1.0],
        ),
    ];
    for (corners, facing) in faces {
        buffers.push_flat_polygon(&corners, facing, 0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_object_stands_on_its_foot_with_its_faces_outwards() {
        for kind in ObjectKind::ALL {
            let model = object(kind);
            assert!(model.triangle_count() >= 4, "{kind:?} has no shape");
            let low = model
                .positions
                .iter()
                .map(|p| p[1])
                .fold(f32::MAX, f32::min);
            let high = model
                .positions
                .iter()
                .map(|p| p[1])
                .fold(f32::MIN, f32::max);
            assert!(low <= 0.0 && high > 0.5, "{kind:?} from {low} to {high}");
            assert!(
                windings(&model).iter().all(|&dot| dot >= 0.0),
                "{kind:?}: a triangle faces inwards"
            );
        }
    }

    /// For each triangle, how far its winding agrees with the stored normal of its first
    /// corner (positive: it faces the way its normal says).
    fn windings(part: &MeshBuffers) -> Vec<f32> {
        part.indices
            .chunks_exact(3)
            .map(|t| {
                let [a, b, c] = [t[0], t[1], t[2]].map(|i| part.positions[i as usize]);
                let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                let n = [
                    e1[1] * e2[2] - e1[2] * e2[1],
                    e1[2] * e2[0] - e1[0] * e2[2],
                    e1[0] * e2[1] - e1[1] * e2[0],
                ];
                let stored = part.normals[t[0] as usize];
                n[0] * stored[0] + n[1] * stored[1] + n[2] * stored[2]
            })
            .collect()
    }

    #[test]
    fn models_are_closed_enough_and_face_outwards() {
        for kind in [TreeKind::Broadleaved, TreeKind::Needleleaved] {
            let (trunk, crown) = tree(kind);
            for part in [&trunk, &crown] {
                assert!(part.triangle_count() >= SIDES);
                // The winding agrees with the stored normal of the first corner.
                assert!(
                    windings(part).iter().all(|&dot| dot > 0.0),
                    "{kind:?}: a triangle faces inwards"
                );
            }
            // One unit tall, the trunk reaching below the ground.
            let top = crown
                .positions
                .iter()
                .map(|p| p[1])
                .fold(f32::MIN, f32::max);
            let bottom = trunk
                .positions
                .iter()
                .map(|p| p[1])
                .fold(f32::MAX, f32::min);
            assert!((top - 1.0).abs() < 1e-6 && bottom < 0.0);
        }
    }
}
