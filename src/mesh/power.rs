//! Power line conductors: each span between two supports sags a little (3 % of its length at
//! mid-span) and is drawn as thin beams, clipped to the tile.

use super::{LocalSpan, MeshBuffers};
use crate::features::power::PowerLine;
use crate::features::tile_rect;
use crate::geometry::clip_segment;
use crate::terrain::Elevation;
use crate::tile::TileFrame;

/// Pieces each span is drawn in.
const PIECES: usize = 6;
/// Sag at mid-span as a fraction of the span's length.
const SAG: f64 = 0.03;
/// Half the thickness of a conductor as drawn, metres (thicker than life, so it shows).
const HALF_THICKNESS_M: f64 = 0.06;

/// The conductors of the power lines.
pub fn build(lines: &[PowerLine], frame: &TileFrame, ground: &dyn Elevation) -> MeshBuffers {
    let rect = tile_rect(frame.tile);
    let mut buffers = MeshBuffers::default();
    for line in lines {
        for (k, pair) in line.line.windows(2).enumerate() {
            let (a, b) = (pair[0], pair[1]);
            if clip_segment(a, b, &rect).is_none() {
                continue;
            }
            let Some(span) = LocalSpan::new(frame, a, b) else {
                continue;
            };
            let ((_, az), (_, bz), (dx, dz)) = (span.a, span.b, span.direction);
            let (length, scale) = (span.length, span.scale);
            let top = |p: [f64; 2], z: f64, height: f64| {
                frame.elevation_to_y(ground.elevation_uv(p), z) + height * scale
            };
            let (ya, yb) = (
                top(a, az, line.heights_m[k]),
                top(b, bz, line.heights_m[k + 1]),
            );
            for &offset in &line.offsets_m {
                let (ox, oz) = (-dz * offset * scale, dx * offset * scale);
                let at = |t: f64| {
                    let sag = SAG * length * 4.0 * t * (1.0 - t);
                    [
                        a[0] + t * (b[0] - a[0]),
                        a[1] + t * (b[1] - a[1]),
                        ya + t * (yb - ya) - sag,
                    ]
                };
                for piece in 0..PIECES {
                    let (p, q) = (
                        at(piece as f64 / PIECES as f64),
                        at((piece + 1) as f64 / PIECES as f64),
                    );
                    let Some((p2, q2)) = clip_segment([p[0], p[1]], [q[0], q[1]], &rect) else {
                        continue;
                    };
                    // Heights at the clipped ends, along the piece.
                    let along = |r: [f64; 2]| {
                        let d = [q[0] - p[0], q[1] - p[1]];
                        let n = d[0] * d[0] + d[1] * d[1];
                        if n == 0.0 {
                            0.0
                        } else {
                            ((r[0] - p[0]) * d[0] + (r[1] - p[1]) * d[1]) / n
                        }
                    };
                    let place = |r: [f64; 2]| {
                        let (x, z) = frame.uv_to_local(r[0], r[1]);
                        let y = p[2] + along(r) * (q[2] - p[2]);
                        [
                            (x + ox).clamp(0.0, frame.size_m),
                            y,
                            (z + oz).clamp(0.0, frame.size_m),
                        ]
                    };
                    push_beam(
                        &mut buffers,
                        place(p2),
                        place(q2),
                        HALF_THICKNESS_M * scale,
                        frame.size_m,
                        line.feature,
                    );
                }
            }
        }
    }
    buffers
}

/// A thin beam of square section from `a` to `b`: its four long sides, kept inside the tile's
/// square `0..size`.
fn push_beam(
    buffers: &mut MeshBuffers,
    a: [f64; 3],
    b: [f64; 3],
    half: f64,
    size: f64,
    feature: u32,
) {
    let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let horizontal = (d[0] * d[0] + d[2] * d[2]).sqrt();
    if horizontal < 1e-9 {
        return;
    }
    // Sideways (horizontal, across the beam) and up (perpendicular to it).
    let side = [-d[2] / horizontal * half, 0.0, d[0] / horizontal * half];
    let up = [0.0, half, 0.0];
    let offset = |p: [f64; 3], s: f64, u: f64| {
        [
            (p[0] + s * side[0] + u * up[0]).clamp(0.0, size),
            p[1] + s * side[1] + u * up[1],
            (p[2] + s * side[2] + u * up[2]).clamp(0.0, size),
        ]
    };
    for (s0, u0, s1, u1, facing) in [
        (1.0, -1.0, 1.0, 1.0, side),
        (-1.0, -1.0, -1.0, 1.0, side.map(|c| -c)),
        (-1.0, 1.0, 1.0, 1.0, up),
        (-1.0, -1.0, 1.0, -1.0, up.map(|c| -c)),
    ] {
        buffers.push_flat_polygon(
            &[
                offset(a, s0, u0),
                offset(a, s1, u1),
                offset(b, s1, u1),
                offset(b, s0, u0),
            ],
            facing,
            feature,
        );
    }
}
