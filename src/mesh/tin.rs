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
//! The caller's seed is a spade constrained Delaunay triangulation (feature edges in it); it is
//! copied into a half-edge mesh made for this one job. Inserting a point changes only the
//! triangles around it (every triangle a flip creates is incident to the new point), so only
//! those are rescanned; the queue is indexed by face and updated in place.

use spade::{Point2, Triangulation};

use crate::geometry::constrained::Cdt;

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
    /// A grid of unit spacing (sample `(i, j)` at `(i, j)`) without weights, for raw rasters.
    pub fn unit(columns: usize, rows: usize, heights: Vec<f64>) -> HeightGrid {
        HeightGrid {
            columns,
            rows,
            width: (columns - 1) as f64,
            depth: (rows - 1) as f64,
            heights,
            weights: None,
        }
    }

    pub fn height(&self, i: usize, j: usize) -> f64 {
        self.heights[j * self.columns + i]
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
}

/// A face and its candidate as the heap stores them (16 bytes).
#[derive(Debug, Clone, Copy)]
struct Entry {
    error: f64,
    sample: u32,
    face: u32,
}

impl Entry {
    /// Larger error first; ties go to the lower sample index, so the result is deterministic.
    /// (Errors are never NaN: heights are finite.)
    fn before(&self, other: &Entry) -> bool {
        if self.error != other.error {
            self.error > other.error
        } else {
            self.sample < other.sample
        }
    }
}

/// A max-heap of faces by their candidate, updated in place when a face is rescanned (so the
/// heap never holds more entries than there are faces). Keys live in the heap array itself.
#[derive(Default)]
struct FaceHeap {
    heap: Vec<Entry>,
    /// Position of each face in `heap`, `ABSENT` when absent.
    position: Vec<u32>,
}

const ABSENT: u32 = u32::MAX;

/// Children per node of the heap: four halves its depth, and siblings share a cache line.
const ARITY: usize = 4;

impl FaceHeap {
    fn set(&mut self, face: usize, candidate: Option<Candidate>) {
        if self.position.len() <= face {
            self.position.resize(face + 1, ABSENT);
        }
        let at = self.position[face];
        match (candidate, at != ABSENT) {
            (Some(c), true) => {
                let at = at as usize;
                self.heap[at].error = c.error;
                self.heap[at].sample = c.sample as u32;
                let at = self.sift_up(at);
                self.sift_down(at);
            }
            (Some(c), false) => {
                self.heap.push(Entry {
                    error: c.error,
                    sample: c.sample as u32,
                    face: face as u32,
                });
                self.position[face] = (self.heap.len() - 1) as u32;
                self.sift_up(self.heap.len() - 1);
            }
            (None, true) => self.remove_at(at as usize),
            (None, false) => {}
        }
    }

    fn peek(&self) -> Option<(usize, Candidate)> {
        self.heap.first().map(|e| {
            (
                e.face as usize,
                Candidate {
                    error: e.error,
                    sample: e.sample as usize,
                },
            )
        })
    }

    fn remove_at(&mut self, at: usize) {
        let last = self.heap.len() - 1;
        self.swap(at, last);
        let entry = self.heap.pop().expect("non-empty heap");
        self.position[entry.face as usize] = ABSENT;
        if at < self.heap.len() {
            let at = self.sift_up(at);
            self.sift_down(at);
        }
    }

    fn swap(&mut self, a: usize, b: usize) {
        self.heap.swap(a, b);
        self.position[self.heap[a].face as usize] = a as u32;
        self.position[self.heap[b].face as usize] = b as u32;
    }

    /// Moves the entry at `at` up to its place; returns where it ended.
    fn sift_up(&mut self, mut at: usize) -> usize {
        let entry = self.heap[at];
        while at > 0 {
            let parent = (at - 1) / ARITY;
            if !entry.before(&self.heap[parent]) {
                break;
            }
            self.place(at, self.heap[parent]);
            at = parent;
        }
        self.place(at, entry);
        at
    }

    /// Moves the entry at `at` down to its place.
    fn sift_down(&mut self, mut at: usize) {
        let entry = self.heap[at];
        let len = self.heap.len();
        loop {
            let first = ARITY * at + 1;
            if first >= len {
                break;
            }
            let mut best = first;
            for child in first + 1..(first + ARITY).min(len) {
                if self.heap[child].before(&self.heap[best]) {
                    best = child;
                }
            }
            if !self.heap[best].before(&entry) {
                break;
            }
            self.place(at, self.heap[best]);
            at = best;
        }
        self.place(at, entry);
    }

    fn place(&mut self, at: usize, entry: Entry) {
        self.heap[at] = entry;
        self.position[entry.face as usize] = at as u32;
    }
}

/// What the refinement did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RefineReport {
    pub inserted: usize,
    /// True when `max_insertions` stopped it before every sample was within the bound.
    pub stopped_early: bool,
}

/// A triangulated irregular network: positions, a height per vertex, counter-clockwise
/// triangles.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Tin {
    pub positions: Vec<Point2<f64>>,
    pub heights: Vec<f64>,
    pub triangles: Vec<[u32; 3]>,
}

/// Refines the triangulation `seed` against `grid`. `vertex_height` gives the height of seed
/// vertices that are not grid samples (feature vertices, constraint crossings).
///
/// The seed is copied into a half-edge mesh made for this one job: a point is always inserted
/// into the triangle known to hold it (or on one of its edges), and Delaunay flips never cross a
/// constraint edge of the seed, so the result stays a constrained Delaunay triangulation.
pub fn refine(
    seed: &Cdt,
    grid: &HeightGrid,
    limits: RefineLimits,
    vertex_height: &mut dyn FnMut(Point2<f64>) -> f64,
) -> (Tin, RefineReport) {
    let mut mesh = Mesh::from_cdt(seed);
    let mut heights: Vec<f64> = mesh
        .points
        .iter()
        .map(|&p| match grid.sample_at(p) {
            Some(sample) => grid.heights[sample],
            None => vertex_height(p),
        })
        .collect();
    // spade's seed may hold slightly inverted slivers (rounded constraint split points); the
    // refinement must never add one.
    #[cfg(test)]
    let seed_inverted = mesh
        .check()
        .unwrap_or_else(|problem| panic!("seed: {problem}"));
    let scanner = Scanner { grid, limits };
    let mut heap = FaceHeap::default();
    for t in 0..mesh.triangle_count() {
        heap.set(t, scanner.scan(&mesh, &heights, t));
    }
    let mut report = RefineReport::default();
    let mut touched: Vec<usize> = Vec::new();
    let mut used = vec![false; grid.heights.len()];
    // Each sample can be inserted once: whatever happens, the loop ends.
    let max_insertions = limits.max_insertions.min(grid.heights.len());
    while let Some((face, candidate)) = heap.peek() {
        if used[candidate.sample] {
            // A sample on the border of two triangles is a candidate of both; the other one may
            // not have changed when the sample became a vertex. Look again, past vertices.
            heap.set(face, scanner.scan_skipping(&mesh, &heights, face, &used));
            continue;
        }
        used[candidate.sample] = true;
        if report.inserted >= max_insertions {
            report.stopped_early = true;
            break;
        }
        let (i, j) = (
            candidate.sample % grid.columns,
            candidate.sample / grid.columns,
        );
        let point = grid.position(i, j);
        touched.clear();
        if mesh.insert(face, point, &mut touched).is_none() {
            // Already a vertex: look again past it (the triangle may hold other samples).
            heap.set(face, scanner.scan_skipping(&mesh, &heights, face, &used));
            continue;
        }
        heights.push(grid.heights[candidate.sample]);
        report.inserted += 1;
        #[cfg(test)]
        match mesh.check() {
            Ok(inverted) => assert!(
                inverted <= seed_inverted,
                "inserting sample {} inverted a triangle",
                candidate.sample
            ),
            Err(problem) => panic!("after inserting sample {}: {problem}", candidate.sample),
        }
        touched.sort_unstable();
        touched.dedup();
        for &t in &touched {
            heap.set(t, scanner.scan(&mesh, &heights, t));
        }
    }
    let triangles = (0..mesh.triangle_count())
        .map(|t| [0, 1, 2].map(|k| mesh.triangles[3 * t + k]))
        .collect();
    (
        Tin {
            positions: mesh.points,
            heights,
            triangles,
        },
        report,
    )
}

/// No twin: a half-edge on the hull.
const NONE: u32 = u32::MAX;

fn next(e: usize) -> usize {
    if e % 3 == 2 {
        e - 2
    } else {
        e + 1
    }
}

fn prev(e: usize) -> usize {
    if e % 3 == 0 {
        e + 2
    } else {
        e - 1
    }
}

/// Triangles as half-edges: half-edge `e` of triangle `e / 3` runs from vertex `triangles[e]` to
/// `triangles[next(e)]`; `twins[e]` is the opposite half-edge, `constrained[e]` marks both halves
/// of a constraint edge.
struct Mesh {
    points: Vec<Point2<f64>>,
    triangles: Vec<u32>,
    twins: Vec<u32>,
    constrained: Vec<bool>,
    /// Scratch space of `legalize`, kept to avoid an allocation per insertion.
    stack: Vec<usize>,
}

/// How far (in grid steps) a row's span is widened beyond a triangle's edges.
const SPAN_SLACK: f64 = 1e-7;

/// Steps a point-location walk takes before it searches every triangle.
const MAX_WALK_STEPS: usize = 256;

fn coord(p: Point2<f64>) -> robust::Coord<f64> {
    robust::Coord { x: p.x, y: p.y }
}

impl Mesh {
    /// Copies spade's own half-edge structure (not a lookup by end vertices: rounded constraint
    /// split points can leave two distinct edges between the same pair of vertices).
    fn from_cdt(cdt: &Cdt) -> Mesh {
        let points: Vec<Point2<f64>> = cdt.vertices().map(|v| v.position()).collect();
        let mut triangles = Vec::with_capacity(cdt.num_inner_faces() * 3);
        let mut half_edge_of = vec![NONE; cdt.num_directed_edges()];
        for face in cdt.inner_faces() {
            for edge in face.adjacent_edges() {
                half_edge_of[edge.fix().index()] = triangles.len() as u32;
                triangles.push(edge.from().fix().index() as u32);
            }
        }
        let mut twins = vec![NONE; triangles.len()];
        let mut constrained = vec![false; triangles.len()];
        for edge in cdt.directed_edges() {
            let e = half_edge_of[edge.fix().index()];
            if e == NONE {
                continue;
            }
            twins[e as usize] = half_edge_of[edge.rev().fix().index()];
            constrained[e as usize] = cdt.is_constraint_edge(edge.fix().as_undirected());
        }
        Mesh {
            points,
            triangles,
            twins,
            constrained,
            stack: Vec::new(),
        }
    }

    /// Checks the half-edge structure: twins are mutual with reversed ends and constraint flags
    /// agree. Returns the number of triangles that are not counter-clockwise. For tests.
    #[cfg(test)]
    fn check(&self) -> Result<usize, String> {
        for e in 0..self.triangles.len() {
            let twin = self.twins[e];
            if twin != NONE {
                let f = twin as usize;
                if self.twins[f] as usize != e {
                    return Err(format!(
                        "twin of {e} is {f}, whose twin is {}",
                        self.twins[f]
                    ));
                }
                if self.triangles[f] != self.triangles[next(e)]
                    || self.triangles[next(f)] != self.triangles[e]
                {
                    return Err(format!(
                        "half-edges {e} and {f} do not join the same vertices"
                    ));
                }
                if self.constrained[e] != self.constrained[f] {
                    return Err(format!("constraint flags of {e} and {f} differ"));
                }
            }
        }
        Ok((0..self.triangle_count())
            .filter(|&t| {
                let [a, b, c] = [0, 1, 2].map(|k| self.triangles[3 * t + k]);
                self.orient(a, b, c) <= 0.0
            })
            .count())
    }

    /// `orient2d` of three vertices: positive when counter-clockwise.
    fn orient(&self, a: u32, b: u32, c: u32) -> f64 {
        let point = |i: u32| coord(self.points[i as usize]);
        robust::orient2d(point(a), point(b), point(c))
    }

    /// True when `d` is certainly inside the circle through the counter-clockwise `a`, `b`, `c`:
    /// the floating-point determinant exceeds its rounding error bound (Shewchuk's first stage of
    /// `incircle`). A point on the circle, or too close to it to tell, is not inside: either
    /// diagonal of such a quadrilateral is Delaunay, and the grid's four-point circles are common
    /// enough that settling them exactly costs more than the whole flip.
    fn certainly_in_circle(&self, a: u32, b: u32, c: u32, d: u32) -> bool {
        let [a, b, c, d] = [a, b, c, d].map(|i| self.points[i as usize]);
        let (adx, ady) = (a.x - d.x, a.y - d.y);
        let (bdx, bdy) = (b.x - d.x, b.y - d.y);
        let (cdx, cdy) = (c.x - d.x, c.y - d.y);
        let (bdxcdy, cdxbdy) = (bdx * cdy, cdx * bdy);
        let (cdxady, adxcdy) = (cdx * ady, adx * cdy);
        let (adxbdy, bdxady) = (adx * bdy, bdx * ady);
        let alift = adx * adx + ady * ady;
        let blift = bdx * bdx + bdy * bdy;
        let clift = cdx * cdx + cdy * cdy;
        let det = alift * (bdxcdy - cdxbdy) + blift * (cdxady - adxcdy) + clift * (adxbdy - bdxady);
        let permanent = (bdxcdy.abs() + cdxbdy.abs()) * alift
            + (cdxady.abs() + adxcdy.abs()) * blift
            + (adxbdy.abs() + bdxady.abs()) * clift;
        const EPSILON: f64 = f64::EPSILON / 2.0;
        const ERROR_BOUND: f64 = (10.0 + 96.0 * EPSILON) * EPSILON;
        det > ERROR_BOUND * permanent
    }

    fn triangle_count(&self) -> usize {
        self.triangles.len() / 3
    }

    fn corners(&self, t: usize) -> [Point2<f64>; 3] {
        let v = &self.triangles[3 * t..3 * t + 3];
        [
            self.points[v[0] as usize],
            self.points[v[1] as usize],
            self.points[v[2] as usize],
        ]
    }

    fn link(&mut self, a: usize, b: u32, constrained: bool) {
        self.twins[a] = b;
        self.constrained[a] = constrained;
        if b != NONE {
            self.twins[b as usize] = a as u32;
            self.constrained[b as usize] = constrained;
        }
    }

    fn add_triangle(&mut self, a: u32, b: u32, c: u32) -> usize {
        let t = self.triangle_count();
        self.triangles.extend_from_slice(&[a, b, c]);
        self.twins.extend_from_slice(&[NONE; 3]);
        self.constrained.extend_from_slice(&[false; 3]);
        t
    }

    fn set_triangle(&mut self, t: usize, a: u32, b: u32, c: u32) {
        self.triangles[3 * t..3 * t + 3].copy_from_slice(&[a, b, c]);
    }

    /// Inserts `p`, starting the search at triangle `t`; returns the new vertex, or `None` if `p`
    /// is already a vertex. Triangles created or changed are added to `touched`.
    fn insert(&mut self, mut t: usize, p: Point2<f64>, touched: &mut Vec<usize>) -> Option<u32> {
        // The new vertex goes in first so the predicates can use it; it is taken back out if the
        // point turns out to be a vertex already.
        let v = self.points.len() as u32;
        self.points.push(p);
        // The point is in `t` or, where the scan's tolerance let it sit on the far side of an
        // edge, a step or two away. A visibility walk can circle in a triangulation that is not
        // Delaunay (constraints), so it never steps back through the edge it came from, takes
        // turns between the edges the point lies beyond, and after a bounded number of steps
        // searches every triangle.
        let mut came_through = usize::MAX;
        let mut located = None;
        for step in 0..MAX_WALK_STEPS {
            let [a, b, c] = [0, 1, 2].map(|k| self.triangles[3 * t + k]);
            let o = [
                self.orient(a, b, v),
                self.orient(b, c, v),
                self.orient(c, a, v),
            ];
            let (mut beyond, mut count) = ([0usize; 3], 0);
            for (k, &side) in o.iter().enumerate() {
                if side < 0.0 && 3 * t + k != came_through {
                    beyond[count] = k;
                    count += 1;
                }
            }
            if count == 0 {
                if o.iter().all(|&x| x >= 0.0) {
                    located = Some((t, o));
                }
                break;
            }
            let k = beyond[step % count];
            let twin = self.twins[3 * t + k];
            if twin == NONE {
                break;
            }
            came_through = twin as usize;
            t = twin as usize / 3;
        }
        let located = located.or_else(|| {
            (0..self.triangle_count()).find_map(|t| {
                let [a, b, c] = [0, 1, 2].map(|k| self.triangles[3 * t + k]);
                let o = [
                    self.orient(a, b, v),
                    self.orient(b, c, v),
                    self.orient(c, a, v),
                ];
                o.iter().all(|&x| x >= 0.0).then_some((t, o))
            })
        });
        if let Some((t, o)) = located {
            match o.iter().filter(|&&x| x == 0.0).count() {
                0 => {
                    self.split_triangle(t, v, touched);
                    return Some(v);
                }
                1 => {
                    let k = (0..3).find(|&k| o[k] == 0.0).unwrap_or(0);
                    // Splitting the triangle across the edge as well would turn a sliver of the
                    // seed that is inverted (or flat) into two; such a point is left out.
                    let across = self.twins[3 * t + k];
                    let clean = across == NONE || {
                        let u = across as usize / 3;
                        let [a, b, c] = [0, 1, 2].map(|k| self.triangles[3 * u + k]);
                        self.orient(a, b, c) > 0.0
                    };
                    if clean {
                        self.split_edge(3 * t + k, v, touched);
                        return Some(v);
                    }
                }
                // On a vertex already.
                _ => {}
            }
        }
        self.points.pop();
        None
    }

    /// Splits triangle `t` = (a, b, c) at the new vertex `v` into (a, b, v), (b, c, v), (c, a, v).
    fn split_triangle(&mut self, t: usize, v: u32, touched: &mut Vec<usize>) {
        let [a, b, c] = [0, 1, 2].map(|k| self.triangles[3 * t + k]);
        let outer = [1, 2].map(|k| (self.twins[3 * t + k], self.constrained[3 * t + k]));
        self.set_triangle(t, a, b, v);
        let t1 = self.add_triangle(b, c, v);
        let t2 = self.add_triangle(c, a, v);
        self.link(3 * t1, outer[0].0, outer[0].1);
        self.link(3 * t2, outer[1].0, outer[1].1);
        self.link(3 * t + 1, (3 * t1 + 2) as u32, false);
        self.link(3 * t + 2, (3 * t2 + 1) as u32, false);
        self.link(3 * t1 + 1, (3 * t2 + 2) as u32, false);
        touched.extend([t, t1, t2]);
        self.legalize(&[3 * t, 3 * t1, 3 * t2], touched);
    }

    /// Splits the edge of half-edge `e` at the new vertex `v` (and the triangle across it).
    fn split_edge(&mut self, e: usize, v: u32, touched: &mut Vec<usize>) {
        let t = e / 3;
        let (a, b, c) = (
            self.triangles[e],
            self.triangles[next(e)],
            self.triangles[prev(e)],
        );
        let (en, ep) = (next(e), prev(e));
        let outer_t = [
            (self.twins[en], self.constrained[en]),
            (self.twins[ep], self.constrained[ep]),
        ];
        let (f, along) = (self.twins[e], self.constrained[e]);
        // (a, v, c) and (v, b, c).
        self.set_triangle(t, a, v, c);
        let t1 = self.add_triangle(v, b, c);
        self.link(3 * t + 2, outer_t[1].0, outer_t[1].1);
        self.link(3 * t1 + 1, outer_t[0].0, outer_t[0].1);
        self.link(3 * t + 1, (3 * t1 + 2) as u32, false);
        touched.extend([t, t1]);
        let mut legalize = [3 * t + 2, 3 * t1 + 1, NONE as usize, NONE as usize];
        if f == NONE {
            self.link(3 * t, NONE, along);
            self.link(3 * t1, NONE, along);
        } else {
            let f = f as usize;
            let u = f / 3;
            let d = self.triangles[prev(f)];
            let (fnext, fprev) = (next(f), prev(f));
            let outer_u = [
                (self.twins[fnext], self.constrained[fnext]),
                (self.twins[fprev], self.constrained[fprev]),
            ];
            // (b, v, d) and (v, a, d).
            self.set_triangle(u, b, v, d);
            let u1 = self.add_triangle(v, a, d);
            self.link(3 * u + 2, outer_u[1].0, outer_u[1].1);
            self.link(3 * u1 + 1, outer_u[0].0, outer_u[0].1);
            self.link(3 * u + 1, (3 * u1 + 2) as u32, false);
            self.link(3 * t, (3 * u1) as u32, along);
            self.link(3 * t1, (3 * u) as u32, along);
            touched.extend([u, u1]);
            legalize[2..].copy_from_slice(&[3 * u + 2, 3 * u1 + 1]);
        }
        let count = if f == NONE { 2 } else { 4 };
        self.legalize(&legalize[..count], touched);
    }

    /// Restores the Delaunay property across the half-edges `edges`, whose triangles' third
    /// vertex is the point just inserted, by flipping edges that are not constraints.
    fn legalize(&mut self, edges: &[usize], touched: &mut Vec<usize>) {
        let mut stack = std::mem::take(&mut self.stack);
        stack.clear();
        for &e in edges {
            stack.push(e);
        }
        // Lawson's flips end in a valid triangulation; next to a sliver spade left inverted they
        // might circle, so their number is bounded (a flip per half-edge is far more than the
        // few a new vertex needs).
        let mut flips_left = self.triangles.len();
        while let Some(a) = stack.pop() {
            if flips_left == 0 {
                break;
            }
            let b = self.twins[a];
            if b == NONE || self.constrained[a] {
                continue;
            }
            let b = b as usize;
            let (ar, al, bl, br) = (prev(a), next(a), prev(b), next(b));
            let p0 = self.triangles[ar];
            let pr = self.triangles[a];
            let pl = self.triangles[al];
            let p1 = self.triangles[bl];
            if !self.certainly_in_circle(pr, pl, p0, p1) {
                continue;
            }
            // Flip only to two counter-clockwise triangles: spade's seed may hold a slightly
            // inverted sliver (its constraint split points are rounded), whose circle test means
            // nothing; such an edge stays as it is.
            if self.orient(p1, pl, p0) <= 0.0 || self.orient(p0, pr, p1) <= 0.0 {
                continue;
            }
            // Flip (pr, pl) to (p0, p1): a's triangle becomes (p1, pl, p0), b's (p0, pr, p1).
            self.triangles[a] = p1;
            self.triangles[b] = p0;
            let (hbl, cbl) = (self.twins[bl], self.constrained[bl]);
            let (har, car) = (self.twins[ar], self.constrained[ar]);
            self.link(a, hbl, cbl);
            self.link(b, har, car);
            self.link(ar, bl as u32, false);
            touched.extend([a / 3, b / 3]);
            flips_left -= 1;
            stack.push(br);
            stack.push(a);
        }
        self.stack = stack;
    }
}

/// Finds each triangle's worst sample.
struct Scanner<'a> {
    grid: &'a HeightGrid,
    limits: RefineLimits,
}

impl Scanner<'_> {
    fn scan(&self, mesh: &Mesh, heights: &[f64], t: usize) -> Option<Candidate> {
        self.scan_skipping(mesh, heights, t, &[])
    }

    /// Like `scan`, passing over the samples marked in `skip` (which may be empty).
    fn scan_skipping(
        &self,
        mesh: &Mesh,
        heights: &[f64],
        t: usize,
        skip: &[bool],
    ) -> Option<Candidate> {
        let p = mesh.corners(t);
        let v = &mesh.triangles[3 * t..3 * t + 3];
        let h = [
            heights[v[0] as usize],
            heights[v[1] as usize],
            heights[v[2] as usize],
        ];
        // A triangle already within the bound is never refined: keeping it out of the queue keeps
        // the queue small.
        self.worst_sample(p, h, skip)
            .filter(|&(error, _)| error > self.limits.max_error)
            .map(|(error, sample)| Candidate { error, sample })
    }

    fn worst_sample(
        &self,
        p: [Point2<f64>; 3],
        h: [f64; 3],
        skip: &[bool],
    ) -> Option<(f64, usize)> {
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
        let (inv_dx, inv_dz) = (1.0 / dx, 1.0 / dz);
        let i0 = ceil_index(min_x * inv_dx - SPAN_SLACK).max(lo_i as i64);
        let i1 = floor_index(max_x * inv_dx + SPAN_SLACK).min(hi_i as i64);
        let j0 = ceil_index(min_z * inv_dz - SPAN_SLACK).max(lo_j as i64);
        let j1 = floor_index(max_z * inv_dz + SPAN_SLACK).min(hi_j as i64);
        if i0 > i1 || j0 > j1 {
            return None;
        }
        let (i0, i1, j0, j1) = (i0 as usize, i1 as usize, j0 as usize, j1 as usize);
        // Barycentric coordinates are affine in x and z: b_k = α_k + β_k·x along a row.
        let inv = 1.0 / det;
        let db1_dx = (p[2].y - p[0].y) * inv;
        let db1_dz = -(p[2].x - p[0].x) * inv;
        let db2_dx = -(p[1].y - p[0].y) * inv;
        let db2_dz = (p[1].x - p[0].x) * inv;
        const INSIDE: f64 = -1e-9;
        // Along a row the approximation is affine in x too: h0 + b1·(h1 − h0) + b2·(h2 − h0).
        let (dh1, dh2) = (h[1] - h[0], h[2] - h[0]);
        let slope = db1_dx * dh1 + db2_dx * dh2;
        // The slopes in x of b0, b1, b2 and their reciprocals (a row's span is where each
        // coordinate stays above INSIDE).
        let betas = [-db1_dx - db2_dx, db1_dx, db2_dx];
        let inv_betas = betas.map(|beta| if beta != 0.0 { 1.0 / beta } else { 0.0 });
        let weights = g.weights.as_deref();
        // Samples are visited in increasing order, so a strictly larger error is the only way to
        // replace the best: ties keep the lowest sample.
        let (mut best_error, mut best_sample) = (f64::NEG_INFINITY, usize::MAX);
        for j in j0..=j1 {
            let z = j as f64 * dz - p[0].y;
            // b1, b2 and b0 = 1 − b1 − b2 at x − p0.x = 0, and their slopes in x.
            let (a1, a2) = (z * db1_dz, z * db2_dz);
            let alphas = [1.0 - a1 - a2, a1, a2];
            let (mut lo, mut hi) = (i0 as f64 * dx - p[0].x, i1 as f64 * dx - p[0].x);
            for k in 0..3 {
                // alpha + beta·x ≥ INSIDE
                let (alpha, beta) = (alphas[k], betas[k]);
                if beta > 0.0 {
                    lo = lo.max((INSIDE - alpha) * inv_betas[k]);
                } else if beta < 0.0 {
                    hi = hi.min((INSIDE - alpha) * inv_betas[k]);
                } else if alpha < INSIDE {
                    hi = f64::NEG_INFINITY;
                }
            }
            if lo > hi {
                continue;
            }
            // A sample on an edge must be scanned whatever the rounding of its position: the
            // triangle across the edge may be a sliver too thin to scan at all.
            let first = ceil_index((lo + p[0].x) * inv_dx - SPAN_SLACK).max(i0 as i64);
            let last = floor_index((hi + p[0].x) * inv_dx + SPAN_SLACK).min(i1 as i64);
            if first > last {
                continue;
            }
            let (first, last) = (first as usize, last as usize);
            let row = j * g.columns;
            let base = h[0] + a1 * dh1 + a2 * dh2;
            let span = Span {
                start: row + first,
                end: row + last + 1,
                approximation: base + (first as f64 * dx - p[0].x) * slope,
                step: dx * slope,
            };
            let (error, sample) = match (weights, skip.is_empty()) {
                (None, true) => span.worst::<false, false>(&g.heights, &[], &[]),
                (None, false) => span.worst::<false, true>(&g.heights, &[], skip),
                (Some(w), true) => span.worst::<true, false>(&g.heights, w, &[]),
                (Some(w), false) => span.worst::<true, true>(&g.heights, w, skip),
            };
            if error > best_error {
                best_error = error;
                best_sample = sample;
            }
        }
        (best_sample != usize::MAX).then_some((best_error, best_sample))
    }
}

/// The samples of one row inside a triangle, and the triangle's plane along them.
struct Span {
    start: usize,
    end: usize,
    /// The plane's height at `start`, and its change from one sample to the next.
    approximation: f64,
    step: f64,
}

impl Span {
    /// The largest (weighted) error in the span and its sample, the first of equals; samples
    /// marked in `skip` are passed over. `(−∞, usize::MAX)` when there is none.
    #[inline(always)]
    fn worst<const WEIGHTED: bool, const SKIP: bool>(
        &self,
        heights: &[f64],
        weights: &[f32],
        skip: &[bool],
    ) -> (f64, usize) {
        let (mut best_error, mut best_sample) = (f64::NEG_INFINITY, usize::MAX);
        for (k, &height) in heights[self.start..self.end].iter().enumerate() {
            let sample = self.start + k;
            let approximation = self.approximation + k as f64 * self.step;
            let mut error = (approximation - height).abs();
            if WEIGHTED {
                error *= f64::from(weights[sample]);
            }
            if error > best_error && (!SKIP || !skip[sample]) {
                best_error = error;
                best_sample = sample;
            }
        }
        (best_error, best_sample)
    }
}

/// `⌈x⌉` as an index, without a call into libm (saturating far outside the grid).
fn ceil_index(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) < x {
        t + 1
    } else {
        t
    }
}

/// `⌊x⌋` as an index, without a call into libm (saturating far outside the grid).
fn floor_index(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x {
        t - 1
    } else {
        t
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
mod tests;
