//! The lines painted on roads ([`crate::features::markings`]) as thin strips just above the
//! road surface as drawn: a solid line as a strip along each of its segments, a dashed one as
//! such strips along each dash.
//! Each strip piece is clipped to the tile, so a line crossing an edge is cut along it by both
//! tiles at the same points, from the same dashes, at the settled surface's heights (which
//! both tiles know alike). A piece inside the tile is cut again where the surface it is
//! painted on bends under it (from one flat face to the next), and takes the surface's heights
//! as drawn at its corners, so the paint neither floats over the surface's creases nor sinks
//! into them.

use std::collections::BTreeMap;

use super::drawn_ground::DrawnGround;
use super::structure_lines::Top;
use super::{triangle_normal, MeshBuffers, Part};
use crate::features::markings::{Marking, Paint, Pattern};
use crate::features::tile_rect;
use crate::geometry::{
    bracket, clip_half_space, clip_to_rect, distance, lerp, simplified_indices, Point, Rect,
};
use crate::terrain::Elevation;
use crate::tile::TileFrame;

/// Height of the paint over the road surface, metres: enough to stay above the drawn surface
/// where it is interpolated between its vertices, too little to be seen as a step.
const LIFT_M: f64 = 0.03;

/// How far the surface under a strip may bend away from it before the strip is cut to follow,
/// metres: well inside the lift, so the paint neither sinks nor is seen to float.
const FIT_M: f64 = 0.02;

/// The normal of the paint: it is lit as level ground, whatever the slope it lies on.
const UP: [f64; 3] = [0.0, 1.0, 0.0];

/// What lines are painted on: its height under a point, and where a straight piece of line
/// crosses from one of its flat faces to the next.
pub trait Canvas: Elevation {
    /// The height of the surface drawn at `p`, if it is drawn there (metres).
    fn drawn_at(&self, p: Point) -> Option<f64> {
        Some(self.elevation_uv(p))
    }

    /// The height of the surface `p` lies on as every tile knows it, whichever draws it.
    fn settled_uv(&self, p: Point) -> f64 {
        self.elevation_uv(p)
    }

    /// The shares of the way from `a` to `b` (global tile units) where it crosses from one
    /// face to the next: rising, strictly between 0 and 1.
    fn creases(&self, a: Point, b: Point) -> Vec<f64>;
}

/// The ground is not drawn under a building, and nothing is painted there.
impl Canvas for DrawnGround<'_> {
    fn drawn_at(&self, p: Point) -> Option<f64> {
        DrawnGround::drawn_at(self, p)
    }

    fn settled_uv(&self, p: Point) -> f64 {
        self.model().elevation_uv(p)
    }

    fn creases(&self, a: Point, b: Point) -> Vec<f64> {
        DrawnGround::creases(self, a, b)
    }
}

/// A deck's or a tunnel floor's top is flat between its stations, at which the lines along it
/// have points of their own.
impl Canvas for Top<'_> {
    fn creases(&self, _: Point, _: Point) -> Vec<f64> {
        Vec::new()
    }
}

/// The strips of every marking: the lines along roads as one part, the crossings as another.
pub fn build(
    markings: &[Marking],
    frame: &TileFrame,
    ground: &dyn Canvas,
) -> BTreeMap<Part, MeshBuffers> {
    let mut parts: BTreeMap<Part, MeshBuffers> = BTreeMap::new();
    paint(&mut parts, markings, frame, ground);
    parts
}

/// Adds the strips of `markings` to `parts`, just above `surface`.
pub fn paint(
    parts: &mut BTreeMap<Part, MeshBuffers>,
    markings: &[Marking],
    frame: &TileFrame,
    surface: &dyn Canvas,
) {
    let rect = tile_rect(frame.tile);
    // A piece whose line stays this far outside the tile may still reach into it.
    let margin = markings
        .iter()
        .map(|m| m.width_m * m.metre)
        .fold(0.0, f64::max);
    let reach = Rect {
        min: [rect.min[0] - margin, rect.min[1] - margin],
        max: [rect.max[0] + margin, rect.max[1] + margin],
    };
    for marking in markings {
        let part = match marking.paint {
            Paint::Line => Part::Marking,
            Paint::Crossing => Part::Crossing,
        };
        let buffers = parts.entry(part).or_default();
        for run in painted(marking) {
            let last = run.len().saturating_sub(2);
            for (k, pair) in run.windows(2).enumerate() {
                if Rect::around(pair).intersects(&reach) {
                    let tip = marking.tip && k == last;
                    strip(buffers, frame, surface, marking, (pair[0], pair[1]), tip);
                }
            }
        }
    }
}

/// The painted runs of a marking's line: the whole line when solid, else each dash, laid by
/// the distance along the way (a dash every dash and gap, from half a gap past the way's first
/// node), so a line cut at a junction or a tile edge keeps its rhythm; a piece of the way
/// that falls between two dashes has one dash at its middle.
fn painted(marking: &Marking) -> Vec<Vec<Point>> {
    let (dash, gap) = match marking.pattern {
        Pattern::Solid => return vec![marking.line.clone()],
        Pattern::Dashed { dash_m, gap_m } => (dash_m * marking.metre, gap_m * marking.metre),
    };
    let stations = &marking.stations;
    let (Some(&first), Some(&last)) = (stations.first(), stations.last()) else {
        return Vec::new();
    };
    if dash <= 0.0 || gap < 0.0 || stations.len() != marking.line.len() || last <= first {
        return Vec::new();
    }
    let period = dash + gap;
    let mut runs = Vec::new();
    let mut start = ((first - gap / 2.0) / period).floor() * period + gap / 2.0;
    while start < last {
        let (from, to) = (start.max(first), (start + dash).min(last));
        if to > from {
            runs.push(part_of(&marking.line, stations, (from, to)));
        }
        start += period;
    }
    if runs.is_empty() {
        // A piece shorter than a gap that fell in one still shows its line: one dash at
        // its middle, as long as a dash or half the piece.
        let (middle, half) = ((first + last) / 2.0, dash.min((last - first) / 2.0) / 2.0);
        runs.push(part_of(
            &marking.line,
            stations,
            (middle - half, middle + half),
        ));
    }
    runs
}

/// The part of `line` between stations `from` and `to` (`stations` rising along it): its
/// ends found by [`bracket`], and the line's own points between them.
fn part_of(line: &[Point], stations: &[f64], (from, to): (f64, f64)) -> Vec<Point> {
    let at = |d: f64| {
        let (k, t) = bracket(stations, d);
        lerp(line[k - 1], line[k], t)
    };
    let inside = stations.partition_point(|&s| s <= from)..stations.partition_point(|&s| s < to);
    let mut part = vec![at(from)];
    part.extend_from_slice(&line[inside]);
    part.push(at(to));
    part
}

/// One strip piece from `a` to `b` (global tile units), as wide as the marking and level
/// across (a triangle narrowing to `b` when `tip`): inside the tile, in parts between the cuts
/// where `surface` bends; a piece across the tile's edge is clipped to it whole, at the same
/// points and heights in both tiles.
fn strip(
    buffers: &mut MeshBuffers,
    frame: &TileFrame,
    surface: &dyn Canvas,
    marking: &Marking,
    (a, b): (Point, Point),
    tip: bool,
) {
    let length = distance(a, b);
    if length <= 0.0 {
        return;
    }
    let half = marking.width_m * marking.metre / 2.0;
    let across = [
        -(b[1] - a[1]) / length * half,
        (b[0] - a[0]) / length * half,
    ];
    let side = |p: Point, share: f64| {
        // A tip narrows to nothing at `b`.
        let w = if tip { 1.0 - share } else { 1.0 };
        (
            [p[0] + across[0] * w, p[1] + across[1] * w],
            [p[0] - across[0] * w, p[1] - across[1] * w],
        )
    };
    // The piece's outline between two shares of it: from its left side at the first to its
    // right side there, a triangle to the tip at `b`.
    let outline = |t0: f64, t1: f64| {
        let ((left0, right0), (left1, right1)) =
            (side(lerp(a, b, t0), t0), side(lerp(a, b, t1), t1));
        if tip && t1 >= 1.0 {
            vec![left0, b, right0]
        } else {
            vec![left0, left1, right1, right0]
        }
    };
    let local = |p: Point, height: f64| {
        let (x, z) = frame.uv_to_local(p[0], p[1]);
        [
            x,
            frame.elevation_to_y(height, z) + LIFT_M * frame.scale_at(z),
            z,
        ]
    };
    let feature = marking.feature;
    let whole = outline(0.0, 1.0);
    let rect = tile_rect(frame.tile);
    let shares = cuts(surface, (a, b), length / marking.metre);
    if !whole.iter().all(|&p| rect.contains(p)) {
        across_edge(
            buffers,
            (frame, surface),
            marking,
            (&whole, &shares),
            &outline,
        );
        return;
    }
    // The parts share their vertices, a pair across each cut, and nothing is painted where the
    // surface is not drawn.
    let at = |p: Point| Some(local(p, surface.drawn_at(p)?));
    let mut previous: Option<[u32; 2]> = None;
    for pair in shares.windows(2) {
        let part = outline(pair[0], pair[1]);
        let n = part.len();
        let Some(ahead) = part[1..n - 1]
            .iter()
            .map(|&p| at(p))
            .collect::<Option<Vec<_>>>()
        else {
            previous = None;
            continue;
        };
        // The start's corners are the previous part's end, where it was drawn.
        let [l0, r0] = match previous {
            Some(pushed) => pushed,
            None => {
                let (Some(left), Some(right)) = (at(part[0]), at(part[n - 1])) else {
                    continue;
                };
                [left, right].map(|c| buffers.push_vertex(c, UP, feature))
            }
        };
        let mut push = |c: [f64; 3]| buffers.push_vertex(c, UP, feature);
        if n == 3 {
            let t = push(ahead[0]);
            push_facing_up(buffers, &[l0, t, r0]);
            previous = None;
        } else {
            let [l1, r1] = [ahead[0], ahead[1]].map(&mut push);
            push_facing_up(buffers, &[l0, l1, r1, r0]);
            previous = Some([l1, r1]);
        }
    }
}

/// The parts of a strip piece whose outline `whole` crosses the tile's edge: the outline
/// clipped to the tile, then cut at those of `shares` whose cut lies inside the tile
/// (`outline` gives the outline between two shares). Where it is cut along the tile's edge its
/// corners stand at the settled surface's heights, which both tiles know alike, so both make
/// the same vertices there; elsewhere at the heights of the surface as drawn.
fn across_edge(
    buffers: &mut MeshBuffers,
    (frame, surface): (&TileFrame, &dyn Canvas),
    marking: &Marking,
    (whole, shares): (&[Point], &[f64]),
    outline: &dyn Fn(f64, f64) -> Vec<Point>,
) {
    let rect = tile_rect(frame.tile);
    let on_edge = |p: [f64; 3]| {
        p[0] == rect.min[0] || p[0] == rect.max[0] || p[1] == rect.min[1] || p[1] == rect.max[1]
    };
    // Each corner with its share along the piece, which the clipping carries along.
    let at_share = |points: Vec<Point>, t0: f64, t1: f64| -> Vec<[f64; 3]> {
        let n = points.len();
        points
            .into_iter()
            .enumerate()
            .map(|(k, p)| [p[0], p[1], if k == 0 || k == n - 1 { t0 } else { t1 }])
            .collect()
    };
    let clipped = clip_to_rect(&at_share(whole.to_vec(), 0.0, 1.0), &rect);
    let inner: Vec<f64> = shares
        .iter()
        .copied()
        .filter(|&t| {
            t > 0.0
                && t < 1.0
                && outline(t, t)
                    .iter()
                    .all(|&p| rect.contains(p) && !on_edge([p[0], p[1], 0.0]))
        })
        .collect();
    let bounds: Vec<f64> = std::iter::once(0.0)
        .chain(inner)
        .chain(std::iter::once(1.0))
        .collect();
    for band in bounds.windows(2) {
        let mut part = clip_half_space(&clipped, 2, band[0], true);
        part = clip_half_space(&part, 2, band[1], false);
        part.dedup();
        let corners: Vec<u32> = part
            .into_iter()
            .map(|p| {
                let point = [p[0], p[1]];
                let height = if on_edge(p) {
                    surface.settled_uv(point)
                } else {
                    surface
                        .drawn_at(point)
                        .unwrap_or_else(|| surface.settled_uv(point))
                };
                let (x, z) = frame.uv_to_local(p[0], p[1]);
                let y = frame.elevation_to_y(height, z) + LIFT_M * frame.scale_at(z);
                buffers.push_vertex([x, y, z], UP, marking.feature)
            })
            .collect();
        push_facing_up(buffers, &corners);
    }
}

/// The shares of the way from `a` to `b` (`length_m` long) at which a strip piece is cut:
/// its ends, and the creases of `surface` under it where it bends away from the straight line
/// between the cuts on either side by more than [`FIT_M`].
fn cuts(surface: &dyn Canvas, (a, b): (Point, Point), length_m: f64) -> Vec<f64> {
    let mut shares = vec![0.0];
    shares.extend(surface.creases(a, b));
    shares.push(1.0);
    let profile: Vec<Point> = shares
        .iter()
        .map(|&t| [t * length_m, surface.elevation_uv(lerp(a, b, t))])
        .collect();
    simplified_indices(&profile, FIT_M)
        .into_iter()
        .map(|k| shares[k])
        .collect()
}

/// A fan of triangles over the convex polygon of the vertices `corners` (pushed, in order
/// round it), each wound to face up; none over fewer than three.
fn push_facing_up(buffers: &mut MeshBuffers, corners: &[u32]) {
    let at = |i: u32| buffers.positions[i as usize].map(f64::from);
    let mut triangles = Vec::with_capacity(3 * corners.len());
    for k in 1..corners.len().saturating_sub(1) {
        let (a, b, c) = (corners[0], corners[k], corners[k + 1]);
        let normal = triangle_normal([at(a), at(b), at(c)]);
        if normal[1] > 0.0 {
            triangles.extend_from_slice(&[a, b, c]);
        } else if normal[1] < 0.0 {
            triangles.extend_from_slice(&[a, c, b]);
        }
    }
    buffers.indices.extend(triangles);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn marking(pattern: Pattern, length: f64) -> Marking {
        Marking {
            feature: 0,
            line: vec![[0.0, 0.0], [length / 2.0, 0.0], [length, 0.0]],
            stations: vec![0.0, length / 2.0, length],
            paint: Paint::Line,
            tip: false,
            pattern,
            width_m: 0.12,
            metre: 1.0,
        }
    }

    #[test]
    fn dashes_repeat_by_the_distance_along_the_way_and_are_cut_at_the_ends() {
        let dashed = Pattern::Dashed {
            dash_m: 3.0,
            gap_m: 6.0,
        };
        let runs = painted(&marking(dashed, 40.0));
        // Dashes start at 3, 12, 21, 30 and 39 m; the last is cut at the line's end.
        assert_eq!(runs.len(), 5);
        for (k, run) in runs.iter().enumerate() {
            let start = 3.0 + 9.0 * k as f64;
            assert_eq!(run.first(), Some(&[start, 0.0]));
            assert_eq!(run.last(), Some(&[(start + 3.0).min(40.0), 0.0]));
        }
        // A dash across a bend of the line keeps the bend.
        let runs = painted(&marking(dashed, 45.0));
        assert!(runs.contains(&vec![[21.0, 0.0], [22.5, 0.0], [24.0, 0.0]]));
        // A line that begins 13 m along its way (cut back at a junction) keeps the way's
        // rhythm: it begins inside the dash that started at 12 m.
        let mut cut = marking(dashed, 40.0);
        cut.stations = cut.stations.iter().map(|s| s + 13.0).collect();
        let runs = painted(&cut);
        assert_eq!(runs[0], vec![[0.0, 0.0], [2.0, 0.0]]);
        assert_eq!(runs[1].first(), Some(&[8.0, 0.0]));
    }

    #[test]
    fn a_piece_between_two_dashes_has_one_at_its_middle() {
        let dashed = Pattern::Dashed {
            dash_m: 3.0,
            gap_m: 6.0,
        };
        // A piece 4 m long from 6.5 m along its way lies in the gap from 6 m to 12 m.
        let mut short = marking(dashed, 4.0);
        short.stations = short.stations.iter().map(|s| s + 6.5).collect();
        assert_eq!(
            painted(&short),
            vec![vec![[1.0, 0.0], [2.0, 0.0], [3.0, 0.0]]]
        );
        // A piece that holds part of a dash keeps only that part.
        short.stations = short.stations.iter().map(|s| s + 4.5).collect();
        assert_eq!(
            painted(&short),
            vec![vec![[1.0, 0.0], [2.0, 0.0], [4.0, 0.0]]]
        );
    }

    #[test]
    fn a_solid_line_is_painted_whole() {
        let runs = painted(&marking(Pattern::Solid, 10.0));
        assert_eq!(runs, vec![vec![[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]]]);
    }
}
