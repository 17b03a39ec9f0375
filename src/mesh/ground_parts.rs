//! The ground's triangles sorted into the tile's parts: each triangle goes to the part of the
//! surface it lies in (a road's paving, water, a land cover) or to the bare terrain, facing up
//! in the Y-up frame, with a vertex per part and feature so each part's buffers stand alone.

use std::collections::BTreeMap;

use super::ground::Ground;
use super::{MeshBuffers, Part};
use crate::features::Surface;
use crate::tile::TileFrame;

/// The ground drawn as parts.
#[derive(Debug, Default)]
pub struct GroundParts {
    pub parts: BTreeMap<Part, MeshBuffers>,
    /// The `y` of each ground vertex in the local frame.
    pub vertex_y: Vec<f64>,
    /// Triangles dropped because they collapse or flip once positions are `f32`.
    pub slivers: usize,
}

/// Sorts `ground`'s triangles into parts; `normals` holds a normal per ground vertex.
pub fn ground_parts(
    ground: &Ground,
    surfaces: &[Surface],
    normals: &[[f64; 3]],
    frame: &TileFrame,
) -> GroundParts {
    let vertex_y: Vec<f64> = ground
        .vertices
        .iter()
        .zip(&ground.elevations)
        .map(|(p, &elevation)| frame.elevation_to_y(elevation, p[1]))
        .collect();
    let mut parts: BTreeMap<Part, MeshBuffers> = BTreeMap::new();
    let mut vertex_slots: rustc_hash::FxHashMap<(Part, u32, u32), u32> = Default::default();
    let mut slivers = 0;
    for triangle in &ground.triangles {
        let part = match triangle.surface {
            Some(index) => {
                let surface = &surfaces[index as usize];
                Part::of_ground(surface.class, surface.cover, surface.paving)
                    .map(|part| (part, surface.feature))
            }
            None => Some((Part::Terrain, 0)),
        };
        let Some((part, feature)) = part else {
            continue;
        };
        // Counter-clockwise in (x, z) faces down in a Y-up frame: reverse to face up.
        let [a, b, c] = triangle.vertices;
        if !faces_up_in_f32([a, c, b].map(|v| ground.vertices[v as usize])) {
            // A sliver that collapses or flips at the output's precision covers no area.
            slivers += 1;
            continue;
        }
        let buffers = parts.entry(part).or_default();
        for vertex in [a, c, b] {
            let slot = *vertex_slots
                .entry((part, vertex, feature))
                .or_insert_with(|| {
                    let [x, z] = ground.vertices[vertex as usize];
                    buffers.push_vertex(
                        [x, vertex_y[vertex as usize], z],
                        normals[vertex as usize],
                        feature,
                    )
                });
            buffers.indices.push(slot);
        }
    }
    GroundParts {
        parts,
        vertex_y,
        slivers,
    }
}

/// True when the triangle `(a, b, c)` of local `(x, z)` points, rounded to `f32` as the glb
/// stores them, has a positive area facing +y.
fn faces_up_in_f32(corners: [[f64; 2]; 3]) -> bool {
    let [a, b, c] = corners.map(|p| p.map(|v| f64::from(v as f32)));
    let cross_y = (b[1] - a[1]) * (c[0] - a[0]) - (b[0] - a[0]) * (c[1] - a[1]);
    cross_y > 0.0
}
