//! Extruded buildings: walls from below the lowest ground under the footprint up to a flat roof.
//!
//! The base follows thesis §4.1 in its simplest form: the lowest terrain point under the whole
//! footprint (vertices, points along the walls, raster samples inside), computed in global
//! coordinates so that a building cut by a tile edge has the same base and top in both tiles.
//! Walls start [`WALL_SKIRT_M`] below that, so no wall ends above the ground on a slope. An
//! untagged height is raised where needed so the roof clears the highest ground under it.

use spade::{Point2, Triangulation};

use super::tin::Cdt;
use super::MeshBuffers;
use crate::features::BuildingShape;
use crate::geometry::{clip_ring, clip_segment, signed_area2, Point, Polygon};
use crate::terrain::TerrainModel;
use crate::tile::TileFrame;

/// How far walls reach below the lowest ground point, metres: hides the difference between the
/// sampled minimum and the triangulated ground between its vertices.
pub const WALL_SKIRT_M: f64 = 0.5;

/// Least height of a roof above the highest ground under a building whose height is a default.
const MIN_CLEARANCE_M: f64 = 2.5;

/// Points along each wall at which the ground is sampled, per SRTM sample spacing.
const WALL_SAMPLES_PER_CELL: f64 = 4.0;

/// The lowest and highest ground under a footprint, metres.
pub fn ground_range(
    footprint: &Polygon,
    terrain: &TerrainModel<'_>,
    sample_step_uv: f64,
) -> (f64, f64) {
    let mut low = f64::INFINITY;
    let mut high = f64::NEG_INFINITY;
    let mut visit = |h: f64| {
        low = low.min(h);
        high = high.max(h);
    };
    for ring in footprint.rings() {
        for i in 0..ring.len() {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            let length = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
            let steps = (length / sample_step_uv * WALL_SAMPLES_PER_CELL)
                .ceil()
                .max(1.0) as usize;
            for s in 0..steps {
                let t = s as f64 / steps as f64;
                visit(terrain.elevation_uv([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]));
            }
        }
    }
    let bounds = footprint.bounds();
    for (p, h) in terrain.samples_in_uv(bounds.min, bounds.max) {
        if footprint.contains(p) {
            visit(h);
        }
    }
    (low, high)
}

/// Adds the walls and the roof of the part of a building inside the tile.
pub fn extrude(
    building: &BuildingShape,
    frame: &TileFrame,
    terrain: &TerrainModel<'_>,
    sample_step_uv: f64,
    walls: &mut MeshBuffers,
    roofs: &mut MeshBuffers,
) {
    let rect = crate::features::tile_rect(frame.tile);
    let footprint = &building.footprint;
    if !footprint.bounds().intersects(&rect) {
        return;
    }
    let (low, high) = ground_range(footprint, terrain, sample_step_uv);
    let mut top = low + building.height_m;
    if !building.height_tagged {
        top = top.max(high + MIN_CLEARANCE_M);
    }
    let bottom = low - WALL_SKIRT_M;
    let local = |p: Point| frame.uv_to_local(p[0], p[1]);

    // Walls: every footprint edge, clipped to the tile, facing away from the building.
    for (ring_index, ring) in footprint.rings().enumerate() {
        // In the (u, v) plane taken as (x, y), the inside of a counter-clockwise outer ring lies
        // left of its edges; for a hole the building lies left of a clockwise ring.
        let area = signed_area2(ring);
        let building_on_left = if ring_index == 0 {
            area > 0.0
        } else {
            area < 0.0
        };
        for i in 0..ring.len() {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            let Some((a, b)) = clip_segment(a, b, &rect) else {
                continue;
            };
            let ((ax, az), (bx, bz)) = (local(a), local(b));
            let (dx, dz) = (bx - ax, bz - az);
            // Left of (dx, dz), turning the same way as from u to v.
            let left = [-dz, 0.0, dx];
            let facing = if building_on_left {
                left.map(|c| -c)
            } else {
                left
            };
            let (ya0, ya1) = (
                frame.elevation_to_y(bottom, az),
                frame.elevation_to_y(top, az),
            );
            let (yb0, yb1) = (
                frame.elevation_to_y(bottom, bz),
                frame.elevation_to_y(top, bz),
            );
            let corners = [[ax, ya0, az], [bx, yb0, bz], [bx, yb1, bz], [ax, ya1, az]];
            walls.push_flat_polygon(&corners, facing, building.feature);
        }
    }

    // Roof: the footprint triangulated, each triangle clipped to the tile.
    let mut roof: Vec<[[f64; 3]; 3]> = Vec::new();
    for triangle in triangulate_polygon(footprint) {
        let clipped = clip_ring(&triangle, &rect);
        let corners: Vec<[f64; 3]> = clipped
            .iter()
            .map(|&p| {
                let (x, z) = local(p);
                [x, frame.elevation_to_y(top, z), z]
            })
            .collect();
        for i in 1..corners.len().saturating_sub(1) {
            roof.push([corners[0], corners[i], corners[i + 1]]);
        }
    }
    roofs.push_flat_triangles(&roof, [0.0, 1.0, 0.0], building.feature);
}

/// Triangles covering a polygon with holes (a CDT of its rings, keeping the triangles inside).
pub fn triangulate_polygon(polygon: &Polygon) -> Vec<Vec<Point>> {
    // Work relative to the first vertex: global tile units are large numbers.
    let origin = polygon.outer[0];
    let relative = |p: &Point| Point2::new(p[0] - origin[0], p[1] - origin[1]);
    let mut segments = Vec::new();
    for ring in polygon.rings() {
        if ring.iter().any(|p| !(p[0].is_finite() && p[1].is_finite())) {
            return Vec::new();
        }
        for i in 0..ring.len() {
            let (a, b) = (relative(&ring[i]), relative(&ring[(i + 1) % ring.len()]));
            if a != b {
                segments.push((a, b));
            }
        }
    }
    // A ring that crosses itself or another is split where it does, never by spade.
    let (cdt, _) = super::constraints::insert(&Cdt::new(), &segments);
    cdt.inner_faces()
        .filter_map(|face| {
            let corners = face.vertices().map(|v| {
                let p = v.position();
                [p.x + origin[0], p.y + origin[1]]
            });
            let centroid = [
                (corners[0][0] + corners[1][0] + corners[2][0]) / 3.0,
                (corners[0][1] + corners[1][1] + corners[2][1]) / 3.0,
            ];
            polygon.contains(centroid).then(|| corners.to_vec())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_l_shape_is_covered_exactly() {
        let polygon = Polygon {
            outer: vec![
                [0.0, 0.0],
                [2.0, 0.0],
                [2.0, 1.0],
                [1.0, 1.0],
                [1.0, 2.0],
                [0.0, 2.0],
            ],
            holes: vec![],
        };
        let area: f64 = triangulate_polygon(&polygon)
            .iter()
            .map(|t| signed_area2(t).abs() / 2.0)
            .sum();
        assert!((area - 3.0).abs() < 1e-12, "{area}");
    }

    #[test]
    fn a_courtyard_stays_open() {
        let polygon = Polygon {
            outer: vec![[0.0, 0.0], [3.0, 0.0], [3.0, 3.0], [0.0, 3.0]],
            holes: vec![vec![[1.0, 1.0], [2.0, 1.0], [2.0, 2.0], [1.0, 2.0]]],
        };
        let area: f64 = triangulate_polygon(&polygon)
            .iter()
            .map(|t| signed_area2(t).abs() / 2.0)
            .sum();
        assert!((area - 8.0).abs() < 1e-12, "{area}");
    }

    #[test]
    fn a_footprint_that_crosses_itself_keeps_both_lobes() {
        // A bow tie: the ring crosses itself at (1, 1); even-odd inside is both triangles.
        let polygon = Polygon {
            outer: vec![[0.0, 0.0], [2.0, 2.0], [2.0, 0.0], [0.0, 2.0]],
            holes: vec![],
        };
        let area: f64 = triangulate_polygon(&polygon)
            .iter()
            .map(|t| signed_area2(t).abs() / 2.0)
            .sum();
        assert!((area - 2.0).abs() < 1e-12, "{area}");
    }
}
