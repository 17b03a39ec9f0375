//! Barriers as thin walls: each segment of a barrier's way, clipped to the tile, becomes a box of
//! the barrier's thickness standing on the ground, its foot sunk a little below the terrain so it
//! never floats where the ground mesh lies lower than the terrain model.

use std::collections::BTreeMap;

use super::{LocalSpan, MeshBuffers, Part};
use crate::features::barriers::Barrier;
use crate::features::tile_rect;
use crate::geometry::clip_segment;
use crate::terrain::Elevation;
use crate::tile::TileFrame;

/// Depth the foot of a barrier reaches below the terrain, metres.
const SINK_M: f64 = 0.5;

/// The walls of the barriers, one part per kind.
pub fn build(
    barriers: &[Barrier],
    frame: &TileFrame,
    ground: &dyn Elevation,
) -> BTreeMap<Part, MeshBuffers> {
    let rect = tile_rect(frame.tile);
    let mut parts: BTreeMap<Part, MeshBuffers> = BTreeMap::new();
    for barrier in barriers {
        let buffers = parts.entry(Part::Barrier(barrier.kind)).or_default();
        for pair in barrier.line.windows(2) {
            let Some((a, b)) = clip_segment(pair[0], pair[1], &rect) else {
                continue;
            };
            let Some(span) = LocalSpan::new(frame, a, b) else {
                continue;
            };
            let ((ax, az), (bx, bz), (dx, dz)) = (span.a, span.b, span.direction);
            // Local metres are Mercator metres: scale the true sizes at this latitude.
            let scale = span.scale;
            let half = barrier.thickness_m * scale / 2.0;
            let (nx, nz) = (-dz * half, dx * half);
            let ground =
                |u: f64, v: f64, z: f64| frame.elevation_to_y(ground.elevation_uv([u, v]), z);
            let (ga, gb) = (ground(a[0], a[1], az), ground(b[0], b[1], bz));
            let (bottom_a, bottom_b) = (ga - SINK_M * scale, gb - SINK_M * scale);
            let (top_a, top_b) = (ga + barrier.height_m * scale, gb + barrier.height_m * scale);
            // Kept inside the tile: where a barrier crosses an edge, the neighbour draws the rest.
            let size = frame.size_m;
            let corner = |x: f64, z: f64, side: f64, y: f64| {
                [
                    (x + side * nx).clamp(0.0, size),
                    y,
                    (z + side * nz).clamp(0.0, size),
                ]
            };
            let faces = [
                // The two long sides, the top, and the two ends.
                (
                    [
                        corner(ax, az, 1.0, bottom_a),
                        corner(bx, bz, 1.0, bottom_b),
                        corner(bx, bz, 1.0, top_b),
                        corner(ax, az, 1.0, top_a),
                    ],
                    [nx, 0.0, nz],
                ),
                (
                    [
                        corner(ax, az, -1.0, bottom_a),
                        corner(bx, bz, -1.0, bottom_b),
                        corner(bx, bz, -1.0, top_b),
                        corner(ax, az, -1.0, top_a),
                    ],
                    [-nx, 0.0, -nz],
                ),
                (
                    [
                        corner(ax, az, 1.0, top_a),
                        corner(bx, bz, 1.0, top_b),
                        corner(bx, bz, -1.0, top_b),
                        corner(ax, az, -1.0, top_a),
                    ],
                    [0.0, 1.0, 0.0],
                ),
                (
                    [
                        corner(ax, az, 1.0, bottom_a),
                        corner(ax, az, -1.0, bottom_a),
                        corner(ax, az, -1.0, top_a),
                        corner(ax, az, 1.0, top_a),
                    ],
                    [-dx, 0.0, -dz],
                ),
                (
                    [
                        corner(bx, bz, 1.0, bottom_b),
                        corner(bx, bz, -1.0, bottom_b),
                        corner(bx, bz, -1.0, top_b),
                        corner(bx, bz, 1.0, top_b),
                    ],
                    [dx, 0.0, dz],
                ),
            ];
            for (corners, facing) in faces {
                buffers.push_flat_polygon(&corners, facing, barrier.feature);
            }
        }
    }
    parts.retain(|_, buffers| !buffers.is_empty());
    parts
}
