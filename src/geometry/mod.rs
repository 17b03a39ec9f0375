//! Small 2D geometry shared by the feature and mesh stages: rings, point-in-polygon, clipping
//! to a tile square, polylines offset to a width.
//!
//! Geometry is held in global tile units (`u`, `v`, see [`crate::tile`]) until it is placed in a
//! tile, so that a computation that decides a point on a tile edge gives the same bits in both
//! tiles that share the edge. [`constrained`] triangulates with constraint edges that may
//! cross, and polygons with holes.

pub mod cells;
pub mod constrained;

/// A point `[u, v]` (or `[x, z]` once local).
pub type Point = [f64; 2];

/// A closed ring without the repeated last point.
pub type Ring = Vec<Point>;

/// An outer ring and its holes.
#[derive(Debug, Clone, PartialEq)]
pub struct Polygon {
    pub outer: Ring,
    pub holes: Vec<Ring>,
}

impl Polygon {
    pub fn rings(&self) -> impl Iterator<Item = &Ring> {
        std::iter::once(&self.outer).chain(self.holes.iter())
    }

    /// Even-odd containment over all rings.
    pub fn contains(&self, p: Point) -> bool {
        self.rings().filter(|r| ring_contains(r, p)).count() % 2 == 1
    }

    pub fn bounds(&self) -> Rect {
        Rect::around(&self.outer)
    }

    /// The area inside the outer ring and outside the holes.
    pub fn area(&self) -> f64 {
        let ring_area = |ring: &Ring| signed_area2(ring).abs() / 2.0;
        ring_area(&self.outer) - self.holes.iter().map(ring_area).sum::<f64>()
    }
}

/// An axis-aligned rectangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rect {
    pub min: Point,
    pub max: Point,
}

impl Rect {
    pub fn around(points: &[Point]) -> Rect {
        let mut rect = Rect {
            min: [f64::INFINITY; 2],
            max: [f64::NEG_INFINITY; 2],
        };
        for p in points {
            for (axis, &value) in p.iter().enumerate() {
                rect.min[axis] = rect.min[axis].min(value);
                rect.max[axis] = rect.max[axis].max(value);
            }
        }
        rect
    }

    /// The box around all of `polygons`; `None` for none.
    pub fn around_all(polygons: &[Polygon]) -> Option<Rect> {
        polygons
            .iter()
            .map(Polygon::bounds)
            .reduce(|a, b| a.union(&b))
    }

    /// The same box grown by `margin` on every side.
    pub fn widened(&self, margin: f64) -> Rect {
        Rect {
            min: [self.min[0] - margin, self.min[1] - margin],
            max: [self.max[0] + margin, self.max[1] + margin],
        }
    }

    pub fn union(&self, other: &Rect) -> Rect {
        Rect {
            min: [self.min[0].min(other.min[0]), self.min[1].min(other.min[1])],
            max: [self.max[0].max(other.max[0]), self.max[1].max(other.max[1])],
        }
    }

    pub fn intersects(&self, other: &Rect) -> bool {
        self.min[0] <= other.max[0]
            && other.min[0] <= self.max[0]
            && self.min[1] <= other.max[1]
            && other.min[1] <= self.max[1]
    }

    pub fn contains(&self, p: Point) -> bool {
        (self.min[0]..=self.max[0]).contains(&p[0]) && (self.min[1]..=self.max[1]).contains(&p[1])
    }

    /// Whether `p` belongs to this tile square, half-open so that a point on an edge shared by
    /// two tiles belongs to one of them only.
    pub fn owns(&self, p: Point) -> bool {
        (self.min[0]..self.max[0]).contains(&p[0]) && (self.min[1]..self.max[1]).contains(&p[1])
    }
}

/// The cell of `value` on a grid of `cells` cells over `min..min + size`, clamped to the grid:
/// the bucket index of the spatial grids that find nearby segments, pieces and triangles.
pub fn grid_cell(value: f64, min: f64, size: f64, cells: usize) -> usize {
    ((value - min) / size * cells as f64)
        .floor()
        .clamp(0.0, cells as f64 - 1.0) as usize
}

/// Twice the signed area; positive when the ring turns counter-clockwise in a y-up plane
/// (clockwise in `u`, `v`, whose `v` axis points south).
pub fn signed_area2(ring: &[Point]) -> f64 {
    let n = ring.len();
    (0..n)
        .map(|i| {
            let a = ring[i];
            let b = ring[(i + 1) % n];
            a[0] * b[1] - b[0] * a[1]
        })
        .sum()
}

/// Crossing-number test; points exactly on the boundary may go either way.
pub fn ring_contains(ring: &[Point], p: Point) -> bool {
    let n = ring.len();
    let mut inside = false;
    let mut j = n.wrapping_sub(1);
    for i in 0..n {
        let (a, b) = (ring[i], ring[j]);
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let u = (b[0] - a[0]) * (p[1] - a[1]) / (b[1] - a[1]) + a[0];
            if p[0] < u {
                inside = !inside;
            }
        }
        j = i;
    }
    inside
}

/// Drops consecutive duplicates (and a last point equal to the first).
pub fn dedup_ring(points: &[Point]) -> Ring {
    let mut ring: Ring = Vec::with_capacity(points.len());
    for &p in points {
        if ring.last() != Some(&p) {
            ring.push(p);
        }
    }
    while ring.len() > 1 && ring.first() == ring.last() {
        ring.pop();
    }
    ring
}

/// Clips segment `a`–`b` to `rect`. A point where the segment crosses a side of the rectangle
/// gets that side's coordinate exactly and the other coordinate interpolated from `a` and `b`
/// alone, so two rectangles that share the side compute the same point.
pub fn clip_segment(a: Point, b: Point, rect: &Rect) -> Option<(Point, Point)> {
    let d = [b[0] - a[0], b[1] - a[1]];
    // (t, axis, value) of the binding entry and exit sides.
    let mut enter: (f64, Option<(usize, f64)>) = (0.0, None);
    let mut leave: (f64, Option<(usize, f64)>) = (1.0, None);
    for axis in 0..2 {
        if d[axis] == 0.0 {
            if a[axis] < rect.min[axis] || a[axis] > rect.max[axis] {
                return None;
            }
            continue;
        }
        let (near, far) = if d[axis] > 0.0 {
            (rect.min[axis], rect.max[axis])
        } else {
            (rect.max[axis], rect.min[axis])
        };
        let t_near = (near - a[axis]) / d[axis];
        let t_far = (far - a[axis]) / d[axis];
        if t_near > enter.0 {
            enter = (t_near, Some((axis, near)));
        }
        if t_far < leave.0 {
            leave = (t_far, Some((axis, far)));
        }
    }
    if enter.0 > leave.0 {
        return None;
    }
    let place = |(t, side): (f64, Option<(usize, f64)>), default: Point| -> Point {
        match side {
            None => default,
            Some((axis, value)) => {
                let other = 1 - axis;
                let mut p = [0.0; 2];
                p[axis] = value;
                p[other] = (a[other] + t * d[other]).clamp(rect.min[other], rect.max[other]);
                snap_to_corner(p, rect)
            }
        }
    };
    Some((place(enter, a), place(leave, b)))
}

/// A point within this distance of a rectangle's corner (in the rectangle's units) is the corner.
const CORNER_SNAP: f64 = 1e-9;

fn snap_to_corner(p: Point, rect: &Rect) -> Point {
    for cu in [rect.min[0], rect.max[0]] {
        for cv in [rect.min[1], rect.max[1]] {
            if (p[0] - cu).abs() <= CORNER_SNAP && (p[1] - cv).abs() <= CORNER_SNAP {
                return [cu, cv];
            }
        }
    }
    p
}

/// Sutherland–Hodgman clipping of a convex or concave polygon to a rectangle (the result may
/// have edges along the rectangle's sides; good enough for roof caps, not for shared edges).
pub fn clip_ring(ring: &[Point], rect: &Rect) -> Ring {
    dedup_ring(&clip_to_rect(ring, rect))
}

/// Sutherland–Hodgman clipping of a polygon whose first two coordinates are the plan: further
/// coordinates (a height, say) are interpolated along with them, so a vertical wall or a sloped
/// roof is cut where it leaves the rectangle. Points repeated in a row are dropped.
pub fn clip_to_rect<const N: usize>(polygon: &[[f64; N]], rect: &Rect) -> Vec<[f64; N]> {
    let mut output: Vec<[f64; N]> = polygon.to_vec();
    for axis in 0..2 {
        for (bound, keep_greater) in [(rect.min[axis], true), (rect.max[axis], false)] {
            output = clip_half_space(&output, axis, bound, keep_greater);
        }
    }
    output.dedup();
    while output.len() > 1 && output.first() == output.last() {
        output.pop();
    }
    output
}

/// One Sutherland–Hodgman pass: the part of a polygon whose coordinate `axis` is at least
/// `bound` (`keep_greater`) or at most it, the other coordinates interpolated where an edge
/// crosses it (and that coordinate set to `bound` there). Points may repeat in a row.
pub fn clip_half_space<const N: usize>(
    polygon: &[[f64; N]],
    axis: usize,
    bound: f64,
    keep_greater: bool,
) -> Vec<[f64; N]> {
    let inside = |p: &[f64; N]| {
        if keep_greater {
            p[axis] >= bound
        } else {
            p[axis] <= bound
        }
    };
    let n = polygon.len();
    let mut output = Vec::with_capacity(n + 2);
    for i in 0..n {
        let current = polygon[i];
        let previous = polygon[(i + n - 1) % n];
        let crossing = || {
            let t = (bound - previous[axis]) / (current[axis] - previous[axis]);
            let mut p = [0.0; N];
            for (k, c) in p.iter_mut().enumerate() {
                *c = previous[k] + t * (current[k] - previous[k]);
            }
            p[axis] = bound;
            p
        };
        match (inside(&previous), inside(&current)) {
            (true, true) => output.push(current),
            (true, false) => output.push(crossing()),
            (false, true) => {
                output.push(crossing());
                output.push(current);
            }
            (false, false) => {}
        }
    }
    output
}

/// The distance along a polyline from its first point to each of its points.
pub fn distances_along(points: &[Point]) -> Vec<f64> {
    let mut total = 0.0;
    let mut out = Vec::with_capacity(points.len());
    for (i, p) in points.iter().enumerate() {
        if i > 0 {
            let q = points[i - 1];
            total += (p[0] - q[0]).hypot(p[1] - q[1]);
        }
        out.push(total);
    }
    out
}

/// Where `x` falls among ascending `xs` (at least two): the index `k` of the interval from
/// `xs[k - 1]` to `xs[k]` that holds it (the first or last one beyond the ends) and the share
/// of the way along it, clamped to 0–1.
pub fn bracket(xs: &[f64], x: f64) -> (usize, f64) {
    let k = xs.partition_point(|&v| v <= x).clamp(1, xs.len() - 1);
    let (x0, x1) = (xs[k - 1], xs[k]);
    let t = if x1 > x0 {
        ((x - x0) / (x1 - x0)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (k, t)
}

/// The value at `x` of the piecewise linear function through `(xs[i], ys[i])` (`xs`
/// ascending, at least two), held at its ends beyond them.
pub fn interpolate(xs: &[f64], ys: &[f64], x: f64) -> f64 {
    let (k, t) = bracket(xs, x);
    ys[k - 1] + t * (ys[k] - ys[k - 1])
}

/// The length of a polyline.
pub fn polyline_length(points: &[Point]) -> f64 {
    points
        .windows(2)
        .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
        .sum()
}

/// How far along the segment `a`–`b` the point nearest `p` lies, as a share from 0 at `a` to
/// 1 at `b` (0 for a segment of no length).
pub fn share_along_segment(p: Point, a: Point, b: Point) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1]];
    let len2 = d[0] * d[0] + d[1] * d[1];
    if len2 > 0.0 {
        (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// Distance between two points.
pub fn distance(a: Point, b: Point) -> f64 {
    (b[0] - a[0]).hypot(b[1] - a[1])
}

/// The point `t` of the way from `a` to `b` (0 at `a`, 1 at `b`).
pub fn lerp(a: Point, b: Point, t: f64) -> Point {
    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t]
}

/// Distance from `p` to the segment `a`–`b`.
pub fn distance_to_segment(p: Point, a: Point, b: Point) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1]];
    let t = share_along_segment(p, a, b);
    let q = [a[0] + t * d[0], a[1] + t * d[1]];
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt()
}

/// The indices of the points a line simplified to `tolerance` keeps (Ramer–Douglas–Peucker):
/// the ends, and every point that lies further than `tolerance` from the simplified line
/// between its neighbours kept. A closed ring keeps its first (and last) point.
pub fn simplified_indices(points: &[Point], tolerance: f64) -> Vec<usize> {
    if points.len() <= 2 {
        return (0..points.len()).collect();
    }
    let mut keep = vec![false; points.len()];
    keep[0] = true;
    keep[points.len() - 1] = true;
    let mut spans = vec![(0, points.len() - 1)];
    while let Some((first, last)) = spans.pop() {
        let farthest = (first + 1..last)
            .map(|i| {
                (
                    i,
                    distance_to_segment(points[i], points[first], points[last]),
                )
            })
            .fold(
                (first, 0.0),
                |best, next| if next.1 > best.1 { next } else { best },
            );
        if farthest.1 > tolerance {
            keep[farthest.0] = true;
            spans.push((first, farthest.0));
            spans.push((farthest.0, last));
        }
    }
    (0..points.len()).filter(|&i| keep[i]).collect()
}

/// Twice the signed area of the triangle `a`, `b`, `c` (positive when it turns from the first
/// axis towards the second).
pub fn orient(a: Point, b: Point, c: Point) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// True when the closed segments `a`–`b` and `c`–`d` share a point.
pub fn segments_meet(a: Point, b: Point, c: Point, d: Point) -> bool {
    let (o1, o2) = (orient(a, b, c), orient(a, b, d));
    let (o3, o4) = (orient(c, d, a), orient(c, d, b));
    let on = |p: Point, q: Point, r: Point| {
        r[0] >= p[0].min(q[0])
            && r[0] <= p[0].max(q[0])
            && r[1] >= p[1].min(q[1])
            && r[1] <= p[1].max(q[1])
    };
    if ((o1 > 0.0 && o2 < 0.0) || (o1 < 0.0 && o2 > 0.0))
        && ((o3 > 0.0 && o4 < 0.0) || (o3 < 0.0 && o4 > 0.0))
    {
        return true;
    }
    (o1 == 0.0 && on(a, b, c))
        || (o2 == 0.0 && on(a, b, d))
        || (o3 == 0.0 && on(c, d, a))
        || (o4 == 0.0 && on(c, d, b))
}

/// True when two edges of a ring that are not neighbours share a point: the ring crosses or
/// touches itself. Edges are swept in order of their least `u`, so long rings stay cheap.
pub fn ring_self_intersects(ring: &[Point]) -> bool {
    let n = ring.len();
    if n < 4 {
        return false;
    }
    let edge = |i: usize| (ring[i], ring[(i + 1) % n]);
    let mut order: Vec<usize> = (0..n).collect();
    let min_u = |i: usize| {
        let (a, b) = edge(i);
        a[0].min(b[0])
    };
    order.sort_by(|&i, &j| min_u(i).total_cmp(&min_u(j)));
    for (k, &i) in order.iter().enumerate() {
        let (a, b) = edge(i);
        let max_u = a[0].max(b[0]);
        for &j in &order[k + 1..] {
            if min_u(j) > max_u {
                break;
            }
            let adjacent = (i + 1) % n == j || (j + 1) % n == i;
            if adjacent {
                continue;
            }
            let (c, d) = edge(j);
            if segments_meet(a, b, c, d) {
                return true;
            }
        }
    }
    false
}

/// True when all points lie on one line (a ring of them encloses nothing).
pub fn is_collinear(points: &[Point]) -> bool {
    let Some(&first) = points.first() else {
        return true;
    };
    let far = points.iter().copied().max_by(|a, b| {
        let d = |p: &Point| (p[0] - first[0]).powi(2) + (p[1] - first[1]).powi(2);
        d(a).total_cmp(&d(b))
    });
    match far {
        Some(far) => points.iter().all(|&p| orient(first, far, p) == 0.0),
        None => true,
    }
}

/// The convex hull of some points, counter-clockwise in a y-up plane, without collinear points
/// (Andrew's monotone chain).
pub fn convex_hull(points: &[Point]) -> Ring {
    let mut sorted = points.to_vec();
    sorted.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    sorted.dedup();
    if sorted.len() < 3 {
        return sorted;
    }
    let mut hull: Ring = Vec::with_capacity(sorted.len() + 1);
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &Point>> = if pass == 0 {
            Box::new(sorted.iter())
        } else {
            Box::new(sorted.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2
                && orient(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

/// Longest a mitre may grow, as a multiple of the half width, before the join is cut short.
pub const MITRE_LIMIT: f64 = 2.0;

/// The outline of a polyline widened by `half_width` on each side: the left and right offset
/// polylines, joined with mitres (limited to [`MITRE_LIMIT`]). Returns `None` for a polyline
/// with fewer than two distinct points.
pub fn offset_polyline(line: &[Point], half_width: f64) -> Option<(Vec<Point>, Vec<Point>)> {
    let line = {
        let mut l: Vec<Point> = Vec::with_capacity(line.len());
        for &p in line {
            if l.last() != Some(&p) {
                l.push(p);
            }
        }
        l
    };
    if line.len() < 2 {
        return None;
    }
    let normal = |a: Point, b: Point| {
        let d = [b[0] - a[0], b[1] - a[1]];
        let len = (d[0] * d[0] + d[1] * d[1]).sqrt();
        // Left of the direction of travel in a plane whose second axis points south.
        [d[1] / len, -d[0] / len]
    };
    let n = line.len();
    let mut left = Vec::with_capacity(n);
    let mut right = Vec::with_capacity(n);
    for i in 0..n {
        let normal_in = (i > 0).then(|| normal(line[i - 1], line[i]));
        let normal_out = (i + 1 < n).then(|| normal(line[i], line[i + 1]));
        let offset = match (normal_in, normal_out) {
            (Some(a), Some(b)) => {
                let sum = [a[0] + b[0], a[1] + b[1]];
                let len = (sum[0] * sum[0] + sum[1] * sum[1]).sqrt();
                if len < 1e-12 {
                    // A full reversal: no sensible join, use the incoming normal.
                    [a[0] * half_width, a[1] * half_width]
                } else {
                    let m = [sum[0] / len, sum[1] / len];
                    let cos = m[0] * a[0] + m[1] * a[1];
                    let scale = (half_width / cos.max(1e-12)).min(half_width * MITRE_LIMIT);
                    [m[0] * scale, m[1] * scale]
                }
            }
            (Some(a), None) | (None, Some(a)) => [a[0] * half_width, a[1] * half_width],
            (None, None) => unreachable!("a polyline of two or more points"),
        };
        left.push([line[i][0] + offset[0], line[i][1] + offset[1]]);
        right.push([line[i][0] - offset[0], line[i][1] - offset[1]]);
    }
    Some((left, right))
}

/// The cell of a grid of `n` cells a side that a coordinate `t` (in cells) falls in, clamped
/// to the grid.
pub fn grid_index(t: f64, n: f64) -> u32 {
    t.floor().clamp(0.0, n - 1.0) as u32
}

/// The cells the segment `a`–`b` passes through or touches: column by column, the rows its
/// stretch in that column spans (a cell it only grazes at a corner included). Two segments
/// that meet have a cell in common.
pub fn segment_cells(a: [f64; 2], b: [f64; 2], n: f64, cells: &mut Vec<(u32, u32)>) {
    let (first, last) = (grid_index(a[0].min(b[0]), n), grid_index(a[0].max(b[0]), n));
    let v_at = |u: f64| match b[0] == a[0] {
        true => a[1],
        false => a[1] + (b[1] - a[1]) * ((u - a[0]) / (b[0] - a[0])).clamp(0.0, 1.0),
    };
    for x in first..=last {
        let (left, right) = (f64::from(x), f64::from(x) + 1.0);
        let (v0, v1) = match b[0] == a[0] {
            true => (a[1], b[1]),
            false => (
                v_at(left.max(a[0].min(b[0]))),
                v_at(right.min(a[0].max(b[0]))),
            ),
        };
        for y in grid_index(v0.min(v1), n)..=grid_index(v0.max(v1), n) {
            cells.push((x, y));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const UNIT: Rect = Rect {
        min: [0.0, 0.0],
        max: [1.0, 1.0],
    };

    #[test]
    fn clipping_a_crossing_segment_gives_the_same_point_in_both_squares() {
        let (a, b) = ([0.3, 0.123456789], [1.7, 0.987654321]);
        let east = Rect {
            min: [1.0, 0.0],
            max: [2.0, 1.0],
        };
        let (_, exit) = clip_segment(a, b, &UNIT).unwrap();
        let (entry, _) = clip_segment(a, b, &east).unwrap();
        assert_eq!(exit[0], 1.0);
        assert_eq!(exit, entry);
    }

    #[test]
    fn segments_outside_are_dropped_and_inside_kept() {
        assert_eq!(clip_segment([2.0, 2.0], [3.0, 3.0], &UNIT), None);
        assert_eq!(
            clip_segment([0.2, 0.2], [0.4, 0.6], &UNIT),
            Some(([0.2, 0.2], [0.4, 0.6]))
        );
        assert_eq!(clip_segment([-1.0, 0.5], [-0.5, 0.5], &UNIT), None);
    }

    #[test]
    fn point_in_polygon_with_a_hole() {
        let polygon = Polygon {
            outer: vec![[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]],
            holes: vec![vec![[1.0, 1.0], [3.0, 1.0], [3.0, 3.0], [1.0, 3.0]]],
        };
        assert!(polygon.contains([0.5, 0.5]));
        assert!(!polygon.contains([2.0, 2.0]));
        assert!(!polygon.contains([5.0, 2.0]));
    }

    #[test]
    fn ring_clipping_keeps_the_inside() {
        let ring = vec![[-1.0, -1.0], [0.5, -1.0], [0.5, 0.5], [-1.0, 0.5]];
        let clipped = clip_ring(&ring, &UNIT);
        assert!(
            (signed_area2(&clipped).abs() - 0.5).abs() < 1e-12,
            "{clipped:?}"
        );
    }

    #[test]
    fn offset_of_a_straight_line_is_parallel() {
        let (left, right) = offset_polyline(&[[0.0, 0.0], [10.0, 0.0]], 1.0).unwrap();
        // With v pointing south, the left of an eastward line is north (smaller v).
        assert_eq!(left, vec![[0.0, -1.0], [10.0, -1.0]]);
        assert_eq!(right, vec![[0.0, 1.0], [10.0, 1.0]]);
    }

    #[test]
    fn mitre_keeps_the_width_at_a_right_angle() {
        let (left, _) = offset_polyline(&[[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]], 1.0).unwrap();
        let corner = left[1];
        assert!((corner[0] - 11.0).abs() < 1e-12 && (corner[1] + 1.0).abs() < 1e-12);
    }
}
