//! The ground as the tile draws it: the height of its triangulation under a point (each
//! triangle flat between its corners' drawn heights), and where a straight line crosses from
//! one of its triangles to the next. What stands or is painted on the ground takes its height
//! from here rather than from the settled surface the triangulation approximates, which it may
//! leave by up to the mesh's error bound.

use super::ground::{Ground, GroundTriangle};
use super::Part;
use crate::features::Surface;
use crate::geometry::{grid_cell, orient, Point};
use crate::tile::TileFrame;

/// Ground triangles in buckets, to find the triangle under a point.
struct Locator<'a> {
    ground: &'a Ground,
    cells: usize,
    size: f64,
    buckets: Vec<Vec<u32>>,
}

impl<'a> Locator<'a> {
    fn new(ground: &'a Ground, size: f64) -> Locator<'a> {
        let cells = 64;
        let mut buckets = vec![Vec::new(); cells * cells];
        let cell = |v: f64| grid_cell(v, 0.0, size, cells);
        for (index, triangle) in ground.triangles.iter().enumerate() {
            let corners = triangle.vertices.map(|v| ground.vertices[v as usize]);
            let (x0, x1) = min_max(corners.map(|p| p[0]));
            let (z0, z1) = min_max(corners.map(|p| p[1]));
            for row in cell(z0)..=cell(z1) {
                for column in cell(x0)..=cell(x1) {
                    buckets[row * cells + column].push(index as u32);
                }
            }
        }
        Locator {
            ground,
            cells,
            size,
            buckets,
        }
    }

    /// The triangle holding `(x, z)` and the barycentric weights of its corners.
    fn locate(&self, x: f64, z: f64) -> Option<(usize, [f64; 3])> {
        let cell = |v: f64| grid_cell(v, 0.0, self.size, self.cells);
        self.buckets[cell(z) * self.cells + cell(x)]
            .iter()
            .find_map(|&index| {
                let t = &self.ground.triangles[index as usize];
                let [a, b, c] = t.vertices.map(|v| self.ground.vertices[v as usize]);
                let det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
                if det == 0.0 {
                    return None;
                }
                let l1 = ((x - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (z - a[1])) / det;
                let l2 = ((b[0] - a[0]) * (z - a[1]) - (x - a[0]) * (b[1] - a[1])) / det;
                let l0 = 1.0 - l1 - l2;
                (l0 >= 0.0 && l1 >= 0.0 && l2 >= 0.0).then_some((index as usize, [l0, l1, l2]))
            })
    }

    /// The triangles in the buckets the box from `a` to `b` (local) overlaps, each once.
    fn near(&self, a: [f64; 2], b: [f64; 2]) -> Vec<u32> {
        let cell = |v: f64| grid_cell(v, 0.0, self.size, self.cells);
        let mut found = Vec::new();
        for row in cell(a[1].min(b[1]))..=cell(a[1].max(b[1])) {
            for column in cell(a[0].min(b[0]))..=cell(a[0].max(b[0])) {
                found.extend_from_slice(&self.buckets[row * self.cells + column]);
            }
        }
        found.sort_unstable();
        found.dedup();
        found
    }
}

/// The ground as the tile draws it: the elevation of its ground mesh under a point, and off
/// the tile the ground model's.
pub struct DrawnGround<'a> {
    locator: Locator<'a>,
    /// By surface: whether its ground is left undrawn (a building's footprint).
    undrawn: Vec<bool>,
    vertex_y: &'a [f64],
    pub(super) frame: &'a TileFrame,
    model: &'a dyn crate::terrain::Elevation,
}

impl<'a> DrawnGround<'a> {
    /// `vertex_y` holds the `y` of each of `ground`'s vertices in the local frame, whose
    /// triangles name their surface among `surfaces`.
    pub fn new(
        (ground, surfaces): (&'a Ground, &[Surface]),
        vertex_y: &'a [f64],
        frame: &'a TileFrame,
        model: &'a dyn crate::terrain::Elevation,
    ) -> DrawnGround<'a> {
        DrawnGround {
            locator: Locator::new(ground, frame.size_m),
            undrawn: surfaces
                .iter()
                .map(|s| Part::of_ground(s.class, s.cover, s.paving).is_none())
                .collect(),
            vertex_y,
            frame,
            model,
        }
    }

    /// The ground triangle under local `(x, z)` and the `y` of the mesh there.
    pub(super) fn under(&self, x: f64, z: f64) -> Option<(&GroundTriangle, f64)> {
        let (index, weights) = self.locator.locate(x, z)?;
        let triangle = &self.locator.ground.triangles[index];
        let y = (0..3)
            .map(|k| weights[k] * self.vertex_y[triangle.vertices[k] as usize])
            .sum();
        Some((triangle, y))
    }

    /// The ground the mesh approximates (the settled surface), as every tile knows it.
    pub fn model(&self) -> &dyn crate::terrain::Elevation {
        self.model
    }

    /// The elevation of the ground mesh at `p` (global tile units), where there is ground
    /// drawn (not under a building, not off the tile).
    pub fn drawn_at(&self, p: Point) -> Option<f64> {
        let (x, z) = self.frame.uv_to_local(p[0], p[1]);
        let (triangle, y) = self.under(x, z)?;
        let undrawn = triangle
            .surface
            .is_some_and(|s| self.undrawn.get(s as usize).copied().unwrap_or(false));
        (!undrawn).then(|| y / self.frame.scale_at(z))
    }

    /// Where the straight line from `a` to `b` (global tile units) crosses an edge of the
    /// ground's triangles, as shares of the way from `a`: rising, strictly between 0 and 1,
    /// each once. Between two of them the line lies on one flat triangle.
    pub fn creases(&self, a: Point, b: Point) -> Vec<f64> {
        let (ax, az) = self.frame.uv_to_local(a[0], a[1]);
        let (bx, bz) = self.frame.uv_to_local(b[0], b[1]);
        let (p, q) = ([ax, az], [bx, bz]);
        let ground = self.locator.ground;
        let mut shares: Vec<f64> = self
            .locator
            .near(p, q)
            .into_iter()
            .flat_map(|index| {
                let corners = ground.triangles[index as usize]
                    .vertices
                    .map(|v| ground.vertices[v as usize]);
                (0..3).filter_map(move |k| crossing(p, q, corners[k], corners[(k + 1) % 3]))
            })
            .filter(|&t| t > 0.0 && t < 1.0)
            .collect();
        shares.sort_by(f64::total_cmp);
        shares.dedup_by(|later, earlier| *later - *earlier < 1e-9);
        shares
    }
}

/// The share of the way from `p` to `q` at which it crosses the segment from `c` to `d`, if
/// it does (touching counts, running along it does not).
fn crossing(p: Point, q: Point, c: Point, d: Point) -> Option<f64> {
    let (sc, sd) = (orient(p, q, c), orient(p, q, d));
    if (sc > 0.0 && sd > 0.0) || (sc < 0.0 && sd < 0.0) || sc == sd {
        return None;
    }
    let (sp, sq) = (orient(c, d, p), orient(c, d, q));
    if (sp > 0.0 && sq > 0.0) || (sp < 0.0 && sq < 0.0) || sp == sq {
        return None;
    }
    Some(sp / (sp - sq))
}

impl crate::terrain::Elevation for DrawnGround<'_> {
    fn elevation_uv(&self, p: [f64; 2]) -> f64 {
        let (x, z) = self.frame.uv_to_local(p[0], p[1]);
        match self.under(x, z) {
            Some((_, y)) => y / self.frame.scale_at(z),
            None => self.model.elevation_uv(p),
        }
    }
}

fn min_max(values: [f64; 3]) -> (f64, f64) {
    (
        values.iter().copied().fold(f64::INFINITY, f64::min),
        values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_crosses_an_edge_at_its_share_and_not_an_edge_it_misses_or_runs_along() {
        let (p, q) = ([0.0, 0.0], [4.0, 0.0]);
        assert_eq!(crossing(p, q, [1.0, -1.0], [1.0, 1.0]), Some(0.25));
        assert_eq!(crossing(p, q, [5.0, -1.0], [5.0, 1.0]), None);
        assert_eq!(crossing(p, q, [1.0, 1.0], [2.0, 2.0]), None);
        assert_eq!(crossing(p, q, [1.0, 0.0], [2.0, 0.0]), None);
        // An edge ending on the line is touched.
        assert_eq!(crossing(p, q, [3.0, 0.0], [3.0, 1.0]), Some(0.75));
    }
}
