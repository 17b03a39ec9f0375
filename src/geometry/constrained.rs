//! Constraint edges into a spade triangulation without spade's own splitting.
//!
//! The segments are split where they cross or touch each other here, with exact orientation
//! tests, and each crossing point is shared by both segments; spade then only adds constraints
//! that cross nothing (`try_add_constraint`). Letting spade split crossing constraints itself
//! (`add_constraint_and_split`) can, with its rounded split points, send it round in circles
//! without end. A piece spade still refuses (a rounded crossing point that leaves two pieces
//! crossing by a hair) is left out, and so is a segment on which spade fails an internal
//! assertion: the triangulation is rebuilt without it. The outcome is deterministic.

use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

use super::{grid_cell, Point, Polygon};

/// A constrained Delaunay triangulation of points in the plane.
pub type Cdt = ConstrainedDelaunayTriangulation<Point2<f64>>;

/// Most segments one triangulation may lose to degenerate geometry before the remaining ones
/// are given up (each loss costs a rebuild).
const MAX_DROPPED: usize = 32;

/// Most cells per side of the grid that finds crossing segments.
const CROSSING_CELLS: usize = 256;

/// Inserts `segments` into a copy of `seed` as constraint edges; returns it with the number of
/// segments and pieces left out.
pub fn insert(seed: &Cdt, segments: &[(Point2<f64>, Point2<f64>)]) -> (Cdt, usize) {
    insert_split(seed, &Split::of(segments))
}

/// Segments split where they cross or touch each other: what [`insert_split`] inserts. It
/// needs no triangulation, so it can be made while the triangulation's seed is.
pub struct Split {
    /// Each segment as the points it passes through in order.
    pieces: Vec<Vec<Point2<f64>>>,
}

impl Split {
    pub fn of(segments: &[(Point2<f64>, Point2<f64>)]) -> Split {
        Split {
            pieces: split_at_crossings(segments),
        }
    }

    /// Every point the pieces pass through: the vertices [`insert_split`] inserts.
    pub fn points(&self) -> impl Iterator<Item = Point2<f64>> + '_ {
        self.pieces.iter().flatten().copied()
    }
}

/// Inserts segments split already into a copy of `seed` as constraint edges (see [`insert`]).
pub fn insert_split(seed: &Cdt, split: &Split) -> (Cdt, usize) {
    let pieces = &split.pieces;
    let mut skipped: Vec<bool> = vec![false; pieces.len()];
    let mut dropped_segments = 0;
    loop {
        let mut cdt = seed.clone();
        let progress = std::cell::Cell::new(0usize);
        let refused = std::cell::Cell::new(0usize);
        let attempt = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            for (k, points) in pieces.iter().enumerate() {
                if skipped[k] {
                    continue;
                }
                progress.set(k);
                let handles: Vec<_> = points.iter().filter_map(|&p| cdt.insert(p).ok()).collect();
                for pair in handles.windows(2) {
                    let (from, to) = (pair[0], pair[1]);
                    if from != to
                        && cdt.try_add_constraint(from, to).is_empty()
                        && !cdt.exists_constraint(from, to)
                    {
                        refused.set(refused.get() + 1);
                    }
                }
            }
        }));
        match attempt {
            Ok(()) => return (cdt, dropped_segments + refused.get()),
            Err(_) => {
                let k = progress.get();
                let segment = pieces[k].first().zip(pieces[k].last());
                tracing::debug!(?segment, "constraint segment left out of the triangulation");
                skipped[k] = true;
                dropped_segments += 1;
                if dropped_segments >= MAX_DROPPED {
                    skipped.iter_mut().for_each(|s| *s = true);
                }
            }
        }
    }
}

/// Each segment as the points it passes through in order: its ends, and every point where it
/// crosses or touches another segment (one shared point per crossing).
fn split_at_crossings(segments: &[(Point2<f64>, Point2<f64>)]) -> Vec<Vec<Point2<f64>>> {
    // The grid covers the segments' bounding box.
    let (mut min, mut max) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for (a, b) in segments {
        for p in [a, b] {
            min = [min[0].min(p.x), min[1].min(p.y)];
            max = [max[0].max(p.x), max[1].max(p.y)];
        }
    }
    let size = (max[0] - min[0])
        .max(max[1] - min[1])
        .max(f64::MIN_POSITIVE);
    // About one segment per cell: a building's few segments need no grid of thousands.
    let cells = ((segments.len() as f64).sqrt().ceil() as usize).clamp(1, CROSSING_CELLS);
    let cell = |v: f64, axis: usize| grid_cell(v, min[axis], size, cells);
    let mut buckets: Vec<Vec<u32>> = vec![Vec::new(); cells * cells];
    for (k, (a, b)) in segments.iter().enumerate() {
        for row in cell(a.y.min(b.y), 1)..=cell(a.y.max(b.y), 1) {
            for column in cell(a.x.min(b.x), 0)..=cell(a.x.max(b.x), 0) {
                buckets[row * cells + column].push(k as u32);
            }
        }
    }
    // Each pair of segments sharing a cell once, the lower index first; pairs whose bounding
    // boxes miss each other can neither cross nor touch.
    let boxes_meet = |(a, b): (Point2<f64>, Point2<f64>), (c, d): (Point2<f64>, Point2<f64>)| {
        a.x.min(b.x) <= c.x.max(d.x)
            && c.x.min(d.x) <= a.x.max(b.x)
            && a.y.min(b.y) <= c.y.max(d.y)
            && c.y.min(d.y) <= a.y.max(b.y)
    };
    let mut pairs: Vec<(u32, u32)> = Vec::new();
    let mut seen_by: Vec<u32> = vec![u32::MAX; segments.len()];
    for (i, &(a, b)) in segments.iter().enumerate() {
        for row in cell(a.y.min(b.y), 1)..=cell(a.y.max(b.y), 1) {
            for column in cell(a.x.min(b.x), 0)..=cell(a.x.max(b.x), 0) {
                for &j in &buckets[row * cells + column] {
                    if j as usize > i
                        && seen_by[j as usize] != i as u32
                        && boxes_meet(segments[i], segments[j as usize])
                    {
                        seen_by[j as usize] = i as u32;
                        pairs.push((i as u32, j));
                    }
                }
            }
        }
    }

    // (position along the segment, point) of every split.
    let mut splits: Vec<Vec<(f64, Point2<f64>)>> = vec![Vec::new(); segments.len()];
    let orient = |a: Point2<f64>, b: Point2<f64>, c: Point2<f64>| {
        robust::orient2d(
            robust::Coord { x: a.x, y: a.y },
            robust::Coord { x: b.x, y: b.y },
            robust::Coord { x: c.x, y: c.y },
        )
    };
    let along = |(a, b): (Point2<f64>, Point2<f64>), p: Point2<f64>| {
        let d = (b.x - a.x, b.y - a.y);
        ((p.x - a.x) * d.0 + (p.y - a.y) * d.1) / (d.0 * d.0 + d.1 * d.1)
    };
    // True when `p` lies strictly between the ends of the segment it is collinear with.
    let inside = |s: (Point2<f64>, Point2<f64>), p: Point2<f64>| {
        let t = along(s, p);
        t > 0.0 && t < 1.0
    };
    for (i, j) in pairs {
        let (si, sj) = (segments[i as usize], segments[j as usize]);
        let (o1, o2) = (orient(si.0, si.1, sj.0), orient(si.0, si.1, sj.1));
        let (o3, o4) = (orient(sj.0, sj.1, si.0), orient(sj.0, sj.1, si.1));
        if o1 * o2 < 0.0 && o3 * o4 < 0.0 {
            // A proper crossing: one point, shared.
            let (di, dj) = (
                (si.1.x - si.0.x, si.1.y - si.0.y),
                (sj.1.x - sj.0.x, sj.1.y - sj.0.y),
            );
            let denominator = di.0 * dj.1 - di.1 * dj.0;
            // Nearly parallel segments make the division ill-conditioned: the point is kept on
            // the segment and within both segments' bounding boxes whatever the rounding.
            let t = (((sj.0.x - si.0.x) * dj.1 - (sj.0.y - si.0.y) * dj.0) / denominator)
                .clamp(0.0, 1.0);
            let within = |value: f64, axis: fn(&Point2<f64>) -> f64| {
                let (lo_i, hi_i) = (axis(&si.0).min(axis(&si.1)), axis(&si.0).max(axis(&si.1)));
                let (lo_j, hi_j) = (axis(&sj.0).min(axis(&sj.1)), axis(&sj.0).max(axis(&sj.1)));
                value.clamp(lo_i.max(lo_j), hi_i.min(hi_j).max(lo_i.max(lo_j)))
            };
            let p = Point2::new(
                within(si.0.x + t * di.0, |p| p.x),
                within(si.0.y + t * di.1, |p| p.y),
            );
            if p.x.is_finite() && p.y.is_finite() {
                splits[i as usize].push((along(si, p), p));
                splits[j as usize].push((along(sj, p), p));
            }
            continue;
        }
        // Touching: an end of one lying on the other (also where they overlap).
        for (end, o, on, k) in [
            (sj.0, o1, si, i),
            (sj.1, o2, si, i),
            (si.0, o3, sj, j),
            (si.1, o4, sj, j),
        ] {
            if o == 0.0 && inside(on, end) {
                splits[k as usize].push((along(on, end), end));
            }
        }
    }
    segments
        .iter()
        .zip(splits)
        .map(|(&(a, b), mut points)| {
            points.sort_by(|x, y| {
                x.0.total_cmp(&y.0)
                    .then(x.1.x.total_cmp(&y.1.x))
                    .then(x.1.y.total_cmp(&y.1.y))
            });
            let mut path = Vec::with_capacity(points.len() + 2);
            path.push(a);
            path.extend(points.into_iter().map(|(_, p)| p));
            path.push(b);
            path.dedup();
            path
        })
        .collect()
}

/// Triangles covering a polygon with holes (a CDT of its rings, keeping the triangles inside),
/// their corners the very points of the rings (and crossing points where rings cross).
pub fn triangulate_polygon(polygon: &Polygon) -> Vec<Vec<Point>> {
    // Work relative to the first vertex: global tile units are large numbers.
    let origin = polygon.outer[0];
    let relative = |p: &Point| Point2::new(p[0] - origin[0], p[1] - origin[1]);
    // Corners come back as the very points given, so edges match the rings bit for bit.
    let mut given: std::collections::HashMap<[u64; 2], Point> = Default::default();
    for p in polygon.rings().flatten() {
        let r = relative(p);
        given.insert([r.x.to_bits(), r.y.to_bits()], *p);
    }
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
    let (cdt, _) = insert(&Cdt::new(), &segments);
    cdt.inner_faces()
        .filter_map(|face| {
            let corners = face.vertices().map(|v| {
                let p = v.position();
                given
                    .get(&[p.x.to_bits(), p.y.to_bits()])
                    .copied()
                    .unwrap_or([p.x + origin[0], p.y + origin[1]])
            });
            let centroid = [
                (corners[0][0] + corners[1][0] + corners[2][0]) / 3.0,
                (corners[0][1] + corners[1][1] + corners[2][1]) / 3.0,
            ];
            polygon.contains(centroid).then(|| corners.to_vec())
        })
        .collect()
}

/// A polygon triangulated with other polygons' rings stitched in: see [`cut_polygon`].
#[derive(Debug, Clone, Default)]
pub struct CutPolygon {
    /// The triangles inside the polygon, counter-clockwise, each with whether it lies in one of
    /// the cuts.
    pub triangles: Vec<([Point; 3], bool)>,
    /// `edges[r][i]`: the polygon's ring `r` from its point `i` to the next, as the points it
    /// passes through (its ends and where a cut's ring crosses or touches it).
    pub edges: Vec<Vec<Vec<Point>>>,
}

/// Triangles covering `polygon` (its rings in the order given), split along the rings of
/// `cuts` where they run inside it, each marked with whether it lies in a cut. Corners are the
/// very points of the rings and the crossing points shared by both rings.
pub fn cut_polygon(polygon: &Polygon, cuts: &[Polygon]) -> CutPolygon {
    let to_point = |p: Point2<f64>| [p.x, p.y];
    let mut segments = Vec::new();
    let mut of_edge: Vec<Vec<Option<usize>>> = Vec::new();
    for ring in polygon.rings() {
        let mut slots = Vec::with_capacity(ring.len());
        for i in 0..ring.len() {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            if a == b {
                slots.push(None);
                continue;
            }
            slots.push(Some(segments.len()));
            segments.push((Point2::new(a[0], a[1]), Point2::new(b[0], b[1])));
        }
        of_edge.push(slots);
    }
    for ring in cuts.iter().flat_map(Polygon::rings) {
        for i in 0..ring.len() {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            if a != b {
                segments.push((Point2::new(a[0], a[1]), Point2::new(b[0], b[1])));
            }
        }
    }
    if segments
        .iter()
        .flat_map(|(a, b)| [a, b])
        .any(|p| !(p.x.is_finite() && p.y.is_finite()))
    {
        return CutPolygon::default();
    }
    // The same splitting the triangulation does, so the edges' points are its vertices.
    let split = split_at_crossings(&segments);
    let edges = of_edge
        .iter()
        .map(|slots| {
            slots
                .iter()
                .map(|slot| match slot {
                    Some(k) => split[*k].iter().copied().map(to_point).collect(),
                    None => Vec::new(),
                })
                .collect()
        })
        .collect();
    let (cdt, _) = insert(&Cdt::new(), &segments);
    let triangles = cdt
        .inner_faces()
        .filter_map(|face| {
            let [a, b, c] = face.vertices().map(|v| to_point(v.position()));
            let centroid = [(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0];
            if !polygon.contains(centroid) {
                return None;
            }
            let corners = if super::signed_area2(&[a, b, c]) >= 0.0 {
                [a, b, c]
            } else {
                [a, c, b]
            };
            Some((corners, cuts.iter().any(|cut| cut.contains(centroid))))
        })
        .collect();
    CutPolygon { triangles, edges }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64) -> Point2<f64> {
        Point2::new(x, y)
    }

    #[test]
    fn crossing_touching_and_overlapping_segments_become_constraints_that_cross_nothing() {
        let segments = [
            // An X.
            (p(0.0, 0.0), p(10.0, 10.0)),
            (p(0.0, 10.0), p(10.0, 0.0)),
            // A T: this one ends on the first diagonal.
            (p(2.0, 8.0), p(7.0, 7.0)),
            // Two that overlap along a line.
            (p(0.0, 12.0), p(6.0, 12.0)),
            (p(4.0, 12.0), p(10.0, 12.0)),
        ];
        let (cdt, left_out) = insert(&Cdt::new(), &segments);
        assert_eq!(left_out, 0);
        // The crossing point and the T's foot are vertices.
        let has = |q: Point2<f64>| cdt.vertices().any(|v| v.position() == q);
        assert!(has(p(5.0, 5.0)) && has(p(7.0, 7.0)));
        // Every segment is covered by constraint edges: total constraint length is the union's.
        let length: f64 = cdt
            .undirected_edges()
            .filter(|e| e.is_constraint_edge())
            .map(|e| {
                let [a, b] = e.positions();
                ((b.x - a.x).powi(2) + (b.y - a.y).powi(2)).sqrt()
            })
            .sum();
        let expected = 2.0 * 200f64.sqrt() + 26f64.sqrt() + 10.0;
        assert!((length - expected).abs() < 1e-9, "{length} vs {expected}");
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

        /// Random segments on a coarse grid (many collinear, touching and crossing), and the
        /// same with tiny offsets: insertion always ends and every constraint edge has length.
        #[test]
        fn any_segments_are_inserted_and_the_insertion_ends(
            raw in proptest::collection::vec(((0i32..8, 0i32..8), (0i32..8, 0i32..8)), 1..40),
            jitter in proptest::bool::ANY,
        ) {
            let segments: Vec<_> = raw
                .iter()
                .enumerate()
                .map(|(k, &((ax, ay), (bx, by)))| {
                    let e = if jitter { 1e-12 * k as f64 } else { 0.0 };
                    (p(f64::from(ax) + e, f64::from(ay)), p(f64::from(bx), f64::from(by) - e))
                })
                .filter(|(a, b)| a != b)
                .collect();
            let (cdt, _) = insert(&Cdt::new(), &segments);
            for e in cdt.undirected_edges().filter(|e| e.is_constraint_edge()) {
                let [a, b] = e.positions();
                proptest::prop_assert!(a != b);
            }
        }
    }
}
