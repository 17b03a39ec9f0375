//! Trees as instances: one low-polygon model per kind of tree (a trunk and a crown, one unit
//! tall), and per tree a translation, rotation and scale, written with `EXT_mesh_gpu_instancing`.
//!
//! A tree stands where the ground triangulation says it may: a forest tree only on its forest's
//! own ground (not on a road or a path through it, not in a clearing another surface claims), a
//! mapped tree anywhere but under a building or in water. Its foot is placed on the ground mesh
//! itself, and its trunk reaches a little below so it never floats.

use std::collections::BTreeMap;
use std::f64::consts::TAU;

use super::ground::Ground;
use super::{MeshBuffers, Part};
use crate::features::vegetation::{Tree, TreeKind};
use crate::features::{FeatureClass, FeatureSet};
use crate::tile::TileFrame;

/// The instances of one model (a kind of tree in one shade of green).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Instances {
    pub translations: Vec<[f32; 3]>,
    /// Unit quaternions `(x, y, z, w)`.
    pub rotations: Vec<[f32; 4]>,
    pub scales: Vec<[f32; 3]>,
    pub feature_ids: Vec<u32>,
}

impl Instances {
    pub fn len(&self) -> usize {
        self.translations.len()
    }

    pub fn is_empty(&self) -> bool {
        self.translations.is_empty()
    }
}

/// Depth the trunk reaches below the ground, metres.
const SINK_M: f64 = 0.5;
/// Sides of trunks and crowns.
const SIDES: usize = 7;

/// The model of a tree one unit tall, foot at the origin, `y` up: its trunk and its crown.
pub fn model(kind: TreeKind) -> (MeshBuffers, MeshBuffers) {
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

/// Ground triangles in buckets, to find the triangle under a point.
struct Locator<'a> {
    ground: &'a Ground,
    cells: usize,
    size: f64,
    buckets: Vec<Vec<u32>>,
}

impl<'a> Locator<'a> {
    fn new(ground: &'a Ground, size: f64) -> Locator<'a> {
        let cells = 64;
        let mut buckets = vec![Vec::new(); cells * cells];
        let cell = |v: f64| ((v / size * cells as f64).floor().max(0.0) as usize).min(cells - 1);
        for (index, triangle) in ground.triangles.iter().enumerate() {
            let corners = triangle.vertices.map(|v| ground.vertices[v as usize]);
            let (x0, x1) = min_max(corners.map(|p| p[0]));
            let (z0, z1) = min_max(corners.map(|p| p[1]));
            for row in cell(z0)..=cell(z1) {
                for column in cell(x0)..=cell(x1) {
                    buckets[row * cells + column].push(index as u32);
                }
            }
        }
        Locator {
            ground,
            cells,
            size,
            buckets,
        }
    }

    /// The triangle holding `(x, z)` and the barycentric weights of its corners.
    fn locate(&self, x: f64, z: f64) -> Option<(usize, [f64; 3])> {
        let cell = |v: f64| {
            ((v / self.size * self.cells as f64).floor().max(0.0) as usize).min(self.cells - 1)
        };
        self.buckets[cell(z) * self.cells + cell(x)]
            .iter()
            .find_map(|&index| {
                let t = &self.ground.triangles[index as usize];
                let [a, b, c] = t.vertices.map(|v| self.ground.vertices[v as usize]);
                let det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
                if det == 0.0 {
                    return None;
                }
                let l1 = ((x - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (z - a[1])) / det;
                let l2 = ((b[0] - a[0]) * (z - a[1]) - (x - a[0]) * (b[1] - a[1])) / det;
                let l0 = 1.0 - l1 - l2;
                (l0 >= 0.0 && l1 >= 0.0 && l2 >= 0.0).then_some((index as usize, [l0, l1, l2]))
            })
    }
}

fn min_max(values: [f64; 3]) -> (f64, f64) {
    (
        values.iter().copied().fold(f64::INFINITY, f64::min),
        values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    )
}

/// Plants the trees of a tile on its ground: the instances of each model, keyed by its crown's
/// part (kind and shade).
pub fn plant(
    trees: &[Tree],
    feature_set: &FeatureSet,
    ground: &Ground,
    vertex_y: &[f64],
    frame: &TileFrame,
) -> BTreeMap<Part, Instances> {
    let locator = Locator::new(ground, frame.size_m);
    let mut models: BTreeMap<Part, Instances> = BTreeMap::new();
    for tree in trees {
        let (x, z) = frame.uv_to_local(tree.at[0], tree.at[1]);
        let Some((index, weights)) = locator.locate(x, z) else {
            continue;
        };
        let triangle = &ground.triangles[index];
        let surface = triangle.surface;
        let allowed = match tree.forest {
            Some(forest) => surface == Some(forest),
            None => surface.is_none_or(|s| {
                !matches!(
                    feature_set.surfaces[s as usize].class,
                    FeatureClass::Building | FeatureClass::Water
                )
            }),
        };
        if !allowed {
            continue;
        }
        let y: f64 = (0..3)
            .map(|k| weights[k] * vertex_y[triangle.vertices[k] as usize])
            .sum();
        let scale = frame.scale_at(z) * tree.height_m;
        let crown_width = match tree.kind {
            TreeKind::Broadleaved => 1.0,
            TreeKind::Needleleaved => 0.9,
        };
        let half = tree.rotation / 2.0;
        let instances = models
            .entry(Part::TreeCrown(tree.kind, tree.shade))
            .or_default();
        instances
            .translations
            .push([x as f32, (y - SINK_M * frame.scale_at(z)) as f32, z as f32]);
        instances
            .rotations
            .push([0.0, half.sin() as f32, 0.0, half.cos() as f32]);
        instances.scales.push([
            (scale * crown_width) as f32,
            scale as f32,
            (scale * crown_width) as f32,
        ]);
        instances.feature_ids.push(tree.feature);
    }
    models
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn models_are_closed_enough_and_face_outwards() {
        for kind in [TreeKind::Broadleaved, TreeKind::Needleleaved] {
            let (trunk, crown) = model(kind);
            for part in [&trunk, &crown] {
                assert!(part.triangle_count() >= SIDES);
                for t in part.indices.chunks_exact(3) {
                    let [a, b, c] = [t[0], t[1], t[2]].map(|i| part.positions[i as usize]);
                    let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                    let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                    let n = [
                        e1[1] * e2[2] - e1[2] * e2[1],
                        e1[2] * e2[0] - e1[0] * e2[2],
                        e1[0] * e2[1] - e1[1] * e2[0],
                    ];
                    // The winding agrees with the stored normal of the first corner.
                    let stored = part.normals[t[0] as usize];
                    let dot = n[0] * stored[0] + n[1] * stored[1] + n[2] * stored[2];
                    assert!(dot > 0.0, "{kind:?}: a triangle faces inwards");
                }
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
