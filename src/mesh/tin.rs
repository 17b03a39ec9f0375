//! Greedy insertion: a triangulated irregular network that approximates a height grid to a
//! vertical error bound (Garland and Heckbert, "Fast polygonal approximation of terrains and
//! height fields", 1995; the refinement of report 002 §2).
//!
//! Starting from a triangulation the caller has seeded (corners, edge vertices, feature
//! constraints), every triangle finds the grid sample it approximates worst; a priority queue
//! holds each triangle's worst sample, and the worst of all is inserted until every sample is
//! within the bound. Errors may be weighted per sample (report 002 §2.2, D-IFATT: a sample near a
//! road counts more, so the mesh is dense where features meet the ground).
//!
//! The triangulation is spade's constrained Delaunay triangulation, so feature edges stay in it.
//! Inserting a point changes only the triangles around it (every triangle a flip creates is
//! incident to the new point), so only those are rescanned; older queue entries for a reused
//! face are recognised as stale by a per-face version number.

use std::cmp::Ordering;

use spade::handles::{FixedFaceHandle, FixedVertexHandle, InnerTag};
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

pub type Cdt = ConstrainedDelaunayTriangulation<Point2<f64>>;

/// Heights sampled on a regular grid: sample `(i, j)` lies at
/// `(width · i/(columns − 1), depth · j/(rows − 1))`, so the last column lies exactly at `width`.
#[derive(Debug, Clone)]
pub struct HeightGrid {
    /// Samples per row (x) and per column (z).
    pub columns: usize,
    pub rows: usize,
    /// Extent in x and z.
    pub width: f64,
    pub depth: f64,
    /// Row-major heights.
    pub heights: Vec<f64>,
    /// Row-major weights the error is multiplied by (1 where features do not matter).
    pub weights: Option<Vec<f32>>,
}

impl HeightGrid {
    pub fn height(&self, i: usize, j: usize) -> f64 {
        self.heights[j * self.columns + i]
    }

    fn weight(&self, index: usize) -> f64 {
        self.weights.as_ref().map_or(1.0, |w| f64::from(w[index]))
    }

    /// Spacing in x.
    pub fn dx(&self) -> f64 {
        self.width / (self.columns - 1) as f64
    }

    /// Spacing in z.
    pub fn dz(&self) -> f64 {
        self.depth / (self.rows - 1) as f64
    }

    pub fn position(&self, i: usize, j: usize) -> Point2<f64> {
        Point2::new(
            self.width * (i as f64 / (self.columns - 1) as f64),
            self.depth * (j as f64 / (self.rows - 1) as f64),
        )
    }

    /// The sample at a position, if the position is exactly a grid point.
    pub fn sample_at(&self, p: Point2<f64>) -> Option<usize> {
        let i = (p.x / self.dx()).round();
        let j = (p.y / self.dz()).round();
        if i < 0.0 || j < 0.0 || i as usize >= self.columns || j as usize >= self.rows {
            return None;
        }
        let (i, j) = (i as usize, j as usize);
        (self.position(i, j) == p).then_some(j * self.columns + i)
    }
}

/// How the refinement may grow the mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineLimits {
    /// Largest weighted vertical error allowed, in the grid's height units.
    pub max_error: f64,
    /// Samples on the grid's border are never inserted (they belong to the caller's edges).
    pub keep_border: bool,
    /// Stop after this many insertions even if the bound is not met.
    pub max_insertions: usize,
}

/// A face's worst sample.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Candidate {
    error: f64,
    sample: usize,
    /// A corner of the face, where the search for the point starts.
    corner: usize,
}

impl Candidate {
    /// Larger error first; ties go to the lower sample index, so the result is deterministic.
    fn before(&self, other: &Candidate) -> bool {
        match self.error.total_cmp(&other.error) {
            Ordering::Greater => true,
            Ordering::Less => false,
            Ordering::Equal => self.sample < other.sample,
        }
    }
}

/// A max-heap of faces by their candidate, updated in place when a face is rescanned (so the
/// heap never holds more entries than there are faces). Keys live in the heap array itself.
#[derive(Default)]
struct FaceHeap {
    heap: Vec<(Candidate, usize)>,
    /// Position of each face in `heap`, `usize::MAX` when absent.
    position: Vec<usize>,
}

impl FaceHeap {
    fn set(&mut self, face: usize, candidate: Option<Candidate>) {
        if self.position.len() <= face {
            self.position.resize(face + 1, usize::MAX);
        }
        let at = self.position[face];
        match (candidate, at != usize::MAX) {
            (Some(c), true) => {
                self.heap[at].0 = c;
                let at = self.sift_up(at);
                self.sift_down(at);
            }
            (Some(c), false) => {
                self.heap.push((c, face));
                self.position[face] = self.heap.len() - 1;
                self.sift_up(self.heap.len() - 1);
            }
            (None, true) => self.remove_at(at),
            (None, false) => {}
        }
    }

    fn peek(&self) -> Option<(usize, Candidate)> {
        self.heap.first().map(|&(c, face)| (face, c))
    }

    fn remove_at(&mut self, at: usize) {
        let last = self.heap.len() - 1;
        self.swap(at, last);
        let (_, face) = self.heap.pop().expect("non-empty heap");
        self.position[face] = usize::MAX;
        if at < self.heap.len() {
            let at = self.sift_up(at);
            self.sift_down(at);
        }
    }

    fn swap(&mut self, a: usize, b: usize) {
        self.heap.swap(a, b);
        self.position[self.heap[a].1] = a;
        self.position[self.heap[b].1] = b;
    }

    fn sift_up(&mut self, mut at: usize) -> usize {
        while at > 0 {
            let parent = (at - 1) / 2;
            if !self.heap[at].0.before(&self.heap[parent].0) {
                break;
            }
            self.swap(at, parent);
            at = parent;
        }
        at
    }

    fn sift_down(&mut self, mut at: usize) {
        let len = self.heap.len();
        loop {
            let (left, right) = (2 * at + 1, 2 * at + 2);
            let mut best = at;
            if left < len && self.heap[left].0.before(&self.heap[best].0) {
                best = left;
            }
            if right < len && self.heap[right].0.before(&self.heap[best].0) {
                best = right;
            }
            if best == at {
                return;
            }
            self.swap(at, best);
            at = best;
        }
    }
}

/// What the refinement did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RefineReport {
    pub inserted: usize,
    /// The largest weighted error left (at most the bound unless `max_insertions` stopped it).
    pub max_error: f64,
}

/// Refines `cdt` against `grid`. `vertex_height` gives the height of vertices that are not grid
/// samples (feature vertices, constraint crossings); `heights` is filled for every vertex.
pub fn refine(
    cdt: &mut Cdt,
    grid: &HeightGrid,
    limits: RefineLimits,
    heights: &mut Vec<f64>,
    vertex_height: &mut dyn FnMut(Point2<f64>) -> f64,
) -> RefineReport {
    let mut state = Refiner {
        grid,
        limits,
        heap: FaceHeap::default(),
    };
    state.complete_heights(cdt, heights, vertex_height);
    let faces: Vec<FixedFaceHandle<InnerTag>> = cdt.fixed_inner_faces().collect();
    for face in faces {
        state.scan(cdt, heights, face);
    }
    let mut report = RefineReport::default();
    while let Some((face, candidate)) = state.heap.peek() {
        if candidate.error <= limits.max_error || report.inserted >= limits.max_insertions {
            report.max_error = candidate.error;
            break;
        }
        let (i, j) = (
            candidate.sample % grid.columns,
            candidate.sample / grid.columns,
        );
        let before = cdt.num_vertices();
        // The candidate's face contains the point: start the search there, not at the last
        // inserted vertex (greedy insertion jumps across the grid).
        let hint = FixedVertexHandle::from_index(candidate.corner);
        let Ok(vertex) = cdt.insert_with_hint(grid.position(i, j), hint) else {
            state.heap.set(face, None);
            continue;
        };
        if cdt.num_vertices() == before {
            // Already a vertex (its error is then zero, so this only happens for a vertex whose
            // height differs from its sample): leave the face be rather than loop.
            state.heap.set(face, None);
            continue;
        }
        report.inserted += 1;
        state.complete_heights(cdt, heights, vertex_height);
        let around: Vec<FixedFaceHandle<InnerTag>> = cdt
            .vertex(vertex)
            .out_edges()
            .filter_map(|edge| edge.face().as_inner().map(|f| f.fix()))
            .collect();
        for face in around {
            state.scan(cdt, heights, face);
        }
    }
    report
}

struct Refiner<'a> {
    grid: &'a HeightGrid,
    limits: RefineLimits,
    heap: FaceHeap,
}

impl Refiner<'_> {
    /// Gives every vertex without a height one: its grid sample, or `vertex_height`.
    fn complete_heights(
        &self,
        cdt: &Cdt,
        heights: &mut Vec<f64>,
        vertex_height: &mut dyn FnMut(Point2<f64>) -> f64,
    ) {
        for index in heights.len()..cdt.num_vertices() {
            let p = cdt.vertex(FixedVertexHandle::from_index(index)).position();
            let h = match self.grid.sample_at(p) {
                Some(sample) => self.grid.heights[sample],
                None => vertex_height(p),
            };
            heights.push(h);
        }
    }

    /// Finds the worst sample inside a face and queues it.
    fn scan(&mut self, cdt: &Cdt, heights: &[f64], face: FixedFaceHandle<InnerTag>) {
        let vertices = cdt.face(face).vertices();
        let p = vertices.map(|v| v.position());
        let h = vertices.map(|v| heights[v.fix().index()]);
        let candidate = self.worst_sample(p, h).map(|(error, sample)| Candidate {
            error,
            sample,
            corner: vertices[0].fix().index(),
        });
        self.heap.set(face.index(), candidate);
    }

    fn worst_sample(&self, p: [Point2<f64>; 3], h: [f64; 3]) -> Option<(f64, usize)> {
        let g = self.grid;
        let (dx, dz) = (g.dx(), g.dz());
        let det = (p[1].x - p[0].x) * (p[2].y - p[0].y) - (p[2].x - p[0].x) * (p[1].y - p[0].y);
        if det.abs() < 1e-12 {
            return None;
        }
        let (lo_i, hi_i) = if self.limits.keep_border {
            (1, g.columns - 2)
        } else {
            (0, g.columns - 1)
        };
        let (lo_j, hi_j) = if self.limits.keep_border {
            (1, g.rows - 2)
        } else {
            (0, g.rows - 1)
        };
        let min_x = p.iter().map(|q| q.x).fold(f64::INFINITY, f64::min);
        let max_x = p.iter().map(|q| q.x).fold(f64::NEG_INFINITY, f64::max);
        let min_z = p.iter().map(|q| q.y).fold(f64::INFINITY, f64::min);
        let max_z = p.iter().map(|q| q.y).fold(f64::NEG_INFINITY, f64::max);
        let i0 = ((min_x / dx).ceil().max(0.0) as usize).max(lo_i);
        let i1 = ((max_x / dx).floor().max(0.0) as usize).min(hi_i);
        let j0 = ((min_z / dz).ceil().max(0.0) as usize).max(lo_j);
        let j1 = ((max_z / dz).floor().max(0.0) as usize).min(hi_j);
        if i0 > i1 || j0 > j1 {
            return None;
        }
        // Barycentric coordinates are affine in x and z: b_k = α_k + β_k·x along a row.
        let inv = 1.0 / det;
        let db1_dx = (p[2].y - p[0].y) * inv;
        let db1_dz = -(p[2].x - p[0].x) * inv;
        let db2_dx = -(p[1].y - p[0].y) * inv;
        let db2_dz = (p[1].x - p[0].x) * inv;
        const INSIDE: f64 = -1e-9;
        let mut best: Option<(f64, usize)> = None;
        for j in j0..=j1 {
            let z = j as f64 * dz - p[0].y;
            // b1, b2 and b0 = 1 − b1 − b2 at x − p0.x = 0, and their slopes in x.
            let (a1, a2) = (z * db1_dz, z * db2_dz);
            let rows = [
                (1.0 - a1 - a2, -db1_dx - db2_dx),
                (a1, db1_dx),
                (a2, db2_dx),
            ];
            let (mut lo, mut hi) = (i0 as f64 * dx - p[0].x, i1 as f64 * dx - p[0].x);
            for (alpha, beta) in rows {
                // alpha + beta·x ≥ INSIDE
                if beta > 0.0 {
                    lo = lo.max((INSIDE - alpha) / beta);
                } else if beta < 0.0 {
                    hi = hi.min((INSIDE - alpha) / beta);
                } else if alpha < INSIDE {
                    hi = f64::NEG_INFINITY;
                }
            }
            if lo > hi {
                continue;
            }
            let first = (((lo + p[0].x) / dx).ceil().max(i0 as f64)) as usize;
            let last = (((hi + p[0].x) / dx).floor().min(i1 as f64)) as usize;
            let row = j * g.columns;
            for i in first..=last {
                let x = i as f64 * dx - p[0].x;
                let b1 = a1 + x * db1_dx;
                let b2 = a2 + x * db2_dx;
                let b0 = 1.0 - b1 - b2;
                let sample = row + i;
                let approximation = b0 * h[0] + b1 * h[1] + b2 * h[2];
                let error = (approximation - g.heights[sample]).abs() * g.weight(sample);
                if best.is_none_or(|(e, s)| error > e || (error == e && sample < s)) {
                    best = Some((error, sample));
                }
            }
        }
        best
    }
}

/// A triangulation of the grid's corners only, the usual seed for a raw height grid.
pub fn corner_seed(grid: &HeightGrid) -> Cdt {
    let (w, h) = (grid.columns - 1, grid.rows - 1);
    let corners = vec![
        grid.position(0, 0),
        grid.position(w, 0),
        grid.position(w, h),
        grid.position(0, h),
    ];
    Cdt::bulk_load(corners).expect("four distinct corners")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(size: usize, f: impl Fn(f64, f64) -> f64) -> HeightGrid {
        let mut heights = Vec::with_capacity(size * size);
        for j in 0..size {
            for i in 0..size {
                heights.push(f(i as f64, j as f64));
            }
        }
        HeightGrid {
            columns: size,
            rows: size,
            width: (size - 1) as f64,
            depth: (size - 1) as f64,
            heights,
            weights: None,
        }
    }

    fn max_error(cdt: &Cdt, heights: &[f64], grid: &HeightGrid) -> f64 {
        let mut worst: f64 = 0.0;
        for face in cdt.inner_faces() {
            let v = face.vertices();
            let p = v.map(|v| v.position());
            let h = v.map(|v| heights[v.fix().index()]);
            let det = (p[1].x - p[0].x) * (p[2].y - p[0].y) - (p[2].x - p[0].x) * (p[1].y - p[0].y);
            for j in 0..grid.rows {
                for i in 0..grid.columns {
                    let (x, z) = (i as f64 - p[0].x, j as f64 - p[0].y);
                    let b1 = (x * (p[2].y - p[0].y) - z * (p[2].x - p[0].x)) / det;
                    let b2 = (z * (p[1].x - p[0].x) - x * (p[1].y - p[0].y)) / det;
                    let b0 = 1.0 - b1 - b2;
                    if b0 >= -1e-9 && b1 >= -1e-9 && b2 >= -1e-9 {
                        let e = (b0 * h[0] + b1 * h[1] + b2 * h[2] - grid.height(i, j)).abs();
                        worst = worst.max(e);
                    }
                }
            }
        }
        worst
    }

    #[test]
    fn a_plane_needs_only_its_corners() {
        let g = grid(33, |x, z| 3.0 * x - 2.0 * z + 7.0);
        let mut cdt = corner_seed(&g);
        let mut heights = Vec::new();
        let limits = RefineLimits {
            max_error: 0.01,
            keep_border: false,
            max_insertions: usize::MAX,
        };
        let report = refine(&mut cdt, &g, limits, &mut heights, &mut |_| unreachable!());
        assert_eq!(report.inserted, 0);
        assert_eq!(cdt.num_inner_faces(), 2);
    }

    #[test]
    fn every_sample_ends_within_the_bound() {
        let g = grid(65, |x, z| {
            20.0 * (x / 6.0).sin() * (z / 9.0).cos() + 0.01 * x * z
        });
        for bound in [0.5, 2.0, 5.0] {
            let mut cdt = corner_seed(&g);
            let mut heights = Vec::new();
            let limits = RefineLimits {
                max_error: bound,
                keep_border: false,
                max_insertions: usize::MAX,
            };
            let report = refine(&mut cdt, &g, limits, &mut heights, &mut |_| unreachable!());
            let measured = max_error(&cdt, &heights, &g);
            assert!(
                measured <= bound + 1e-9,
                "bound {bound}: measured {measured}"
            );
            assert!(
                report.inserted < 65 * 65 / 2,
                "bound {bound}: {} insertions",
                report.inserted
            );
        }
    }

    #[test]
    fn weights_make_the_mesh_denser_where_they_are_high() {
        let mut g = grid(65, |x, z| 10.0 * (x / 5.0).sin() + 10.0 * (z / 7.0).cos());
        let count = |g: &HeightGrid| {
            let mut cdt = corner_seed(g);
            let mut heights = Vec::new();
            let limits = RefineLimits {
                max_error: 1.0,
                keep_border: false,
                max_insertions: usize::MAX,
            };
            refine(&mut cdt, g, limits, &mut heights, &mut |_| unreachable!());
            cdt.vertices().filter(|v| v.position().x < 32.0).count()
        };
        let plain = count(&g);
        g.weights = Some(
            (0..65 * 65)
                .map(|k| if k % 65 < 32 { 4.0 } else { 1.0 })
                .collect(),
        );
        let weighted = count(&g);
        assert!(weighted > plain * 3 / 2, "{plain} → {weighted}");
    }
}
