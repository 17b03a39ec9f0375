//! Extruded buildings: walls from below the lowest ground under the footprint up to the eaves,
//! and the roof: flat, or hipped and gabled roofs on the straight skeleton ([`super::roofs`]).
//!
//! The base follows thesis §4.1 in its simplest form: the lowest terrain point under the whole
//! footprint (vertices, points along the walls, raster samples inside), computed in global
//! coordinates so that a building cut by a tile edge has the same base and top in both tiles.
//! Walls start [`WALL_SKIRT_M`] below that, so no wall ends above the ground on a slope. An
//! untagged height is raised where needed so the roof clears the highest ground under it.

use spade::{Point2, Triangulation};

use super::roofs::{
    bend, centred_roof, skeleton_roof, spread, CentredRoof, RoofMesh, SkeletonRoof,
};
use super::tin::Cdt;
use super::MeshBuffers;
use crate::features::buildings::RoofShape;
use crate::features::BuildingShape;
use crate::geometry::{clip_ring, clip_segment, signed_area2, Point, Polygon, Ring};
use crate::terrain::TerrainModel;
use crate::tile::TileFrame;

/// How far walls reach below the lowest ground point, metres: hides the difference between the
/// sampled minimum and the triangulated ground between its vertices.
pub const WALL_SKIRT_M: f64 = 0.5;

/// Least height of a roof above the highest ground under a building whose height is a default.
const MIN_CLEARANCE_M: f64 = 2.5;

/// Footprints with more vertices than this get a flat roof: the skeleton's cost grows with the
/// cube of the count.
const MAX_ROOF_VERTICES: usize = 400;

/// The largest share of a building's height its roof may take.
const MAX_ROOF_SHARE: f64 = 0.6;

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
    if !building.drawn || !footprint.bounds().intersects(&rect) {
        return;
    }
    // The parts of one building share the base of their outline.
    let base = building.base.as_ref().unwrap_or(footprint);
    let (low, high) = ground_range(base, terrain, sample_step_uv);
    let mut top = low + building.height_m;
    if !building.height_tagged {
        top = top.max(high + MIN_CLEARANCE_M);
    }
    let floating = building.min_height_m > 0.0;
    let bottom = if floating {
        low + building.min_height_m
    } else {
        low - WALL_SKIRT_M
    };
    let local = |p: Point| frame.uv_to_local(p[0], p[1]);
    walls.paint(building.appearance.walls);
    roofs.paint(building.appearance.roof);
    if floating {
        // A part that floats is closed underneath.
        let floor = flat_cap(footprint, frame, bottom);
        walls.push_flat_triangles(&floor, [0.0, -1.0, 0.0], building.feature);
    }

    // A pitched roof takes its height from the top; the walls stop at its eaves, on the rings
    // the roof stands on, so the two meet edge for edge.
    let pitched = pitched_roof(building, frame.size_m);
    let (eaves, wall_rings): (f64, Vec<Ring>) = match &pitched {
        Some(roof) => (
            top - roof.mesh.height,
            roof.mesh
                .rings
                .iter()
                .map(|r| r.iter().map(|&p| roof.to_uv(p)).collect())
                .collect(),
        ),
        None => (top, footprint.rings().cloned().collect()),
    };

    // Walls: every footprint edge, clipped to the tile, facing away from the building.
    for (ring_index, ring) in wall_rings.iter().enumerate() {
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
                frame.elevation_to_y(eaves, az),
            );
            let (yb0, yb1) = (
                frame.elevation_to_y(bottom, bz),
                frame.elevation_to_y(eaves, bz),
            );
            let corners = [[ax, ya0, az], [bx, yb0, bz], [bx, yb1, bz], [ax, ya1, az]];
            walls.push_flat_polygon(&corners, facing, building.feature);
        }
    }

    if let Some(roof) = &pitched {
        // Each roof triangle clipped to the tile, heights carried along its plane.
        let place = |triangle: &[[f64; 3]; 3]| -> Vec<[f64; 3]> {
            let plan = triangle.map(|c| roof.to_uv([c[0], c[1]]));
            clip_ring(&plan, &rect)
                .iter()
                .map(|&p| {
                    let h = interpolate(&plan, triangle.map(|c| c[2]), p);
                    let (x, z) = local(p);
                    [x, frame.elevation_to_y(eaves + h, z), z]
                })
                .collect()
        };
        for triangle in &roof.mesh.slopes {
            roofs.push_flat_polygon(&place(triangle), [0.0, 1.0, 0.0], building.feature);
        }
        for triangle in &roof.mesh.gables {
            let corners = place_gable(triangle, &|p| roof.to_uv(p), &rect)
                .into_iter()
                .map(|(p, h)| {
                    let (x, z) = local(p);
                    [x, frame.elevation_to_y(eaves + h, z), z]
                })
                .collect::<Vec<_>>();
            if corners.len() < 3 {
                continue;
            }
            // Outwards: away from the footprint, seen from the middle of the gable's foot.
            let normal = super::triangle_normal([corners[0], corners[1], corners[2]]);
            let facing = [normal[0], 0.0, normal[2]];
            let foot = triangle.map(|c| roof.to_uv([c[0], c[1]]));
            let middle = [
                (foot[0][0] + foot[1][0] + foot[2][0]) / 3.0,
                (foot[0][1] + foot[1][1] + foot[2][1]) / 3.0,
            ];
            let step = 0.05 / frame.size_m;
            let length = facing[0].hypot(facing[2]).max(1e-12);
            let probe = [
                middle[0] + facing[0] / length * step,
                middle[1] + facing[2] / length * step,
            ];
            let facing = if footprint.contains(probe) {
                facing.map(|c| -c)
            } else {
                facing
            };
            walls.push_flat_polygon(&corners, facing, building.feature);
        }
        return;
    }

    let roof = flat_cap(footprint, frame, top);
    roofs.push_flat_triangles(&roof, [0.0, 1.0, 0.0], building.feature);
}

/// The footprint triangulated at one elevation, each triangle clipped to the tile: a flat roof
/// or the underside of a floating part.
fn flat_cap(footprint: &Polygon, frame: &TileFrame, elevation: f64) -> Vec<[[f64; 3]; 3]> {
    let rect = crate::features::tile_rect(frame.tile);
    let mut cap = Vec::new();
    for triangle in triangulate_polygon(footprint) {
        let corners: Vec<[f64; 3]> = clip_ring(&triangle, &rect)
            .iter()
            .map(|&p| {
                let (x, z) = frame.uv_to_local(p[0], p[1]);
                [x, frame.elevation_to_y(elevation, z), z]
            })
            .collect();
        for i in 1..corners.len().saturating_sub(1) {
            cap.push([corners[0], corners[i], corners[i + 1]]);
        }
    }
    cap
}

/// A roof built on the skeleton, in metres around the footprint's first vertex.
struct PitchedRoof {
    mesh: RoofMesh,
    origin: Point,
    size_m: f64,
}

impl PitchedRoof {
    fn to_uv(&self, p: Point) -> Point {
        [
            self.origin[0] + p[0] / self.size_m,
            self.origin[1] + p[1] / self.size_m,
        ]
    }
}

/// The building's pitched roof, `None` for a flat one or when the skeleton cannot be built
/// (logged; the roof is then flat). Pyramids, domes and onions rise over the centroid of a
/// footprint without courtyards that is star-shaped around it; other footprints get a hipped
/// roof instead. The footprint is measured in metres from its first vertex, the same in every
/// tile that shows the building.
fn pitched_roof(building: &BuildingShape, size_m: f64) -> Option<PitchedRoof> {
    let centred = match building.roof.shape {
        RoofShape::Flat => return None,
        RoofShape::Pyramidal => Some(CentredRoof::Pyramid),
        RoofShape::Dome => Some(CentredRoof::Dome),
        RoofShape::Onion => Some(CentredRoof::Onion),
        RoofShape::Hipped | RoofShape::Gabled | RoofShape::Mansard | RoofShape::Gambrel => None,
    };
    let shape = match building.roof.shape {
        RoofShape::Gabled | RoofShape::Gambrel => SkeletonRoof::Gabled,
        _ => SkeletonRoof::Hipped,
    };
    let footprint = &building.footprint;
    if footprint.rings().map(Vec::len).sum::<usize>() > MAX_ROOF_VERTICES {
        tracing::debug!(
            feature = building.feature,
            "footprint too detailed for a pitched roof"
        );
        return None;
    }
    let origin = footprint.outer[0];
    let rings: Vec<Vec<Point>> = footprint
        .rings()
        .map(|r| {
            r.iter()
                .map(|p| [(p[0] - origin[0]) * size_m, (p[1] - origin[1]) * size_m])
                .collect()
        })
        .collect();
    let most = building.height_m * MAX_ROOF_SHARE;
    let height = building.roof.height_m.map(|h| h.min(most));
    if let (Some(centred), [outer]) = (centred, rings.as_slice()) {
        if let Some((inner, radius)) = spread(outer) {
            let untagged = match centred {
                CentredRoof::Pyramid => building.roof.pitch * inner,
                CentredRoof::Dome => radius,
                CentredRoof::Onion => 1.5 * radius,
            };
            let height = height.unwrap_or(untagged).min(most);
            if let Some(mesh) = centred_roof(outer, centred, height) {
                return Some(PitchedRoof {
                    mesh,
                    origin,
                    size_m,
                });
            }
        }
    }
    let built = skeleton_roof(&rings, shape, height, building.roof.pitch).and_then(|mesh| {
        if mesh.height > most {
            skeleton_roof(&rings, shape, Some(most), building.roof.pitch)
        } else {
            Ok(mesh)
        }
    });
    let bent = matches!(building.roof.shape, RoofShape::Mansard | RoofShape::Gambrel);
    match built {
        Ok(mut mesh) => {
            if bent {
                bend(&mut mesh);
            }
            Some(PitchedRoof {
                mesh,
                origin,
                size_m,
            })
        }
        Err(error) => {
            tracing::debug!(feature = building.feature, %error, "roof drawn flat");
            None
        }
    }
}

/// The part of a vertical gable triangle inside the tile, as plan points with heights: its foot
/// (the two corners at the eaves) clipped to the tile, and its top edge above the clipped foot.
fn place_gable(
    triangle: &[[f64; 3]; 3],
    to_uv: &dyn Fn(Point) -> Point,
    rect: &crate::geometry::Rect,
) -> Vec<(Point, f64)> {
    // The foot: the two corners lowest down; the apex: the other.
    let mut order = [0, 1, 2];
    order.sort_by(|&i, &j| triangle[i][2].total_cmp(&triangle[j][2]));
    let (a, b, apex) = (triangle[order[0]], triangle[order[1]], triangle[order[2]]);
    let (pa, pb) = (to_uv([a[0], a[1]]), to_uv([b[0], b[1]]));
    let Some((from, to)) = clip_segment(pa, pb, rect) else {
        return Vec::new();
    };
    let d = [pb[0] - pa[0], pb[1] - pa[1]];
    let length2 = d[0] * d[0] + d[1] * d[1];
    if length2 == 0.0 {
        return Vec::new();
    }
    let along = |p: Point| ((p[0] - pa[0]) * d[0] + (p[1] - pa[1]) * d[1]) / length2;
    let top = along(to_uv([apex[0], apex[1]])).clamp(0.0, 1.0);
    let height = |t: f64| {
        if t <= top && top > 0.0 {
            apex[2] * t / top
        } else if t > top && top < 1.0 {
            apex[2] * (1.0 - t) / (1.0 - top)
        } else {
            apex[2]
        }
    };
    let (t0, t1) = (along(from), along(to));
    let mut out = vec![(from, 0.0), (to, 0.0), (to, height(t1))];
    if (t0.min(t1)..=t0.max(t1)).contains(&top) {
        out.push(([pa[0] + d[0] * top, pa[1] + d[1] * top], apex[2]));
    }
    out.push((from, height(t0)));
    out.dedup_by(|x, y| x == y);
    while out.len() > 1 && out.first() == out.last() {
        out.pop();
    }
    out
}

/// The value at `p` of the plane through three points with values `h`.
fn interpolate(triangle: &[Point; 3], h: [f64; 3], p: Point) -> f64 {
    let [a, b, c] = *triangle;
    let det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
    if det == 0.0 {
        return h[0].max(h[1]).max(h[2]);
    }
    let s = ((p[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (p[1] - a[1])) / det;
    let t = ((b[0] - a[0]) * (p[1] - a[1]) - (p[0] - a[0]) * (b[1] - a[1])) / det;
    h[0] + s * (h[1] - h[0]) + t * (h[2] - h[0])
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
