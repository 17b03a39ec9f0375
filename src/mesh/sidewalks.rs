//! Sidewalks and verges ([`crate::features::sidewalks`]) on the ground beside the roads: a
//! sidewalk as a wedge on its band, its top at its kerb's height over the road's edge along
//! the kerb and just above the ground at its outer edge (so no step or gap shows there,
//! whether the ground rises or falls), a kerb face towards the road and a face at each end; a
//! verge as a strip just above the ground. Heights are the ground's as the tile draws it (its
//! mesh lies within the error bound of the settled ground, above it or below), and on the
//! tile's edge the settled ground's, which both tiles know alike.
//! Inside the tile, neighbouring stretches share their vertices; a stretch across an edge is
//! clipped to the tile, so both tiles cut it along the edge at the same points.

use std::collections::BTreeMap;

use super::markings::Canvas;
use super::{MeshBuffers, Part};
use crate::features::sidewalks::{Band, Look};
use crate::features::tile_rect;
use crate::geometry::{clip_segment, clip_to_rect, Point, Rect};
use crate::tile::TileFrame;

/// Height of a verge, and of a sidewalk's outer edge, over the ground, metres (as the paint
/// of markings over a road).
const LIFT_M: f64 = 0.03;
/// How far a sidewalk's faces reach down into the road and ground under them, metres, so no
/// gap shows where the ground is interpolated between its vertices.
const FOOT_M: f64 = 0.05;

/// The sidewalks' tops, kerbs and the verges, added to `parts`.
pub fn build(
    bands: &[Band],
    frame: &TileFrame,
    ground: &dyn Canvas,
    parts: &mut BTreeMap<Part, MeshBuffers>,
) {
    let rect = tile_rect(frame.tile);
    for band in bands {
        let n = band.inner.len().min(band.outer.len());
        if n < 2 || !reaches(band, &rect) {
            continue;
        }
        let placed = Placed::new(band, frame, ground, n);
        match band.look {
            Look::Verge => {
                let buffers = parts.entry(Part::Verge).or_default();
                placed.top(buffers, &rect, (LIFT_M, LIFT_M));
            }
            Look::Sidewalk { kerb_m } => {
                let kerb_m = kerb_m.max(LIFT_M);
                let top = parts.entry(Part::Sidewalk).or_default();
                placed.top(top, &rect, (kerb_m, LIFT_M));
                let kerb = parts.entry(Part::Kerb).or_default();
                placed.kerb(kerb, &rect, kerb_m);
                placed.ends(kerb, &rect, kerb_m);
            }
        }
    }
}

fn reaches(band: &Band, rect: &Rect) -> bool {
    Rect::around(&band.inner)
        .union(&Rect::around(&band.outer))
        .intersects(rect)
}

/// A band's points with the ground's elevation at each (the road's on its inner edge).
struct Placed<'a> {
    band: &'a Band,
    frame: &'a TileFrame,
    ground: &'a dyn Canvas,
    rect: Rect,
    n: usize,
    inner: Vec<f64>,
    outer: Vec<f64>,
}

impl<'a> Placed<'a> {
    fn new(band: &'a Band, frame: &'a TileFrame, ground: &'a dyn Canvas, n: usize) -> Self {
        let mut placed = Placed {
            band,
            frame,
            ground,
            rect: tile_rect(frame.tile),
            n,
            inner: Vec::new(),
            outer: Vec::new(),
        };
        placed.inner = band.inner[..n].iter().map(|&p| placed.height(p)).collect();
        placed.outer = band.outer[..n].iter().map(|&p| placed.height(p)).collect();
        placed
    }

    /// The ground's height at `p`: as drawn inside the tile, as settled on its edge, off it and
    /// where no ground is drawn (under a building).
    fn height(&self, p: Point) -> f64 {
        let Rect { min, max } = self.rect;
        if p[0] <= min[0] || p[0] >= max[0] || p[1] <= min[1] || p[1] >= max[1] {
            return self.ground.settled_uv(p);
        }
        self.ground
            .drawn_at(p)
            .unwrap_or_else(|| self.ground.settled_uv(p))
    }

    /// A point of the band at `lift` metres over the ground, in the tile's frame.
    fn local(&self, p: Point, elevation: f64, lift: f64) -> [f64; 3] {
        let (x, z) = self.frame.uv_to_local(p[0], p[1]);
        let y = self.frame.elevation_to_y(elevation + lift, z);
        [x, y, z]
    }

    /// The band's top, `inner` and `outer` metres over the ground on its edges: a strip
    /// whose stretches inside the tile share their vertices, and clipped stretches where it
    /// crosses an edge.
    fn top(&self, buffers: &mut MeshBuffers, rect: &Rect, (inner, outer): (f64, f64)) {
        let up = [0.0, 1.0, 0.0];
        let feature = self.band.feature;
        let mut previous: Option<[u32; 2]> = None;
        for k in 1..self.n {
            let quad = [
                (self.band.inner[k - 1], self.inner[k - 1], inner),
                (self.band.inner[k], self.inner[k], inner),
                (self.band.outer[k], self.outer[k], outer),
                (self.band.outer[k - 1], self.outer[k - 1], outer),
            ];
            let mut corner = |(p, h, lift): (Point, f64, f64)| {
                buffers.push_vertex(self.local(p, h, lift), up, feature)
            };
            if quad.iter().all(|(p, ..)| rect.contains(*p)) {
                let [a, b] = previous.unwrap_or_else(|| [quad[0], quad[3]].map(&mut corner));
                let [c, d] = [quad[1], quad[2]].map(&mut corner);
                buffers.push_quad([a, c, d, b], up);
                previous = Some([c, d]);
                continue;
            }
            previous = None;
            // The lift across the band goes with each corner through the clip.
            let flat: Vec<[f64; 3]> = quad
                .iter()
                .map(|(p, _, lift)| [p[0], p[1], *lift])
                .collect();
            let clipped = clip_to_rect(&flat, rect);
            if clipped.len() < 3 {
                continue;
            }
            let corners: Vec<[f64; 3]> = clipped
                .iter()
                .map(|&[u, v, lift]| self.local([u, v], self.height([u, v]), lift))
                .collect();
            buffers.push_flat_polygon(&corners, up, feature);
        }
    }

    /// The kerb: the vertical face along the inner edge, from under the road up to the
    /// top, facing the carriageway: a strip whose stretches inside the tile share their
    /// vertices, and clipped stretches where it crosses an edge.
    fn kerb(&self, buffers: &mut MeshBuffers, rect: &Rect, top: f64) {
        let (line, heights) = (&self.band.inner[..self.n], &self.inner);
        let other = &self.band.outer[..self.n];
        let feature = self.band.feature;
        // Towards the carriageway, for each stretch: square to it, on the side away from the
        // outer edge.
        let away: Vec<[f64; 2]> = (1..self.n)
            .map(|k| {
                let (a, b) = (line[k - 1], line[k]);
                let (du, dv) = (b[0] - a[0], b[1] - a[1]);
                let length = du.hypot(dv).max(f64::MIN_POSITIVE);
                let square = [-dv / length, du / length];
                let from_other = [
                    a[0] + b[0] - other[k - 1][0] - other[k][0],
                    a[1] + b[1] - other[k - 1][1] - other[k][1],
                ];
                let sign = if square[0] * from_other[0] + square[1] * from_other[1] < 0.0 {
                    -1.0
                } else {
                    1.0
                };
                [square[0] * sign, square[1] * sign]
            })
            .collect();
        // A point's normal is the mean of its stretches'.
        let normal_at = |k: usize| {
            let before = away[k.saturating_sub(1).min(away.len() - 1)];
            let after = away[k.min(away.len() - 1)];
            let (u, v) = (before[0] + after[0], before[1] + after[1]);
            let length = u.hypot(v);
            if length > 1e-9 {
                [u / length, 0.0, v / length]
            } else {
                [after[0], 0.0, after[1]]
            }
        };
        let mut previous: Option<[u32; 2]> = None;
        for k in 1..self.n {
            let facing = [away[k - 1][0], 0.0, away[k - 1][1]];
            if rect.contains(line[k - 1]) && rect.contains(line[k]) {
                let mut station = |j: usize| {
                    let normal = normal_at(j);
                    [-FOOT_M, top].map(|lift| {
                        buffers.push_vertex(self.local(line[j], heights[j], lift), normal, feature)
                    })
                };
                let [a, d] = previous.unwrap_or_else(|| station(k - 1));
                let [b, c] = station(k);
                buffers.push_quad([a, b, c, d], facing);
                previous = Some([b, c]);
                continue;
            }
            previous = None;
            let Some((a, b)) = clip_segment(line[k - 1], line[k], rect) else {
                continue;
            };
            let (ha, hb) = (self.height(a), self.height(b));
            let corners = [
                self.local(a, ha, -FOOT_M),
                self.local(b, hb, -FOOT_M),
                self.local(b, hb, top),
                self.local(a, ha, top),
            ];
            buffers.push_flat_polygon(&corners, facing, feature);
        }
    }

    /// The faces across the band at its two ends, where they lie inside the tile.
    fn ends(&self, buffers: &mut MeshBuffers, rect: &Rect, top: f64) {
        let last = self.n - 1;
        for (k, towards) in [(0, 1), (last, last - 1)] {
            let (inner, outer) = (self.band.inner[k], self.band.outer[k]);
            if !rect.contains(inner) || !rect.contains(outer) {
                continue;
            }
            let corners = [
                self.local(inner, self.inner[k], -FOOT_M),
                self.local(outer, self.outer[k], -FOOT_M),
                self.local(outer, self.outer[k], LIFT_M),
                self.local(inner, self.inner[k], top),
            ];
            let along = self.band.inner[towards];
            let facing = [inner[0] - along[0], 0.0, inner[1] - along[1]];
            buffers.push_flat_polygon(&corners, facing, self.band.feature);
        }
    }
}
