//! Cesium quantized-mesh-1.0 (`.terrain`) writer (notes 004).
//!
//! The tile's ground triangulation is written as: the 88-byte header (ECEF centre, height range,
//! bounding sphere, horizon occlusion point), vertices as zig-zag delta-coded `u`, `v`, `height`
//! in `0..=32767`, triangles counter-clockwise in (east, north) with high-water-mark index coding,
//! the west/south/east/north edge vertex lists, and the `octvertexnormals` (id 1) and `watermask`
//! (id 2) extensions when asked for. Indices are 16-bit up to 65,536 vertices, 32-bit beyond.
//!
//! `u` and `v` are linear in Web Mercator across the tile (the layer's projection is EPSG:3857).
//! Vertices that quantize to the same `(u, v)` are welded (a vertex on the tile's edge wins, then
//! the one first along the edge, so both tiles that share an edge keep the same one), and the
//! welded points are triangulated again (Delaunay, spade, on the integer grid): at 1/32767 of a
//! tile some of the ground's thinnest triangles would collapse or flip, and dropping them would
//! orphan vertices on one side of a shared edge. The result covers the tile exactly, every
//! triangle is counter-clockwise, and every edge vertex stays. Vertices are renumbered in order of
//! first use, as high-water-mark coding requires.
//!
//! The horizon occlusion point is written in the ellipsoid-scaled frame (ECEF divided by the
//! WGS84 radii), as the spec says and CesiumJS reads it (`occludeePointInScaledSpace`): its norm
//! is about 1. The reference encoder (quantized-mesh-encoder) writes ECEF metres, which is wrong.

use std::collections::HashMap;

use crate::features::Surface;
use crate::format::Extensions;
use crate::geodesy::{ecef, enu_to_ecef, scaled};
use crate::geoid::VerticalDatum;
use crate::mesh::ground::Ground;
use crate::tile::TileFrame;

/// The largest quantized coordinate.
const MAX: f64 = 32767.0;

/// The terrain of one tile, ready to encode.
#[derive(Debug, Clone)]
pub struct TerrainTile {
    /// West, south, east, north in degrees.
    pub bounds: [f64; 4],
    /// Vertex positions as fractions of the tile: east from the west edge and north from the
    /// south edge, both in `0..=1` and linear in Web Mercator.
    pub positions: Vec<[f64; 2]>,
    /// Longitude and latitude of each vertex, degrees (for the ECEF header values).
    pub lon_lat: Vec<[f64; 2]>,
    /// Height of each vertex, metres: SRTM's, used as above the ellipsoid, or above the
    /// ellipsoid ([`TerrainTile::in_datum`]).
    pub heights: Vec<f64>,
    /// Unit normal of each vertex in (east, north, up).
    pub normals: Vec<[f64; 3]>,
    /// Triangles, counter-clockwise in (east, north).
    pub triangles: Vec<[u32; 3]>,
    /// 256 × 256 cells, row 0 north, column 0 west: true where there is water.
    pub water: Option<Vec<bool>>,
}

/// Cells of the water mask along each side.
pub const WATER_MASK_CELLS: usize = 256;

impl TerrainTile {
    /// A tile's ground as quantized-mesh takes it: positions as fractions of the tile, normals
    /// turned from the local frame (x east, y up, z south) to (east, north, up), triangles
    /// counter-clockwise in (east, north), and the water mask from `water` surfaces if asked.
    pub fn of_ground(
        ground: &Ground,
        normals: &[[f64; 3]],
        frame: &TileFrame,
        water: Option<&[&Surface]>,
    ) -> TerrainTile {
        let size = frame.size_m;
        let b = frame.tile.bounds();
        TerrainTile {
            bounds: [b.west, b.south, b.east, b.north],
            positions: ground
                .vertices
                .iter()
                .map(|&[x, z]| [x / size, 1.0 - z / size])
                .collect(),
            lon_lat: ground
                .vertices
                .iter()
                .map(|&[x, z]| {
                    let (lon, lat) = frame.to_lon_lat(x, z);
                    [lon, lat]
                })
                .collect(),
            heights: ground.elevations.clone(),
            normals: normals.iter().map(|n| [n[0], -n[2], n[1]]).collect(),
            // Counter-clockwise in (x, z) with z south is clockwise in (east, north).
            triangles: ground
                .triangles
                .iter()
                .map(|t| [t.vertices[0], t.vertices[2], t.vertices[1]])
                .collect(),
            water: water.map(|surfaces| water_mask(surfaces, frame)),
        }
    }
}

impl TerrainTile {
    /// The same tile with its heights measured from `datum` (each vertex offset by the datum
    /// at its own place, so neighbours' shared edge vertices move alike).
    pub fn in_datum(mut self, datum: VerticalDatum) -> TerrainTile {
        if datum != VerticalDatum::Srtm {
            for (height, [lon, lat]) in self.heights.iter_mut().zip(&self.lon_lat) {
                *height += datum.offset(*lon, *lat);
            }
        }
        self
    }
}

/// [`WATER_MASK_CELLS`]² cells, row 0 north: true where a cell's centre is in water.
fn water_mask(waters: &[&Surface], frame: &TileFrame) -> Vec<bool> {
    let n = WATER_MASK_CELLS;
    let size = frame.size_m;
    let mut cells = Vec::with_capacity(n * n);
    for row in 0..n {
        for column in 0..n {
            let x = (column as f64 + 0.5) / n as f64 * size;
            let z = (row as f64 + 0.5) / n as f64 * size;
            let (u, v) = frame.local_to_uv(x, z);
            cells.push(waters.iter().any(|s| s.contains([u, v])));
        }
    }
    cells
}

/// What the encoder wrote.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct EncodeReport {
    pub vertices: usize,
    pub triangles: usize,
    /// Triangles of the ground before quantization.
    pub input_triangles: usize,
}

/// Encodes a tile (uncompressed; the server gzips it).
pub fn encode(tile: &TerrainTile, extensions: Extensions) -> (Vec<u8>, EncodeReport) {
    let (quantized, welded) = weld(&tile.positions);
    let mut triangles = triangulate(&quantized);
    let order = renumber(&mut triangles, welded.len());
    let vertices = Vertices::new(tile, &quantized, &welded, &order);
    let n = vertices.source.len();
    let report = EncodeReport {
        vertices: n,
        triangles: triangles.len(),
        input_triangles: tile.triangles.len(),
    };

    let mut out = Vec::with_capacity(88 + n * 6 + triangles.len() * 6 + 64);
    write_header(&mut out, tile, &vertices);
    write_vertices(&mut out, &vertices);
    let wide = n > 65536;
    write_indices(&mut out, &triangles, wide);
    write_edge_lists(&mut out, &vertices, wide);
    if extensions.normals {
        write_normals(&mut out, tile, &vertices.source);
    }
    if extensions.watermask {
        write_watermask(&mut out, tile.water.as_deref());
    }
    (out, report)
}

/// Quantizes the positions and welds those that share a quantized position, returning the
/// distinct quantized points sorted by `(u, v)` and, for each, the index of the vertex that won:
/// the one on the tile's edge, then the one with the smallest (u, v).
fn weld(positions: &[[f64; 2]]) -> (Vec<(u16, u16)>, Vec<usize>) {
    let on_edge = |p: [f64; 2]| p[0] == 0.0 || p[0] == 1.0 || p[1] == 0.0 || p[1] == 1.0;
    let rank = |i: usize| {
        let q = positions[i];
        (!on_edge(q), q[0].to_bits(), q[1].to_bits())
    };
    let mut winner: HashMap<(u16, u16), usize> = HashMap::new();
    for (index, &p) in positions.iter().enumerate() {
        let key = (quantize(p[0]), quantize(p[1]));
        winner
            .entry(key)
            .and_modify(|w| {
                if rank(index) < rank(*w) {
                    *w = index;
                }
            })
            .or_insert(index);
    }
    let mut points: Vec<((u16, u16), usize)> = winner.into_iter().collect();
    points.sort_unstable();
    points.into_iter().unzip()
}

/// A fraction of the tile on the `0..=MAX` grid. A coordinate strictly inside the tile stays
/// strictly inside: a vertex a few centimetres from the edge must not land on it in one tile only.
fn quantize(f: f64) -> u16 {
    if f <= 0.0 {
        0
    } else if f >= 1.0 {
        MAX as u16
    } else {
        (f * MAX).round().clamp(1.0, MAX - 1.0) as u16
    }
}

/// Renumbers the triangles' vertices in order of first use, as high-water-mark coding requires,
/// and returns the old index of each new one. Points no triangle uses are dropped.
fn renumber(triangles: &mut [[u32; 3]], point_count: usize) -> Vec<u32> {
    let mut order: Vec<u32> = Vec::new();
    let mut new_index: Vec<u32> = vec![u32::MAX; point_count];
    for t in triangles.iter_mut() {
        for i in t.iter_mut() {
            if new_index[*i as usize] == u32::MAX {
                new_index[*i as usize] = order.len() as u32;
                order.push(*i);
            }
            *i = new_index[*i as usize];
        }
    }
    order
}

/// The vertices as written, in order of first use.
struct Vertices {
    /// The index of each in the tile's own vertices.
    source: Vec<usize>,
    /// Quantized east, `0..=MAX`.
    u: Vec<i32>,
    /// Quantized north, `0..=MAX`.
    v: Vec<i32>,
    /// Heights above the ellipsoid, metres.
    heights: Vec<f64>,
    /// Heights quantized over `min_height..=max_height` to `0..=MAX`.
    quantized_heights: Vec<i32>,
    /// The height range, both 0 for a tile without vertices.
    min_height: f64,
    max_height: f64,
}

impl Vertices {
    fn new(tile: &TerrainTile, quantized: &[(u16, u16)], welded: &[usize], order: &[u32]) -> Self {
        let n = order.len();
        let source: Vec<usize> = order.iter().map(|&o| welded[o as usize]).collect();
        let heights: Vec<f64> = source.iter().map(|&s| tile.heights[s]).collect();
        let min_height = heights.iter().copied().fold(f64::INFINITY, f64::min);
        let max_height = heights.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let (min_height, max_height) = if n == 0 {
            (0.0, 0.0)
        } else {
            (min_height, max_height)
        };
        let span = max_height - min_height;
        let quantized_heights: Vec<i32> = heights
            .iter()
            .map(|&h| {
                if span > 0.0 {
                    ((h - min_height) / span * MAX).round() as i32
                } else {
                    0
                }
            })
            .collect();
        let u = order
            .iter()
            .map(|&o| i32::from(quantized[o as usize].0))
            .collect();
        let v = order
            .iter()
            .map(|&o| i32::from(quantized[o as usize].1))
            .collect();
        Self {
            source,
            u,
            v,
            heights,
            quantized_heights,
            min_height,
            max_height,
        }
    }
}

/// The 88-byte header: centre, height range, bounding sphere and horizon occlusion point.
///
/// The bounding sphere and the horizon occlusion point hold both the exact vertices and the
/// points a client decodes: longitude and latitude linear in `u` and `v` across the tile's
/// bounds, heights from the quantized values over the range as written (f32).
fn write_header(out: &mut Vec<u8>, tile: &TerrainTile, vertices: &Vertices) {
    let [west, south, east, north] = tile.bounds;
    let (min_height, max_height) = (vertices.min_height, vertices.max_height);
    let (low, high) = (f64::from(min_height as f32), f64::from(max_height as f32));
    let n = vertices.source.len();
    let exact = (0..n).map(|k| {
        let [lon, lat] = tile.lon_lat[vertices.source[k]];
        ecef(lon, lat, vertices.heights[k])
    });
    let decoded = (0..n).map(|k| {
        ecef(
            west + f64::from(vertices.u[k]) / MAX * (east - west),
            south + f64::from(vertices.v[k]) / MAX * (north - south),
            low + f64::from(vertices.quantized_heights[k]) / MAX * (high - low),
        )
    });
    let ecef_points: Vec<[f64; 3]> = exact.chain(decoded).collect();
    let centre = ecef(
        (west + east) / 2.0,
        (south + north) / 2.0,
        (min_height + max_height) / 2.0,
    );
    let radius = ecef_points
        .iter()
        .map(|p| distance(*p, centre))
        .fold(0.0, f64::max);
    let occlusion = horizon_occlusion_point(&ecef_points, centre);

    for value in centre {
        out.extend_from_slice(&value.to_le_bytes());
    }
    out.extend_from_slice(&(min_height as f32).to_le_bytes());
    out.extend_from_slice(&(max_height as f32).to_le_bytes());
    for value in centre {
        out.extend_from_slice(&value.to_le_bytes());
    }
    out.extend_from_slice(&radius.to_le_bytes());
    for value in occlusion {
        out.extend_from_slice(&value.to_le_bytes());
    }
}

/// The vertex count, then `u`, `v` and height, each zig-zag delta coded.
fn write_vertices(out: &mut Vec<u8>, vertices: &Vertices) {
    out.extend_from_slice(&(vertices.source.len() as u32).to_le_bytes());
    for values in [&vertices.u, &vertices.v, &vertices.quantized_heights] {
        let mut previous = 0i32;
        for &value in values.iter() {
            let delta = value - previous;
            let zigzag = ((delta << 1) ^ (delta >> 31)) as u16;
            out.extend_from_slice(&zigzag.to_le_bytes());
            previous = value;
        }
    }
}

/// The triangle count and the high-water-mark coded indices, aligned to the index width.
fn write_indices(out: &mut Vec<u8>, triangles: &[[u32; 3]], wide: bool) {
    let align = if wide { 4 } else { 2 };
    while out.len() % align != 0 {
        out.push(0);
    }
    out.extend_from_slice(&(triangles.len() as u32).to_le_bytes());
    let mut highest = 0u32;
    for &index in triangles.iter().flatten() {
        push_index(out, highest - index, wide);
        if index == highest {
            highest += 1;
        }
    }
}

/// An index in 32 bits when the tile has more vertices than 16 bits can number, else in 16.
fn push_index(out: &mut Vec<u8>, value: u32, wide: bool) {
    if wide {
        out.extend_from_slice(&value.to_le_bytes());
    } else {
        out.extend_from_slice(&(value as u16).to_le_bytes());
    }
}

/// The west, south, east and north edge vertex lists, each sorted along its edge.
fn write_edge_lists(out: &mut Vec<u8>, vertices: &Vertices, wide: bool) {
    let (us, vs) = (&vertices.u, &vertices.v);
    let edge = |select: &dyn Fn(usize) -> Option<i32>| {
        let mut list: Vec<(i32, u32)> = (0..us.len())
            .filter_map(|k| select(k).map(|key| (key, k as u32)))
            .collect();
        list.sort_unstable();
        list.into_iter().map(|(_, k)| k).collect::<Vec<u32>>()
    };
    let max = MAX as i32;
    let lists = [
        edge(&|k| (us[k] == 0).then_some(vs[k])),
        edge(&|k| (vs[k] == 0).then_some(us[k])),
        edge(&|k| (us[k] == max).then_some(vs[k])),
        edge(&|k| (vs[k] == max).then_some(us[k])),
    ];
    for list in lists {
        out.extend_from_slice(&(list.len() as u32).to_le_bytes());
        for index in list {
            push_index(out, index, wide);
        }
    }
}

/// The `octvertexnormals` extension (id 1): each vertex's normal, in ECEF, oct-encoded.
fn write_normals(out: &mut Vec<u8>, tile: &TerrainTile, source: &[usize]) {
    out.push(1);
    out.extend_from_slice(&((2 * source.len()) as u32).to_le_bytes());
    for &s in source {
        let [lon, lat] = tile.lon_lat[s];
        let [x, y] = oct_encode(enu_to_ecef(tile.normals[s], lon, lat));
        out.push(x);
        out.push(y);
    }
}

/// The `watermask` extension (id 2): the 256 × 256 mask, or one byte when the tile is all land
/// or all water.
fn write_watermask(out: &mut Vec<u8>, water: Option<&[bool]>) {
    let mask: Vec<u8> = match water {
        Some(cells) if cells.iter().any(|&w| w) && !cells.iter().all(|&w| w) => {
            cells.iter().map(|&w| if w { 255 } else { 0 }).collect()
        }
        Some(cells) if cells.first() == Some(&true) => vec![255],
        _ => vec![0],
    };
    out.push(2);
    out.extend_from_slice(&(mask.len() as u32).to_le_bytes());
    out.extend_from_slice(&mask);
}

/// A Delaunay triangulation of distinct integer points, counter-clockwise in (u, v).
fn triangulate(points: &[(u16, u16)]) -> Vec<[u32; 3]> {
    use spade::{DelaunayTriangulation, Point2, Triangulation};
    let vertices: Vec<Point2<f64>> = points
        .iter()
        .map(|&(u, v)| Point2::new(f64::from(u), f64::from(v)))
        .collect();
    let Ok(triangulation) = DelaunayTriangulation::<Point2<f64>>::bulk_load_stable(vertices) else {
        return Vec::new();
    };
    triangulation
        .inner_faces()
        .map(|face| face.vertices().map(|v| v.fix().index() as u32))
        .collect()
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// The point that is below the horizon only when the whole tile is (Cesium's horizon culling,
/// computed in ellipsoid-scaled space along the direction of the centre), returned in that
/// ellipsoid-scaled frame, where the spec puts it.
fn horizon_occlusion_point(points: &[[f64; 3]], centre: [f64; 3]) -> [f64; 3] {
    let scale = scaled;
    let direction = {
        let c = scale(centre);
        let length = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
        c.map(|v| v / length)
    };
    let mut magnitude: f64 = 1.0;
    for &p in points {
        let q = scale(p);
        let length_squared = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
        let length = length_squared.sqrt();
        let unit = q.map(|v| v / length);
        let (length_squared, length) = (length_squared.max(1.0), length.max(1.0));
        let cos_alpha = unit[0] * direction[0] + unit[1] * direction[1] + unit[2] * direction[2];
        let cross = [
            unit[1] * direction[2] - unit[2] * direction[1],
            unit[2] * direction[0] - unit[0] * direction[2],
            unit[0] * direction[1] - unit[1] * direction[0],
        ];
        let sin_alpha = (cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]).sqrt();
        let cos_beta = 1.0 / length;
        let sin_beta = (length_squared - 1.0).sqrt() * cos_beta;
        let denominator = cos_alpha * cos_beta - sin_alpha * sin_beta;
        if denominator > 0.0 {
            magnitude = magnitude.max(1.0 / denominator);
        }
    }
    direction.map(|v| v * magnitude)
}

/// Oct encoding of a unit vector into two bytes (Cigolle et al. 2014, as Cesium decodes it).
fn oct_encode(v: [f64; 3]) -> [u8; 2] {
    let sum = v[0].abs() + v[1].abs() + v[2].abs();
    let (mut x, mut y) = (v[0] / sum, v[1] / sum);
    if v[2] < 0.0 {
        let (ox, oy) = (x, y);
        x = (1.0 - oy.abs()) * if ox >= 0.0 { 1.0 } else { -1.0 };
        y = (1.0 - ox.abs()) * if oy >= 0.0 { 1.0 } else { -1.0 };
    }
    let to_byte = |t: f64| ((t.clamp(-1.0, 1.0) * 0.5 + 0.5) * 255.0).round() as u8;
    [to_byte(x), to_byte(y)]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> TerrainTile {
        TerrainTile {
            bounds: [7.4048, 43.7394, 7.4268, 43.7552],
            positions: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]],
            lon_lat: vec![
                [7.4048, 43.7394],
                [7.4268, 43.7394],
                [7.4268, 43.7552],
                [7.4048, 43.7552],
                [7.4158, 43.7473],
            ],
            heights: vec![10.0, 20.0, 30.0, 40.0, 100.0],
            normals: vec![[0.0, 0.0, 1.0]; 5],
            triangles: vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]],
            water: None,
        }
    }

    #[test]
    fn accept_header_chooses_extensions() {
        let e = Extensions::from_accept(
            "application/vnd.quantized-mesh;extensions=octvertexnormals-watermask,*/*;q=0.01",
        );
        assert_eq!(
            e,
            Extensions {
                normals: true,
                watermask: true
            }
        );
        assert_eq!(
            Extensions::from_accept("application/vnd.quantized-mesh"),
            Extensions::default()
        );
        assert!(
            Extensions::from_accept("application/vnd.quantized-mesh;extensions=vertexnormals")
                .normals
        );
    }

    #[test]
    fn encodes_the_structure_the_spec_describes() {
        let (bytes, report) = encode(
            &square(),
            Extensions {
                normals: true,
                watermask: true,
            },
        );
        assert_eq!((report.vertices, report.triangles), (5, 4));
        let f32_at = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
        assert_eq!((f32_at(24), f32_at(28)), (10.0, 100.0));
        let count = u32::from_le_bytes(bytes[88..92].try_into().unwrap());
        assert_eq!(count, 5);
        // The u values, zig-zag delta coded: the corners and the centre.
        let u16_at = |o: usize| u16::from_le_bytes(bytes[o..o + 2].try_into().unwrap());
        let zz = |v: u16| (i32::from(v) >> 1) ^ -(i32::from(v) & 1);
        let mut u = 0;
        let mut us: Vec<i32> = (0..5)
            .map(|k| {
                u += zz(u16_at(92 + 2 * k));
                u
            })
            .collect();
        us.sort_unstable();
        assert_eq!(us, [0, 0, 16384, 32767, 32767]);
        // Extensions at the end: watermask of one byte (no water).
        assert_eq!(&bytes[bytes.len() - 6..], &[2, 1, 0, 0, 0, 0]);
    }

    #[test]
    fn horizon_occlusion_point_is_in_the_ellipsoid_scaled_frame_and_covers_every_vertex() {
        let (bytes, _) = encode(&square(), Extensions::default());
        let f64_at = |o: usize| f64::from_le_bytes(bytes[o..o + 8].try_into().unwrap());
        let point = [f64_at(64), f64_at(72), f64_at(80)];
        let norm = point.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(norm > 1.0 && norm < 1.001, "norm {norm}");
        // Every vertex, scaled, sees the point below its horizon only when it is itself hidden:
        // the point is at least as far along its direction as each vertex requires.
        let direction = point.map(|v| v / norm);
        for (k, &[lon, lat]) in square().lon_lat.iter().enumerate() {
            let p = ecef(lon, lat, square().heights[k]);
            let q = scaled(p);
            let length = q.iter().map(|v| v * v).sum::<f64>().sqrt();
            let cos_alpha = (0..3).map(|i| q[i] / length * direction[i]).sum::<f64>();
            let sin_alpha = (1.0 - cos_alpha * cos_alpha).max(0.0).sqrt();
            let cos_beta = 1.0 / length;
            let sin_beta = (length * length - 1.0).sqrt() * cos_beta;
            let needed = 1.0 / (cos_alpha * cos_beta - sin_alpha * sin_beta);
            assert!(
                norm >= needed * (1.0 - 1e-9),
                "vertex {k}: {norm} < {needed}"
            );
        }
    }

    #[test]
    fn welds_what_collapses_at_the_precision_keeping_the_first_along_the_edge() {
        let mut tile = square();
        // Two vertices on the south edge a millionth of the tile apart: one survives, the one
        // first along the edge, with its own height.
        for (u, h) in [(0.5 + 1e-6, 200.0), (0.5, 5.0)] {
            tile.positions.push([u, 0.0]);
            tile.lon_lat.push([7.4158, 43.7394]);
            tile.heights.push(h);
            tile.normals.push([0.0, 0.0, 1.0]);
        }
        let (bytes, report) = encode(&tile, Extensions::default());
        assert_eq!(report.vertices, 6);
        let f32_at = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
        assert_eq!((f32_at(24), f32_at(28)), (5.0, 100.0));
    }

    #[test]
    fn a_vertex_just_inside_stays_inside() {
        let mut tile = square();
        tile.positions.push([1e-6, 0.3]);
        tile.lon_lat.push([7.4048, 43.745]);
        tile.heights.push(20.0);
        tile.normals.push([0.0, 0.0, 1.0]);
        let (bytes, report) = encode(&tile, Extensions::default());
        assert_eq!(report.vertices, 6);
        // West edge list: only the two corners.
        let n = 6;
        let mut o = 92 + 6 * n;
        o += o % 2;
        let triangles = u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap()) as usize;
        o += 4 + triangles * 6;
        assert_eq!(u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap()), 2);
    }

    #[test]
    fn oct_encoding_of_up_and_down() {
        assert_eq!(oct_encode([0.0, 0.0, 1.0]), [128, 128]);
        let down = oct_encode([0.0, 0.0, -1.0]);
        assert!(
            down == [255, 255] || down == [0, 0] || down[0] == 255 || down[0] == 0,
            "{down:?}"
        );
    }
}
