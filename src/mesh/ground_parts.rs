//! The ground's triangles sorted into the tile's parts: each triangle goes to the part of the
//! surface it lies in (a road's paving, water, a land cover) or to the bare terrain, facing up
//! in the Y-up frame, with a vertex per part and feature so each part's buffers stand alone.

use std::collections::BTreeMap;

use super::ground::Ground;
use super::{dot, triangle_normal, MeshBuffers, Part};
use crate::features::Surface;
use crate::tile::TileFrame;

/// The ground drawn as parts.
#[derive(Debug, Default)]
pub struct GroundParts {
    pub parts: BTreeMap<Part, MeshBuffers>,
    /// The `y` of each ground vertex in the local frame.
    pub vertex_y: Vec<f64>,
    /// Triangles dropped because they collapse once positions are `f32`: their three corners
    /// lie on a line (or two of them meet), so they cover nothing.
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
        let Some((mut part, feature)) = part else {
            continue;
        };
        // Counter-clockwise in (x, z) faces down in a Y-up frame: reverse to face up.
        let [a, b, c] = triangle.vertices;
        let corners = [a, c, b].map(|v| {
            let [x, z] = ground.vertices[v as usize];
            [x, vertex_y[v as usize], z]
        });
        if part == Part::Terrain && too_steep_for_soil(corners) {
            part = Part::Rock;
        }
        if !covers_in_f32(corners) {
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

/// The steepest bare ground that keeps its soil and grass, as the cosine of its slope (40°,
/// about the angle of repose of soil): the terrain, an approximation of 30 m SRTM samples,
/// rounds cliffs off, so a face steeper than this is mostly rock in the land it stands for.
const SOIL_HOLDS_COS: f64 = 0.766;

/// The least area of a face of bare rock, square metres (of the local frame): smaller steep
/// faces are where the ground meets what stands on it (a road's profile off the terrain, a
/// cut) rather than the land's own slope.
const ROCK_FACE_M2: f64 = 60.0;

/// Whether a ground triangle (local `(x, y, z)`, the Mercator scale the same across and up)
/// is a face of the land too steep for soil.
fn too_steep_for_soil(corners: [[f64; 3]; 3]) -> bool {
    let normal = triangle_normal(corners);
    let length = dot(normal, normal).sqrt();
    0.5 * length >= ROCK_FACE_M2 && normal[1].abs() < SOIL_HOLDS_COS * length
}

/// The least area, in square metres, of a ground triangle that stands almost upright (where
/// the ground steps at a kerb or a cliff) for it to be drawn: smaller ones are seen as lines.
const UPRIGHT_AREA_M2: f64 = 1e-4;
/// How far from upright such a triangle may lean (the cosine of its normal with the vertical):
/// one leaning further that flips at `f32` is a flat sliver, seen from below.
const UPRIGHT_TILT: f64 = 0.05;

/// True when the triangle of local `(x, y, z)` points, rounded to `f32` as the glb stores them,
/// covers something: it faces up (a positive area seen from above), or it stands upright
/// with an area of its own. Dropping the upright ones would open a crack in the ground where
/// its elevation steps between two points the tile's precision sees as one place.
fn covers_in_f32(corners: [[f64; 3]; 3]) -> bool {
    let normal = triangle_normal(corners.map(|p| p.map(|v| f64::from(v as f32))));
    let length = dot(normal, normal).sqrt();
    let upright = normal[1].abs() <= UPRIGHT_TILT * length;
    normal[1] > 0.0 || (upright && 0.5 * length >= UPRIGHT_AREA_M2)
}
