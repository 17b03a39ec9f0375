//! The ground triangulation: an adaptive constrained Delaunay triangulation (spade) of the tile
//! with every ground surface's outline stitched in (report 002: features integrated into the
//! terrain triangulation; thesis §2.4.1: the ground partition).
//!
//! 1. The approximated terrain is sampled on a regular grid over the tile
//!    ([`MeshSettings::sample_cells`] cells a side), and each sample gets an error weight that
//!    grows near roads, railways and water (report 002 §2.2, D-IFATT).
//! 2. The tile's edges are fixed first, from global data only (seed 001 §4.1): along each side,
//!    the samples on it and the points where feature outlines cross it, simplified by 1D greedy
//!    insertion to the same error bound. The corners are always vertices. Both tiles that share
//!    a side compute exactly the same vertices, so neighbours meet without a crack.
//! 3. Feature outlines, clipped to the tile in global tile units, go in as constraint edges,
//!    split where they cross by [`crate::geometry::constrained`] (never by spade itself).
//! 4. Greedy insertion ([`super::tin`]) adds interior samples until every sample is within the
//!    bound; it never inserts on the tile's edges.
//! 5. Each triangle belongs to exactly one surface, decided at its centroid by priority
//!    ([`FeatureClass::ground_priority`]), buildings first.

use spade::{Point2, Triangulation};

use super::tin::{refine, HeightGrid, RefineLimits};
use crate::features::{FeatureClass, Surface};
use crate::geometry::cells::{Cell, CellIndex};
use crate::geometry::constrained::Cdt;
use crate::geometry::{clip_segment, distance_to_segment, grid_cell, Point, Polygon, Rect};
use crate::terrain::Elevation;
use crate::tile::{mercator_scale, v_to_lat, TileFrame};

#[derive(Debug, thiserror::Error)]
pub enum GroundError {
    #[error("the ground triangulation rejected a point: {0}")]
    Insertion(String),
}

/// How the ground is meshed.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct MeshSettings {
    /// Cells along a tile edge of the grid the terrain is sampled on (9.6 m at zoom 14 for 256).
    pub sample_cells: u32,
    /// Largest vertical error of the mesh against the samples, metres.
    pub max_error_m: f64,
    /// How much more the error counts right at a road, railway or water edge (0: not at all).
    pub feature_weight: f64,
    /// Distance from a feature at which its extra weight has faded out, metres.
    pub feature_distance_m: f64,
}

impl Default for MeshSettings {
    fn default() -> Self {
        MeshSettings {
            sample_cells: 256,
            max_error_m: 1.0,
            feature_weight: 3.0,
            feature_distance_m: 40.0,
        }
    }
}

/// A triangle of the ground and the surface it belongs to (a building's, for the ground under
/// a building: the 3D tile leaves those out, the terrain keeps them).
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
    /// Elevation of each vertex in metres (not yet scaled into the local frame).
    pub elevations: Vec<f64>,
    pub triangles: Vec<GroundTriangle>,
    /// Triangles under buildings.
    pub removed: usize,
    /// Interior samples added by greedy insertion.
    pub inserted: usize,
    /// Vertices on the tile's edges.
    pub edge_vertices: usize,
    /// Outline segments left out because they could not be inserted (degenerate geometry).
    pub dropped_constraints: usize,
}

/// The pieces of the surfaces in buckets over the tile, so a centroid is tested against the
/// few pieces near it (a road has a piece per segment) rather than whole surfaces; a piece of
/// many corners (a land cover, a coast) also has a [`CellIndex`] of its own.
struct SurfaceBuckets {
    rect: Rect,
    cells: usize,
    /// (surface, piece, piece bounds, the piece's index in `indexes` or `u32::MAX`) per bucket.
    buckets: Vec<Vec<(u32, u32, Rect, u32)>>,
    indexes: Vec<CellIndex>,
}

/// A piece with at least this many corners is tested through a [`CellIndex`].
const INDEXED_CORNERS: usize = 32;

/// How near an outline a point is in a cell the outline crosses (global tile units).
const NEAR_OUTLINE: f64 = 1e-9;

impl SurfaceBuckets {
    fn new(rect: Rect, cells: usize, surfaces: &[Surface]) -> SurfaceBuckets {
        let mut grid = SurfaceBuckets {
            rect,
            cells,
            buckets: vec![Vec::new(); cells * cells],
            indexes: Vec::new(),
        };
        for (index, surface) in surfaces.iter().enumerate() {
            if !surface.bounds.intersects(&rect) {
                continue;
            }
            for (piece_index, piece) in surface.pieces.iter().enumerate() {
                let bounds = piece.bounds();
                if !bounds.intersects(&rect) {
                    continue;
                }
                let corners: usize = piece.rings().map(Vec::len).sum();
                let indexed = if corners >= INDEXED_CORNERS {
                    let one = std::slice::from_ref(piece);
                    grid.indexes.push(CellIndex::new(one, bounds, NEAR_OUTLINE));
                    grid.indexes.len() as u32 - 1
                } else {
                    u32::MAX
                };
                let (c0, c1) = (grid.cell(bounds.min[0], 0), grid.cell(bounds.max[0], 0));
                let (r0, r1) = (grid.cell(bounds.min[1], 1), grid.cell(bounds.max[1], 1));
                for row in r0..=r1 {
                    for column in c0..=c1 {
                        grid.buckets[row * cells + column].push((
                            index as u32,
                            piece_index as u32,
                            bounds,
                            indexed,
                        ));
                    }
                }
            }
        }
        grid
    }

    /// The bucket row or column of a coordinate on `axis`.
    fn cell(&self, value: f64, axis: usize) -> usize {
        let size = self.rect.max[axis] - self.rect.min[axis];
        grid_cell(value, self.rect.min[axis], size, self.cells)
    }

    /// The surfaces with a piece that contains `p`.
    fn containing<'a>(
        &'a self,
        p: Point,
        surfaces: &'a [Surface],
    ) -> impl Iterator<Item = u32> + 'a {
        self.buckets[self.cell(p[1], 1) * self.cells + self.cell(p[0], 0)]
            .iter()
            .filter(move |&&(surface, piece, bounds, indexed)| {
                let contains = || surfaces[surface as usize].pieces[piece as usize].contains(p);
                bounds.contains(p)
                    && match self.indexes.get(indexed as usize).map(|i| i.cell(p)) {
                        None => contains(),
                        Some(None | Some(Cell::Outside)) => false,
                        Some(Some(Cell::Inside)) => true,
                        Some(Some(Cell::Crossed(..))) => contains(),
                    }
            })
            .map(|&(surface, _, _, _)| surface)
    }
}

/// Triangles below this many are classified on the calling thread.
const TRIANGLES_PER_THREAD: usize = 16_384;
/// Most threads one tile's triangles are classified on.
const MAX_CLASSIFY_THREADS: usize = 4;

/// The surface of each triangle, spread over the cores when there are many (each triangle's is
/// its own, so the result does not depend on how they are shared out).
fn classify(
    triangles: &[[u32; 3]],
    surface_of: &(dyn Fn(&[u32; 3]) -> Option<u32> + Sync),
) -> Vec<Option<u32>> {
    let threads =
        crate::parallel::threads_for(triangles.len(), TRIANGLES_PER_THREAD, MAX_CLASSIFY_THREADS);
    if threads == 1 {
        return triangles.iter().map(surface_of).collect();
    }
    crate::parallel::map_chunks(triangles, threads, &|chunk| {
        chunk.iter().map(surface_of).collect()
    })
}

/// Side of the bucket grid used to classify triangles.
const BUCKETS_PER_SIDE: usize = 64;

/// The four sides of a tile, each walked from one corner to the next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Side {
    North,
    South,
    West,
    East,
}

impl Side {
    const ALL: [Side; 4] = [Side::North, Side::South, Side::West, Side::East];

    /// The fixed coordinate: (axis, value in sample indices) — `u` is axis 0, `v` axis 1.
    fn fixed(self, n: usize) -> (usize, usize) {
        match self {
            Side::North => (1, 0),
            Side::South => (1, n),
            Side::West => (0, 0),
            Side::East => (0, n),
        }
    }

    /// The sample `(i, j)` at position `t` along the side.
    fn sample(self, t: usize, n: usize) -> (usize, usize) {
        let (axis, value) = self.fixed(n);
        if axis == 1 {
            (t, value)
        } else {
            (value, t)
        }
    }
}

/// A vertex on a tile edge: its position along the side in sample steps, where it is, and its
/// elevation.
#[derive(Debug, Clone, Copy)]
struct EdgeVertex {
    t: f64,
    local: Point2<f64>,
    elevation: f64,
}

/// Triangulates the ground of a tile.
///
/// `weighting_outlines` are the outlines (roads, railways, water) near which the error counts
/// more; they must include those just outside the tile, so both sides of an edge agree.
/// The elevations of many points (global tile units) at once, as `terrain` gives them one by
/// one; it may share them out over threads.
pub type Sampler<'a> = dyn Fn(&[Point]) -> Vec<f64> + 'a;

pub fn triangulate(
    frame: &TileFrame,
    settings: &MeshSettings,
    surfaces: &[Surface],
    weighting_outlines: &[Vec<Point>],
    terrain: &dyn Elevation,
    sample: &Sampler<'_>,
) -> Result<Ground, GroundError> {
    let stitched = (surfaces, &[][..]);
    triangulate_lines(
        frame,
        settings,
        stitched,
        weighting_outlines,
        terrain,
        sample,
    )
}

/// Triangulates the ground of a tile as [`triangulate`] does, with `lines` (global tile
/// units) stitched in as well as the surfaces' outlines: where the ground changes its slope
/// along a line rather than inside a triangle (the outer edge of a sidewalk's level band).
pub fn triangulate_lines(
    frame: &TileFrame,
    settings: &MeshSettings,
    (surfaces, lines): (&[Surface], &[Vec<Point>]),
    weighting_outlines: &[Vec<Point>],
    terrain: &dyn Elevation,
    sample: &Sampler<'_>,
) -> Result<Ground, GroundError> {
    let tile = frame.tile;
    let rect = crate::features::tile_rect(tile);
    let n = settings.sample_cells.max(2) as usize;
    let size = frame.size_m;
    let origin = [f64::from(tile.x), f64::from(tile.y)];
    let sample_uv = |i: usize, j: usize| {
        [
            origin[0] + i as f64 / n as f64,
            origin[1] + j as f64 / n as f64,
        ]
    };

    let mut segments = clipped_outlines(surfaces, &rect);
    segments.extend(clipped_lines(lines, &rect));
    let to_local = |p: Point| {
        let (x, z) = frame.uv_to_local(p[0], p[1]);
        Point2::new(x, z)
    };

    // 1. Samples and their weights; meanwhile, on a thread of its own, the outlines split
    // where they cross, ready to be inserted.
    let points: Vec<Point> = (0..=n)
        .flat_map(|j| (0..=n).map(move |i| (i, j)))
        .map(|(i, j)| sample_uv(i, j))
        .collect();
    let (split, (heights, weights)) = crate::parallel::join(
        || constraint_split(size, &segments, &to_local),
        || {
            (
                sample(&points),
                feature_weights(frame, settings, weighting_outlines, n),
            )
        },
    );
    let grid = HeightGrid {
        columns: n + 1,
        rows: n + 1,
        width: size,
        depth: size,
        heights,
        weights: Some(weights),
    };

    // 2. The edges.
    let mut edge_points: Vec<Point2<f64>> = Vec::new();
    for side in Side::ALL {
        for vertex in edge_vertices(
            side,
            &grid,
            n,
            settings.max_error_m,
            &segments,
            origin,
            terrain,
            &to_local,
        ) {
            edge_points.push(vertex.local);
        }
    }
    edge_points.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    edge_points.dedup();
    let edge_count = edge_points.len();
    let cdt = Cdt::bulk_load(edge_points).map_err(|e| GroundError::Insertion(format!("{e:?}")))?;

    // 3. Feature outlines as constraints; meanwhile, here, the settled ground at the edge's
    // vertices and the points the outlines bring, which lie off the sample grid.
    let ((cdt, dropped), mut read) = crate::parallel::join(
        || crate::geometry::constrained::insert_split(&cdt, &split),
        || {
            let seed = cdt.vertices().map(|v| v.position());
            off_grid_heights(seed.chain(split.points()), &grid, frame, sample)
        },
    );
    // Any vertex read above is found there (a point is read alike whichever points are read
    // with it).
    let missing: Vec<Point2<f64>> = cdt
        .vertices()
        .map(|v| v.position())
        .filter(|p| !read.contains_key(&(p.x.to_bits(), p.y.to_bits())))
        .collect();
    read.extend(off_grid_heights(missing.into_iter(), &grid, frame, sample));

    // 4. Greedy insertion inside.
    let limits = RefineLimits {
        max_error: settings.max_error_m,
        keep_border: true,
        max_insertions: usize::MAX,
    };
    let (tin, report) = refine(&cdt, &grid, limits, &mut |p| {
        read.get(&(p.x.to_bits(), p.y.to_bits()))
            .copied()
            .unwrap_or_else(|| {
                let (u, v) = frame.local_to_uv(p.x, p.y);
                terrain.elevation_uv([u, v])
            })
    });

    // 5. Classification.
    let buckets = SurfaceBuckets::new(rect, BUCKETS_PER_SIDE, surfaces);
    let rank = ground_ranks(surfaces);
    let vertices: Vec<Point> = tin.positions.iter().map(|p| [p.x, p.y]).collect();
    let elevations = tin.heights;
    let surface_of = |&[a, b, c]: &[u32; 3]| {
        let centroid = {
            let [pa, pb, pc] = [a, b, c].map(|i| vertices[i as usize]);
            let x = (pa[0] + pb[0] + pc[0]) / 3.0;
            let z = (pa[1] + pb[1] + pc[1]) / 3.0;
            let (u, v) = frame.local_to_uv(x, z);
            [u, v]
        };
        buckets.containing(centroid, surfaces).min_by(|&a, &b| {
            let (ka, kb) = (rank[a as usize], rank[b as usize]);
            (ka.0, ka.1)
                .cmp(&(kb.0, kb.1))
                .then(ka.2.total_cmp(&kb.2))
                .then(ka.3.cmp(&kb.3))
        })
    };
    let classes = classify(&tin.triangles, &surface_of);
    let mut triangles = Vec::with_capacity(tin.triangles.len());
    let mut removed = 0;
    for (&vertices, surface) in tin.triangles.iter().zip(classes) {
        if surface.is_some_and(|i| surfaces[i as usize].class == FeatureClass::Building) {
            removed += 1;
        }
        triangles.push(GroundTriangle { vertices, surface });
    }
    Ok(Ground {
        vertices,
        elevations,
        triangles,
        removed,
        inserted: report.inserted,
        edge_vertices: edge_count,
        dropped_constraints: dropped,
    })
}

/// The rank of each surface where surfaces overlap, the lowest winning: the class's priority,
/// where a track embedded in a road ranks as the road and before it and a road through a
/// building before the building; among land covers the smaller area (the detail: a pitch in a
/// park); then the lower feature id.
fn ground_ranks(surfaces: &[Surface]) -> Vec<(u8, bool, f64, u32)> {
    surfaces
        .iter()
        .map(|s| {
            let priority = if s.passage {
                0
            } else if s.embedded {
                FeatureClass::Road.ground_priority() + 1
            } else {
                s.class.ground_priority() + 1
            };
            let detail = match s.class {
                FeatureClass::LandCover => s.pieces.iter().map(Polygon::area).sum(),
                _ => 0.0,
            };
            (priority, !s.embedded, detail, s.feature)
        })
        .collect()
}

/// The outline segments of `surfaces` clipped to the tile's `rect`, in global tile units.
fn clipped_outlines(surfaces: &[Surface], rect: &Rect) -> Vec<(Point, Point)> {
    let outlines = surfaces
        .iter()
        .filter(|s| s.bounds.intersects(rect))
        .flat_map(|s| &s.outline);
    clipped_lines(outlines, rect)
}

/// The segments of `lines` clipped to `rect`, in global tile units.
fn clipped_lines<'a>(
    lines: impl IntoIterator<Item = &'a Vec<Point>>,
    rect: &Rect,
) -> Vec<(Point, Point)> {
    let mut segments = Vec::new();
    for polyline in lines {
        for pair in polyline.windows(2) {
            if let Some((a, b)) = clip_segment(pair[0], pair[1], rect) {
                if a != b {
                    segments.push((a, b));
                }
            }
        }
    }
    segments
}

/// The elevations of `points` off the sample grid (where outlines meet and cross, each once),
/// read all at once through `sample` (over threads), by their local position's bits: the
/// refinement looks them up rather than reading them one by one.
fn off_grid_heights(
    points: impl Iterator<Item = Point2<f64>>,
    grid: &HeightGrid,
    frame: &TileFrame,
    sample: &Sampler<'_>,
) -> rustc_hash::FxHashMap<(u64, u64), f64> {
    let mut off_grid: Vec<Point2<f64>> = points.filter(|&p| grid.sample_at(p).is_none()).collect();
    off_grid.sort_unstable_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    off_grid.dedup();
    let uv: Vec<Point> = off_grid
        .iter()
        .map(|p| {
            let (u, v) = frame.local_to_uv(p.x, p.y);
            [u, v]
        })
        .collect();
    off_grid
        .iter()
        .map(|p| (p.x.to_bits(), p.y.to_bits()))
        .zip(sample(&uv))
        .collect()
}

/// The outline segments split where they cross, ready to be inserted as constraint edges
/// ([`crate::geometry::constrained::insert_split`]). Segments along the tile's border are left
/// out: the edge vertices already lie on them.
fn constraint_split(
    size: f64,
    segments: &[(Point, Point)],
    to_local: &(dyn Fn(Point) -> Point2<f64> + Sync),
) -> crate::geometry::constrained::Split {
    let on_border = |(a, b): &(Point2<f64>, Point2<f64>)| {
        let on_line = |p: f64, q: f64| p == q && (p == 0.0 || p == size);
        on_line(a.x, b.x) || on_line(a.y, b.y)
    };
    let local: Vec<(Point2<f64>, Point2<f64>)> = segments
        .iter()
        .map(|&(a, b)| (to_local(a), to_local(b)))
        .filter(|s| s.0 != s.1 && !on_border(s))
        .collect();
    crate::geometry::constrained::Split::of(&local)
}

/// Error weights of the samples: `1 + feature_weight · (1 − d / feature_distance)` within
/// `feature_distance` of an outline, 1 elsewhere. Distances are measured in global tile units
/// and converted with the scale factor at the sample's own latitude, so a sample on a shared edge
/// gets the same weight in both tiles.
fn feature_weights(
    frame: &TileFrame,
    settings: &MeshSettings,
    outlines: &[Vec<Point>],
    n: usize,
) -> Vec<f32> {
    let mut nearest = vec![f64::INFINITY; (n + 1) * (n + 1)];
    if settings.feature_weight > 0.0 && settings.feature_distance_m > 0.0 {
        let tile = frame.tile;
        let origin = [f64::from(tile.x), f64::from(tile.y)];
        let tiles_per_axis = tile.tiles_per_axis();
        // Metres on the ground per tile unit at a latitude, once for each row of samples.
        let metres_per_uv = |v: f64| frame.size_m / mercator_scale(v_to_lat(v, tiles_per_axis));
        let row_scale: Vec<f64> = (0..=n)
            .map(|j| metres_per_uv(origin[1] + j as f64 / n as f64))
            .collect();
        let reach_uv = settings.feature_distance_m / metres_per_uv(origin[1] + 0.5) * 1.01;
        let segments: Vec<(Point, Point)> = outlines
            .iter()
            .flat_map(|polyline| polyline.windows(2).map(|pair| (pair[0], pair[1])))
            .collect();
        // Bands of rows on threads of their own: each sample's nearest distance is its own.
        let rows_per_band = (n + 1).div_ceil(weight_threads(segments.len()));
        let budget = crate::budget::Inherited::here();
        std::thread::scope(|scope| {
            for (band, slots) in nearest.chunks_mut(rows_per_band * (n + 1)).enumerate() {
                let first_row = band * rows_per_band;
                let (segments, row_scale) = (&segments, &row_scale);
                scope.spawn(move || {
                    budget.run(|| {
                        let rows = first_row..first_row + slots.len() / (n + 1);
                        for &(a, b) in segments {
                            nearest_in_rows(
                                slots,
                                rows.clone(),
                                (a, b),
                                origin,
                                n,
                                reach_uv,
                                row_scale,
                            );
                        }
                    })
                });
            }
        });
    }
    nearest
        .into_iter()
        .map(|d| {
            let fade = (1.0 - d / settings.feature_distance_m).max(0.0);
            (1.0 + settings.feature_weight * fade) as f32
        })
        .collect()
}

/// Outline segments below this many are weighed on one thread.
const WEIGHT_SEGMENTS_PER_THREAD: usize = 4_096;

fn weight_threads(segments: usize) -> usize {
    crate::parallel::threads_for(segments, WEIGHT_SEGMENTS_PER_THREAD, 4)
}

/// Lowers the nearest distance (metres) of the samples of `rows` within `reach_uv` of the
/// segment `a`–`b`; `slots` holds those rows' samples.
fn nearest_in_rows(
    slots: &mut [f64],
    rows: std::ops::Range<usize>,
    (a, b): (Point, Point),
    origin: Point,
    n: usize,
    reach_uv: f64,
    row_scale: &[f64],
) {
    let index_range = |axis: usize, lo_limit: usize, hi_limit: usize| {
        let lo = (a[axis].min(b[axis]) - reach_uv - origin[axis]) * n as f64;
        let hi = (a[axis].max(b[axis]) + reach_uv - origin[axis]) * n as f64;
        let lo = lo.ceil().max(lo_limit as f64);
        let hi = hi.floor().min(hi_limit as f64);
        (lo <= hi).then_some((lo as usize, hi as usize))
    };
    if rows.is_empty() {
        return;
    }
    let (Some((i0, i1)), Some((j0, j1))) = (
        index_range(0, 0, n),
        index_range(1, rows.start, rows.end - 1),
    ) else {
        return;
    };
    for j in j0..=j1 {
        let v = origin[1] + j as f64 / n as f64;
        let scale = row_scale[j];
        let row = &mut slots[(j - rows.start) * (n + 1)..(j - rows.start + 1) * (n + 1)];
        for (i, slot) in row.iter_mut().enumerate().take(i1 + 1).skip(i0) {
            let u = origin[0] + i as f64 / n as f64;
            let d = distance_to_segment([u, v], a, b) * scale;
            if d < *slot {
                *slot = d;
            }
        }
    }
}

/// The vertices of one side: its two corners, the points where outlines cross it, and the samples
/// that 1D greedy insertion needs to bring every sample on the side within the bound.
#[allow(clippy::too_many_arguments)]
fn edge_vertices(
    side: Side,
    grid: &HeightGrid,
    n: usize,
    max_error: f64,
    segments: &[(Point, Point)],
    origin: [f64; 2],
    terrain: &dyn Elevation,
    to_local: &dyn Fn(Point) -> Point2<f64>,
) -> Vec<EdgeVertex> {
    let (axis, fixed) = side.fixed(n);
    let along = 1 - axis;
    let fixed_uv = origin[axis] + fixed as f64 / n as f64;
    let sample = |t: usize| {
        let (i, j) = side.sample(t, n);
        EdgeVertex {
            t: t as f64,
            local: grid.position(i, j),
            elevation: grid.height(i, j),
        }
    };
    let weight = |t: usize| {
        let (i, j) = side.sample(t, n);
        grid.weights
            .as_ref()
            .map_or(1.0, |w| f64::from(w[j * grid.columns + i]))
    };
    let mut vertices = vec![sample(0), sample(n)];
    let mut crossings: Vec<Point> = segments
        .iter()
        .flat_map(|&(a, b)| [a, b])
        .filter(|p| p[axis] == fixed_uv)
        .collect();
    crossings.sort_by(|a, b| a[along].total_cmp(&b[along]));
    crossings.dedup();
    for p in crossings {
        vertices.push(EdgeVertex {
            t: (p[along] - origin[along]) * n as f64,
            local: to_local(p),
            elevation: terrain.elevation_uv(p),
        });
    }
    vertices.sort_by(|a, b| a.t.total_cmp(&b.t));
    vertices.dedup_by(|a, b| a.local == b.local);

    // 1D greedy insertion: the worst sample between two vertices, until all are within the bound.
    loop {
        let mut worst: Option<(f64, usize)> = None;
        let mut k = 0;
        for t in 1..n {
            while k + 1 < vertices.len() && vertices[k + 1].t <= t as f64 {
                k += 1;
            }
            let (a, b) = (vertices[k], vertices[(k + 1).min(vertices.len() - 1)]);
            if a.t == t as f64 || b.t == a.t {
                continue;
            }
            let s = (t as f64 - a.t) / (b.t - a.t);
            let approximation = a.elevation + s * (b.elevation - a.elevation);
            let (i, j) = side.sample(t, n);
            let error = (approximation - grid.height(i, j)).abs() * weight(t);
            if worst.is_none_or(|(e, _)| error > e) {
                worst = Some((error, t));
            }
        }
        match worst {
            Some((error, t)) if error > max_error => {
                let at = vertices.partition_point(|v| v.t < t as f64);
                vertices.insert(at, sample(t));
            }
            _ => break,
        }
    }
    vertices
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangles_classified_over_threads_keep_their_order() {
        let triangles: Vec<[u32; 3]> = (0..50_000u32).map(|k| [k, k + 1, k + 2]).collect();
        let surface_of = |t: &[u32; 3]| (t[0] % 7 != 0).then_some(t[0] % 13);
        let expected: Vec<Option<u32>> = triangles.iter().map(surface_of).collect();
        assert_eq!(classify(&triangles, &surface_of), expected);
    }
    use crate::terrain::cell::{CellId, SrtmTile};
    use crate::terrain::{Interpolation, Mosaic, TerrainModel};
    use crate::tile::TileId;
    use std::sync::Arc;

    /// The tile the tests triangulate (its corner is at `u, v = 8529, 5973`).
    const TEST_TILE: TileId = TileId {
        z: 14,
        x: 8529,
        y: 5973,
    };

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
            cover: None,
            paving: None,
            embedded: false,
            passage: false,
            centreline: Vec::new(),
            piece_lines: Vec::new(),
            junction_at: None,
            water: None,
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

    /// A hilly synthetic SRTM file around Monaco.
    fn hills() -> Mosaic {
        let size = 1201;
        let mut heights = Vec::with_capacity(size * size);
        for row in 0..size {
            for column in 0..size {
                let (r, c) = (row as f64, column as f64);
                heights.push((200.0 + 80.0 * (r / 9.0).sin() * (c / 13.0).cos()) as f32);
            }
        }
        Mosaic::new([Arc::new(SrtmTile {
            cell: CellId { lat: 43, lon: 7 },
            size,
            heights,
        })])
    }

    fn ground(surfaces: &[Surface], settings: &MeshSettings) -> Ground {
        let mosaic = hills();
        let terrain = TerrainModel::new(&mosaic, Interpolation::Bilinear, 14);
        let frame = TEST_TILE.frame();
        let outlines: Vec<Vec<Point>> = surfaces
            .iter()
            .filter(|s| s.class != FeatureClass::Building)
            .flat_map(|s| s.outline.iter().cloned())
            .collect();
        let sample = |points: &[Point]| points.iter().map(|&p| terrain.elevation_uv(p)).collect();
        triangulate(&frame, settings, surfaces, &outlines, &terrain, &sample).unwrap()
    }

    #[test]
    fn a_building_is_cut_out_and_water_kept_exactly() {
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
        let ground = ground(&surfaces, &MeshSettings::default());
        let s = TEST_TILE.size_m();
        let water = area(&ground, |t| t.surface == Some(0));
        assert!((water - 0.04 * s * s).abs() < 1e-6 * s * s, "water {water}");
        let total = area(&ground, |t| t.surface != Some(1));
        let expected = s * s * (1.0 - 0.1 * 0.1);
        let with_buildings = area(&ground, |_| true);
        assert!((with_buildings - s * s).abs() < 1e-6 * s * s);
        assert!(
            (total - expected).abs() < 1e-6 * s * s,
            "total {total} vs {expected}"
        );
        assert!(ground.removed > 0);
    }

    #[test]
    fn overlaps_go_to_the_stronger_surface() {
        let (x, y) = (8529.0, 5973.0);
        let mut tram = square_surface(
            FeatureClass::Railway,
            3,
            [x + 0.45, y + 0.1],
            [x + 0.47, y + 0.9],
        );
        tram.embedded = true;
        let rail = square_surface(
            FeatureClass::Railway,
            4,
            [x + 0.1, y + 0.65],
            [x + 0.9, y + 0.67],
        );
        let mut park = square_surface(
            FeatureClass::LandCover,
            5,
            [x + 0.6, y + 0.2],
            [x + 0.8, y + 0.4],
        );
        park.cover = Some(crate::features::landcover::Cover::Park);
        let mut pitch = square_surface(
            FeatureClass::LandCover,
            6,
            [x + 0.65, y + 0.25],
            [x + 0.7, y + 0.3],
        );
        pitch.cover = Some(crate::features::landcover::Cover::Pitch);
        let surfaces = vec![
            // A road across the tile, a tram along the tile through it, a railway crossing the
            // tram and a pond.
            square_surface(
                FeatureClass::Road,
                1,
                [x + 0.1, y + 0.4],
                [x + 0.9, y + 0.5],
            ),
            square_surface(
                FeatureClass::Water,
                2,
                [x + 0.1, y + 0.6],
                [x + 0.3, y + 0.8],
            ),
            tram,
            rail,
            park,
            pitch,
        ];
        let ground = ground(&surfaces, &MeshSettings::default());
        let s = TEST_TILE.size_m();
        let of = |index: u32| area(&ground, |t| t.surface == Some(index)) / (s * s);
        let near = |a: f64, b: f64| (a - b).abs() < 1e-6;
        // The tram keeps its whole strip, across the road too.
        assert!(near(of(2), 0.02 * 0.8), "tram {}", of(2));
        // The road loses the tram's part.
        assert!(near(of(0), 0.8 * 0.1 - 0.02 * 0.1), "road {}", of(0));
        // The railway lies over the water and gives way to the tram it crosses.
        assert!(near(of(3), 0.8 * 0.02 - 0.02 * 0.02), "railway {}", of(3));
        assert!(near(of(1), 0.2 * 0.2 - 0.2 * 0.02), "water {}", of(1));
        // The pitch inside the park keeps its own ground.
        assert!(near(of(5), 0.05 * 0.05), "pitch {}", of(5));
        assert!(near(of(4), 0.2 * 0.2 - 0.05 * 0.05), "park {}", of(4));
    }

    #[test]
    fn a_looser_bound_gives_fewer_triangles_and_features_attract_them() {
        let fine = ground(
            &[],
            &MeshSettings {
                max_error_m: 0.5,
                ..MeshSettings::default()
            },
        );
        let coarse = ground(
            &[],
            &MeshSettings {
                max_error_m: 5.0,
                ..MeshSettings::default()
            },
        );
        assert!(
            coarse.triangles.len() * 2 < fine.triangles.len(),
            "{} vs {}",
            coarse.triangles.len(),
            fine.triangles.len()
        );
        let (x, y) = (8529.0, 5973.0);
        // A long thin road across the tile.
        let road = [square_surface(
            FeatureClass::Road,
            1,
            [x + 0.0, y + 0.5],
            [x + 1.0, y + 0.502],
        )];
        let plain = ground(
            &road,
            &MeshSettings {
                feature_weight: 0.0,
                ..MeshSettings::default()
            },
        );
        let weighted = ground(&road, &MeshSettings::default());
        let near = |g: &Ground| {
            g.vertices
                .iter()
                .filter(|v| (v[1] / 2445.98 - 0.501).abs() < 0.02)
                .count()
        };
        assert!(
            near(&weighted) > near(&plain),
            "{} vs {}",
            near(&weighted),
            near(&plain)
        );
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(32))]

        /// Random outlines (crossing, touching, collinear, reaching past the tile, repeated
        /// points): the triangulation never fails, covers the tile exactly, and its vertices lie
        /// in the tile.
        #[test]
        fn any_outlines_give_a_tiling_of_the_square(
            rings in proptest::collection::vec(
                proptest::collection::vec((-0.2f64..1.2, -0.2f64..1.2), 3..8), 1..12),
            snap in proptest::bool::ANY,
        ) {
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
                        cover: None,
            paving: None,
            embedded: false,
            passage: false,
            centreline: Vec::new(),
            piece_lines: Vec::new(),
            junction_at: None,
            water: None,
                    }
                })
                .collect();
            let settings = MeshSettings { sample_cells: 32, max_error_m: 5.0, ..MeshSettings::default() };
            let ground = ground(&surfaces, &settings);
            let s = TEST_TILE.size_m();
            let total = area(&ground, |_| true);
            proptest::prop_assert!((total - s * s).abs() < 1e-6 * s * s, "area {} of {}", total, s * s);
            proptest::prop_assert_eq!(ground.elevations.len(), ground.vertices.len());
            for v in &ground.vertices {
                proptest::prop_assert!(v[0] >= 0.0 && v[0] <= s && v[1] >= 0.0 && v[1] <= s, "{:?}", v);
            }
        }
    }
}
