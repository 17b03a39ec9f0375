//! The ground triangulation: a constrained Delaunay triangulation (spade) of the tile square with
//! a regular grid of terrain points, into which every ground surface's outline is stitched as
//! constraint edges (report 002: roads integrated into the terrain triangulation; thesis §2.4.1:
//! the ground partition).
//!
//! Each triangle then belongs to exactly one surface, decided at its centroid by priority
//! ([`FeatureClass::ground_priority`]); triangles under buildings are removed. Outlines are
//! clipped to the tile in global tile units with [`clip_segment`], so the points where features
//! cross a tile edge are the same in both tiles that share the edge.
//!
//! Crossing constraint edges are split with `add_constraint_and_split`, the one spade call that
//! accepts them (`add_constraint` and `bulk_load_cdt` panic on crossings).

use spade::handles::FixedVertexHandle;
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

use crate::features::{FeatureClass, Surface};
use crate::geometry::{clip_segment, Point, Rect};
use crate::tile::TileFrame;

#[derive(Debug, thiserror::Error)]
pub enum GroundError {
    #[error("the ground triangulation rejected a point: {0}")]
    Insertion(String),
}

/// A triangle of the ground and the surface it belongs to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroundTriangle {
    /// Vertex indices, counter-clockwise in the local `(x, z)` plane.
    pub vertices: [u32; 3],
    /// Index into the surfaces, `None` for the default ground.
    pub surface: Option<u32>,
}

/// The triangulated ground of one tile.
#[derive(Debug, Clone, Default)]
pub struct Ground {
    /// Local `(x, z)` positions in metres.
    pub vertices: Vec<Point>,
    pub triangles: Vec<GroundTriangle>,
    /// Triangles removed because a building stands on them.
    pub removed: usize,
}

/// Buckets of surfaces over the tile, so a centroid is tested against a few surfaces only.
struct SurfaceBuckets {
    rect: Rect,
    cells: usize,
    buckets: Vec<Vec<u32>>,
}

impl SurfaceBuckets {
    fn new(rect: Rect, cells: usize, surfaces: &[Surface]) -> SurfaceBuckets {
        let mut buckets = vec![Vec::new(); cells * cells];
        let size = [rect.max[0] - rect.min[0], rect.max[1] - rect.min[1]];
        let cell_of = |value: f64, axis: usize| {
            (((value - rect.min[axis]) / size[axis]) * cells as f64)
                .floor()
                .clamp(0.0, cells as f64 - 1.0) as usize
        };
        for (index, surface) in surfaces.iter().enumerate() {
            if !surface.bounds.intersects(&rect) {
                continue;
            }
            let (c0, c1) = (
                cell_of(surface.bounds.min[0], 0),
                cell_of(surface.bounds.max[0], 0),
            );
            let (r0, r1) = (
                cell_of(surface.bounds.min[1], 1),
                cell_of(surface.bounds.max[1], 1),
            );
            for row in r0..=r1 {
                for column in c0..=c1 {
                    buckets[row * cells + column].push(index as u32);
                }
            }
        }
        SurfaceBuckets {
            rect,
            cells,
            buckets,
        }
    }

    fn candidates(&self, p: Point) -> &[u32] {
        let size = [
            self.rect.max[0] - self.rect.min[0],
            self.rect.max[1] - self.rect.min[1],
        ];
        let cell = |axis: usize| {
            (((p[axis] - self.rect.min[axis]) / size[axis]) * self.cells as f64)
                .floor()
                .clamp(0.0, self.cells as f64 - 1.0) as usize
        };
        &self.buckets[cell(1) * self.cells + cell(0)]
    }
}

/// Side of the bucket grid used to classify triangles.
const BUCKETS_PER_SIDE: usize = 64;

/// Triangulates the ground of a tile.
///
/// `grid_cells` is the number of grid cells along a tile edge; grid points lie at
/// `size · i / grid_cells`, so the grid points on a shared edge coincide in both tiles.
pub fn triangulate(
    frame: &TileFrame,
    grid_cells: u32,
    surfaces: &[Surface],
) -> Result<Ground, GroundError> {
    let rect = crate::features::tile_rect(frame.tile);
    let size = frame.size_m;
    let cells = grid_cells.max(1);
    let mut grid = Vec::with_capacity(((cells + 1) * (cells + 1)) as usize);
    for row in 0..=cells {
        let z = size * (f64::from(row) / f64::from(cells));
        for column in 0..=cells {
            let x = size * (f64::from(column) / f64::from(cells));
            grid.push(Point2::new(x, z));
        }
    }
    let mut cdt: ConstrainedDelaunayTriangulation<Point2<f64>> =
        ConstrainedDelaunayTriangulation::bulk_load(grid)
            .map_err(|e| GroundError::Insertion(format!("{e:?}")))?;

    let to_local = |p: Point| {
        let (x, z) = frame.uv_to_local(p[0], p[1]);
        Point2::new(x, z)
    };
    let insert = |cdt: &mut ConstrainedDelaunayTriangulation<Point2<f64>>,
                  p: Point2<f64>|
     -> Result<FixedVertexHandle, GroundError> {
        cdt.insert(p)
            .map_err(|e| GroundError::Insertion(format!("{e:?} at {p:?}")))
    };
    for surface in surfaces {
        if !surface.bounds.intersects(&rect) {
            continue;
        }
        for polyline in &surface.outline {
            for pair in polyline.windows(2) {
                let Some((a, b)) = clip_segment(pair[0], pair[1], &rect) else {
                    continue;
                };
                let (a, b) = (to_local(a), to_local(b));
                let from = insert(&mut cdt, a)?;
                let to = insert(&mut cdt, b)?;
                if from != to {
                    cdt.add_constraint_and_split(from, to, |p| p);
                }
            }
        }
    }

    let buckets = SurfaceBuckets::new(rect, BUCKETS_PER_SIDE, surfaces);
    let vertices: Vec<Point> = cdt
        .vertices()
        .map(|v| [v.position().x, v.position().y])
        .collect();
    let mut triangles = Vec::with_capacity(cdt.num_inner_faces());
    let mut removed = 0;
    for face in cdt.inner_faces() {
        let [a, b, c] = face.vertices().map(|v| v.fix().index() as u32);
        let centroid = {
            let [pa, pb, pc] = [a, b, c].map(|i| vertices[i as usize]);
            let x = (pa[0] + pb[0] + pc[0]) / 3.0;
            let z = (pa[1] + pb[1] + pc[1]) / 3.0;
            let (u, v) = frame.local_to_uv(x, z);
            [u, v]
        };
        let surface = buckets
            .candidates(centroid)
            .iter()
            .copied()
            .filter(|&i| surfaces[i as usize].contains(centroid))
            .min_by_key(|&i| {
                (
                    surfaces[i as usize].class.ground_priority(),
                    surfaces[i as usize].feature,
                )
            });
        if surface.is_some_and(|i| surfaces[i as usize].class == FeatureClass::Building) {
            removed += 1;
            continue;
        }
        triangles.push(GroundTriangle {
            vertices: [a, b, c],
            surface,
        });
    }
    Ok(Ground {
        vertices,
        triangles,
        removed,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Polygon;
    use crate::tile::TileId;

    fn square_surface(class: FeatureClass, feature: u32, min: Point, max: Point) -> Surface {
        let ring = vec![min, [max[0], min[1]], max, [min[0], max[1]]];
        let mut closed = ring.clone();
        closed.push(ring[0]);
        Surface {
            class,
            feature,
            pieces: vec![Polygon {
                outer: ring,
                holes: vec![],
            }],
            outline: vec![closed],
            bounds: Rect { min, max },
        }
    }

    fn area(ground: &Ground, filter: impl Fn(&GroundTriangle) -> bool) -> f64 {
        ground
            .triangles
            .iter()
            .filter(|t| filter(t))
            .map(|t| {
                let [a, b, c] = t.vertices.map(|i| ground.vertices[i as usize]);
                ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])).abs() / 2.0
            })
            .sum()
    }

    #[test]
    fn a_building_is_cut_out_and_water_kept_exactly() {
        let tile = TileId {
            z: 14,
            x: 8529,
            y: 5973,
        };
        let frame = tile.frame();
        let (x, y) = (8529.0, 5973.0);
        let surfaces = vec![
            square_surface(
                FeatureClass::Water,
                1,
                [x + 0.1, y + 0.1],
                [x + 0.3, y + 0.3],
            ),
            // Overlaps the tile edge: only the part inside counts.
            square_surface(
                FeatureClass::Building,
                2,
                [x + 0.9, y + 0.5],
                [x + 1.1, y + 0.6],
            ),
        ];
        let ground = triangulate(&frame, 16, &surfaces).unwrap();
        let s = frame.size_m;
        let water = area(&ground, |t| t.surface == Some(0));
        assert!((water - 0.04 * s * s).abs() < 1e-6 * s * s, "water {water}");
        let total = area(&ground, |_| true);
        let expected = s * s * (1.0 - 0.1 * 0.1);
        assert!(
            (total - expected).abs() < 1e-6 * s * s,
            "total {total} vs {expected}"
        );
        assert!(ground.removed > 0);
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

        /// Random outlines (crossing, touching, collinear, reaching past the tile, repeated
        /// points): the triangulation never fails, covers the tile exactly, and its edge
        /// vertices lie on the tile edge.
        #[test]
        fn any_outlines_give_a_tiling_of_the_square(
            rings in proptest::collection::vec(
                proptest::collection::vec((-0.2f64..1.2, -0.2f64..1.2), 3..8), 1..12),
            snap in proptest::bool::ANY,
        ) {
            let tile = TileId { z: 14, x: 8529, y: 5973 };
            let frame = tile.frame();
            let surfaces: Vec<Surface> = rings
                .iter()
                .enumerate()
                .map(|(i, ring)| {
                    // Snapping to a coarse grid makes repeated and collinear points likely.
                    let q = |v: f64| if snap { (v * 8.0).round() / 8.0 } else { v };
                    let ring: Vec<Point> = ring.iter().map(|&(u, v)| [8529.0 + q(u), 5973.0 + q(v)]).collect();
                    let mut closed = ring.clone();
                    closed.push(ring[0]);
                    Surface {
                        class: if i % 2 == 0 { FeatureClass::Road } else { FeatureClass::Water },
                        feature: i as u32 + 1,
                        bounds: Rect::around(&ring),
                        pieces: vec![Polygon { outer: ring, holes: vec![] }],
                        outline: vec![closed],
                    }
                })
                .collect();
            let ground = triangulate(&frame, 4, &surfaces).unwrap();
            let s = frame.size_m;
            let total = area(&ground, |_| true);
            proptest::prop_assert!((total - s * s).abs() < 1e-6 * s * s, "area {} of {}", total, s * s);
            for v in &ground.vertices {
                proptest::prop_assert!(v[0] >= 0.0 && v[0] <= s && v[1] >= 0.0 && v[1] <= s, "{:?}", v);
            }
        }
    }

    #[test]
    fn crossing_outlines_are_split_not_fatal() {
        let tile = TileId {
            z: 14,
            x: 8529,
            y: 5973,
        };
        let (x, y) = (8529.0, 5973.0);
        let surfaces = vec![
            square_surface(
                FeatureClass::Road,
                1,
                [x + 0.2, y + 0.2],
                [x + 0.6, y + 0.6],
            ),
            square_surface(
                FeatureClass::Road,
                2,
                [x + 0.4, y + 0.1],
                [x + 0.5, y + 0.9],
            ),
        ];
        let ground = triangulate(&tile.frame(), 8, &surfaces).unwrap();
        assert!(ground.triangles.iter().any(|t| t.surface == Some(1)));
    }
}
