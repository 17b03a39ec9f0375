//! Steps drawn as steps: a `highway=steps` way is a ramp in the ground (a road of the network,
//! on its settled profile) with a flight of treads over it, each level at the higher end of
//! its stretch of the ramp as the tile draws it, so the ramp rises in risers. The treads are
//! counted along the whole way, so tiles either side of an edge cut the same flight.

use super::MeshBuffers;
use crate::features::carriageways::Stairs;
use crate::geometry::{polyline_length, Point};
use crate::terrain::Elevation;
use crate::tile::TileFrame;

/// The least going of a tread, metres (a comfortable stair has 0.25–0.32 m).
const LEAST_GOING_M: f64 = 0.25;
/// The rise of a step, metres (outdoor stairs have 0.15–0.19 m): a flight has as many as its
/// ramp climbs and falls in all.
const RISER_M: f64 = 0.19;
/// A tread whose ends differ by less than this is a landing: the ramp shows, metres.
const LEAST_RISE_M: f64 = 0.02;
/// Depth a tread's riser and sides reach below the lower end of its ramp, metres.
const SINK_M: f64 = 0.1;

/// The treads of every flight of steps, clipped to the tile.
pub fn build(stairs: &[Stairs], frame: &TileFrame, ground: &dyn Elevation) -> MeshBuffers {
    let mut buffers = MeshBuffers::default();
    for flight in stairs {
        let length = polyline_length(&flight.line);
        // How far the ramp climbs and falls in all, at the least going's spacing.
        let fine = evenly(&flight.line, length, least_treads(length, flight.metre));
        let heights: Vec<f64> = fine.iter().map(|&p| ground.elevation_uv(p)).collect();
        let travel: f64 = heights.windows(2).map(|h| (h[1] - h[0]).abs()).sum();
        let count = ((travel / RISER_M).round() as usize).clamp(1, fine.len().max(2) - 1);
        let points = evenly(&flight.line, length, count);
        for pair in points.windows(2) {
            push_tread(&mut buffers, flight, pair[0], pair[1], frame, ground);
        }
    }
    buffers
}

/// How many treads of the least going a line of `length` tile units holds (`metre` of them
/// to a metre); at least one.
fn least_treads(length: f64, metre: f64) -> usize {
    if metre <= 0.0 {
        return 1;
    }
    ((length / metre / LEAST_GOING_M).floor() as usize).max(1)
}

/// `count + 1` points spaced evenly along `line` of `length`, both ends included.
fn evenly(line: &[Point], length: f64, count: usize) -> Vec<Point> {
    let step = length / count.max(1) as f64;
    (0..=count.max(1))
        .map(|k| point_at(line, k as f64 * step))
        .collect()
}

/// The point `along` tile units from the start of `line`.
fn point_at(line: &[Point], mut along: f64) -> Point {
    for pair in line.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let length = (b[0] - a[0]).hypot(b[1] - a[1]);
        if along <= length && length > 0.0 {
            let t = along / length;
            return [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
        }
        along -= length;
    }
    line.last().copied().unwrap_or([0.0, 0.0])
}

/// One tread from `a` to `b` (tile units): its top level at the higher end of the ramp, the
/// flight's width, with a riser at the lower end and a side each way down to the ramp; kept
/// inside the tile (a neighbour draws the rest of one that crosses an edge).
fn push_tread(
    buffers: &mut MeshBuffers,
    flight: &Stairs,
    a: Point,
    b: Point,
    frame: &TileFrame,
    ground: &dyn Elevation,
) {
    let rect = crate::features::tile_rect(frame.tile);
    let inside = |p: Point| {
        p[0] >= rect.min[0] && p[0] <= rect.max[0] && p[1] >= rect.min[1] && p[1] <= rect.max[1]
    };
    if !inside(a) && !inside(b) {
        return;
    }
    let (ha, hb) = (ground.elevation_uv(a), ground.elevation_uv(b));
    if (hb - ha).abs() < LEAST_RISE_M {
        return;
    }
    let Some(span) = super::LocalSpan::new(frame, a, b) else {
        return;
    };
    let ((ax, az), (bx, bz), (dx, dz)) = (span.a, span.b, span.direction);
    let half = flight.width_m * span.scale / 2.0;
    let (nx, nz) = (-dz * half, dx * half);
    let y = |elevation: f64, z: f64| frame.elevation_to_y(elevation, z);
    // Level with the highest ground under the tread's corners too (the ramp as drawn may lean
    // a little across).
    let (length, half_uv) = (
        (b[0] - a[0]).hypot(b[1] - a[1]),
        flight.width_m * flight.metre / 2.0,
    );
    let (su, sv) = (
        -(b[1] - a[1]) / length * half_uv,
        (b[0] - a[0]) / length * half_uv,
    );
    // By a riser at most: higher than that, the corner is on another way beside the steps.
    let ends = ha.max(hb);
    let top = [a, b]
        .iter()
        .flat_map(|p| [[p[0] + su, p[1] + sv], [p[0] - su, p[1] - sv]])
        .map(|p| ground.elevation_uv(p))
        .fold(ends, f64::max)
        .min(ends + RISER_M);
    let size = frame.size_m;
    let corner = |x: f64, z: f64, side: f64, elevation: f64| {
        let (x, z) = (
            (x + side * nx).clamp(0.0, size),
            (z + side * nz).clamp(0.0, size),
        );
        [x, y(elevation, z), z]
    };
    // The lower end, where the riser stands, and the direction up the flight.
    let (low, high, (ux, uz)) = if ha < hb {
        ((ax, az, ha), (bx, bz), (dx, dz))
    } else {
        ((bx, bz, hb), (ax, az), (-dx, -dz))
    };
    let top_face = [
        corner(ax, az, 1.0, top),
        corner(bx, bz, 1.0, top),
        corner(bx, bz, -1.0, top),
        corner(ax, az, -1.0, top),
    ];
    // The ramp under the tread meets its top at the higher end: each side is a triangle,
    // sunk a little at the lower end where the ramp's own edge may lie lower.
    let faces: [(Vec<[f64; 3]>, [f64; 3]); 4] = [
        (top_face.to_vec(), [0.0, 1.0, 0.0]),
        (
            vec![
                corner(low.0, low.1, 1.0, low.2 - SINK_M),
                corner(high.0, high.1, 1.0, top),
                corner(low.0, low.1, 1.0, top),
            ],
            [nx, 0.0, nz],
        ),
        (
            vec![
                corner(low.0, low.1, -1.0, low.2 - SINK_M),
                corner(high.0, high.1, -1.0, top),
                corner(low.0, low.1, -1.0, top),
            ],
            [-nx, 0.0, -nz],
        ),
        (
            vec![
                corner(low.0, low.1, 1.0, low.2 - SINK_M),
                corner(low.0, low.1, -1.0, low.2 - SINK_M),
                corner(low.0, low.1, -1.0, top),
                corner(low.0, low.1, 1.0, top),
            ],
            [-ux, 0.0, -uz],
        ),
    ];
    for (corners, facing) in faces {
        buffers.push_flat_polygon(&corners, facing, flight.feature);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flight_is_spaced_evenly_end_to_end() {
        // 10 m at 100 units to the metre, with a bend: 40 treads of the least going.
        let line = [[0.0, 0.0], [600.0, 0.0], [600.0, 400.0]];
        let length = polyline_length(&line);
        assert_eq!(least_treads(length, 100.0), 40);
        let points = evenly(&line, length, 40);
        assert_eq!(points.len(), 41);
        assert_eq!(points[0], [0.0, 0.0]);
        assert_eq!(points[24], [600.0, 0.0]);
        assert!((points[40][1] - 400.0).abs() < 1e-9);
    }

    /// Ground rising 0.5 m per metre eastwards (a thousandth of a unit to the metre).
    struct Slope;
    impl Elevation for Slope {
        fn elevation_uv(&self, p: [f64; 2]) -> f64 {
            p[0] * 500.0
        }
    }

    #[test]
    fn a_flight_rises_in_risers_of_about_nineteen_centimetres() {
        let tile = crate::tile::TileId { z: 14, x: 0, y: 0 };
        let frame = tile.frame();
        // 3.4 m up 6.8 m of ramp: eighteen steps, each a top, two sides and a riser.
        let line = vec![[0.1, 0.5], [0.1068, 0.5]];
        let stairs = Stairs {
            feature: 1,
            line,
            width_m: 2.0,
            metre: 0.001,
        };
        let buffers = build(std::slice::from_ref(&stairs), &frame, &Slope);
        assert_eq!(buffers.indices.len() / 3, 18 * (2 + 1 + 1 + 2));
    }
}
