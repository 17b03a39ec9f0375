//! The ground's triangles sorted into the tile's parts: each triangle goes to the part of the
//! surface it lies in (a road's paving, water, a land cover) or to the bare terrain, facing up
//! in the Y-up frame, with a vertex per part and feature so each part's buffers stand alone.

use std::collections::BTreeMap;

use super::ground::Ground;
use super::ground_look::{GroundLook, Site};
use super::{dot, triangle_normal, MeshBuffers, Part};
use crate::features::{FeatureClass, FeatureInfo, Surface};
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

/// Sorts `ground`'s triangles into parts; `normals` holds a normal per ground vertex. Along the
/// tile's sides the ground hangs a skirt `skirt_y` deep (local units; none when 0).
pub fn ground_parts(
    ground: &Ground,
    (surfaces, features): (&[Surface], &[FeatureInfo]),
    normals: &[[f64; 3]],
    frame: &TileFrame,
    skirt_y: f64,
) -> GroundParts {
    let vertex_y: Vec<f64> = ground
        .vertices
        .iter()
        .zip(&ground.elevations)
        .map(|(p, &elevation)| frame.elevation_to_y(elevation, p[1]))
        .collect();
    let mut parts: BTreeMap<Part, MeshBuffers> = BTreeMap::new();
    let mut vertex_slots: rustc_hash::FxHashMap<(Part, u32, u32), u32> = Default::default();
    let mut skirt = Skirt {
        size: frame.size_m,
        depth: skirt_y,
        edges: Vec::new(),
    };
    let mut slivers = 0;
    let look = GroundLook::new(frame);
    let at_building = building_outlines(ground, surfaces);
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
        let varies = GroundLook::varies(part);
        let (element, large) = match triangle.surface {
            Some(index) => (
                features.get(feature as usize).and_then(|f| f.element),
                spans_parcels(&surfaces[index as usize], frame.size_m),
            ),
            None => (None, true),
        };
        // Water lies level, or all but: straight up is its normal. The ground vertex's own,
        // averaged with the banks and cliffs that share it, would streak a sea kilometres
        // wide with the coast's slopes.
        let up = part == Part::Water;
        for vertex in [a, c, b] {
            let slot = *vertex_slots
                .entry((part, vertex, feature))
                .or_insert_with(|| {
                    let [x, z] = ground.vertices[vertex as usize];
                    if varies {
                        let site = Site {
                            at: [x, z],
                            elevation_m: ground.elevations[vertex as usize],
                            up: normals[vertex as usize][1],
                            element,
                            at_building: at_building[vertex as usize],
                            large,
                        };
                        buffers.paint(look.colour(part, &site));
                    }
                    buffers.push_vertex(
                        [x, vertex_y[vertex as usize], z],
                        if up {
                            [0.0, 1.0, 0.0]
                        } else {
                            normals[vertex as usize]
                        },
                        feature,
                    )
                });
            buffers.indices.push(slot);
        }
        skirt.collect([a, c, b], ground);
    }
    if skirt_y > 0.0 && !skirt.edges.is_empty() {
        parts.insert(Part::Skirt, skirt.build(ground, &vertex_y, normals));
    }
    GroundParts {
        parts,
        vertex_y,
        slivers,
    }
}

/// Whether a surface spans more than a couple of the land's parcels (its bounds in global
/// tile units, `size` map metres to the unit).
fn spans_parcels(surface: &Surface, size: f64) -> bool {
    let (w, h) = (
        surface.bounds.max[0] - surface.bounds.min[0],
        surface.bounds.max[1] - surface.bounds.min[1],
    );
    w.max(h) * size > super::ground_look::FIELD_M
}

/// Which ground vertices lie on a building's outline: the corners of the triangles under a
/// building's footprint (which the tile leaves out) that the ground around it shares.
fn building_outlines(ground: &Ground, surfaces: &[Surface]) -> Vec<bool> {
    let mut outline = vec![false; ground.vertices.len()];
    for triangle in &ground.triangles {
        let under_building = triangle
            .surface
            .is_some_and(|index| surfaces[index as usize].class == FeatureClass::Building);
        if under_building {
            for v in triangle.vertices {
                outline[v as usize] = true;
            }
        }
    }
    outline
}

/// The ground's skirt: under each edge of a ground triangle that lies along a side of the
/// tile, a strip straight down, so where a neighbour of another zoom (another error bound)
/// meets the side higher or lower, no crack opens between them. One part of its own, so the
/// ground's parts stay surfaces and a viewer may hide it. Its top vertices are the ground's
/// edge vertices (same normals); the bottom ones copy them a fixed depth under the `f32` top,
/// so two neighbours hang the same skirt along their side.
struct Skirt {
    size: f64,
    depth: f64,
    /// The edges along the sides, as ground vertex pairs in the order their triangle faces up.
    edges: Vec<(u32, u32)>,
}

impl Skirt {
    /// Keeps the edges of a ground triangle (its vertices in the order it faces up) that lie
    /// along a side of the tile.
    fn collect(&mut self, vertices: [u32; 3], ground: &Ground) {
        for k in 0..3 {
            let (a, b) = (vertices[k], vertices[(k + 1) % 3]);
            let (p, q) = (ground.vertices[a as usize], ground.vertices[b as usize]);
            let along = |axis: usize| {
                (p[axis] == 0.0 && q[axis] == 0.0) || (p[axis] == self.size && q[axis] == self.size)
            };
            if p != q && (along(0) || along(1)) {
                self.edges.push((a, b));
            }
        }
    }

    /// The skirt's buffers: a strip under each edge kept, facing out of the tile.
    fn build(&self, ground: &Ground, vertex_y: &[f64], normals: &[[f64; 3]]) -> MeshBuffers {
        let mut buffers = MeshBuffers::default();
        let mut slots: rustc_hash::FxHashMap<u32, [u32; 2]> = Default::default();
        for &(a, b) in &self.edges {
            let [[top_a, bottom_a], [top_b, bottom_b]] = [a, b].map(|v| {
                *slots.entry(v).or_insert_with(|| {
                    let [x, z] = ground.vertices[v as usize];
                    let y = f64::from(vertex_y[v as usize] as f32);
                    let normal = normals[v as usize];
                    [
                        buffers.push_vertex([x, y, z], normal, 0),
                        buffers.push_vertex([x, y - self.depth, z], normal, 0),
                    ]
                })
            });
            // The strip unfolded outwards across the edge would face up: folded down, it
            // faces out of the tile.
            buffers
                .indices
                .extend_from_slice(&[top_b, top_a, bottom_a, top_b, bottom_a, bottom_b]);
        }
        buffers
    }
}

/// The least area of a face of bare rock, square metres (of the local frame): smaller steep
/// faces are where the ground meets what stands on it (a road's profile off the terrain, a
/// cut) rather than the land's own slope.
const ROCK_FACE_M2: f64 = 60.0;

/// Whether a ground triangle (local `(x, y, z)`, the Mercator scale the same across and up)
/// is a face of the land too steep for soil.
fn too_steep_for_soil(corners: [[f64; 3]; 3]) -> bool {
    let normal = triangle_normal(corners);
    let length = dot(normal, normal).sqrt();
    0.5 * length >= ROCK_FACE_M2 && normal[1].abs() < super::ground_look::SOIL_HOLDS_COS * length
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
