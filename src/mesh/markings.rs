//! The lines painted on roads ([`crate::features::markings`]) as thin strips just above the
//! settled road surface: a solid line as a strip along each of its segments, a dashed one as
//! such strips along each dash.
//! Each strip piece is clipped to the tile, so a line crossing an edge is cut along it by both
//! tiles at the same points, from the same dashes.

use std::collections::BTreeMap;

use super::{MeshBuffers, Part};
use crate::features::markings::{Marking, Paint, Pattern};
use crate::features::tile_rect;
use crate::geometry::{bracket, clip_to_rect, distance, lerp, Point, Rect};
use crate::terrain::Elevation;
use crate::tile::TileFrame;

/// Height of the paint over the road surface, metres: enough to stay above the drawn surface
/// where it is interpolated between its vertices, too little to be seen as a step.
const LIFT_M: f64 = 0.03;

/// The strips of every marking: the lines along roads as one part, the crossings as another.
pub fn build(
    markings: &[Marking],
    frame: &TileFrame,
    ground: &dyn Elevation,
) -> BTreeMap<Part, MeshBuffers> {
    let mut parts: BTreeMap<Part, MeshBuffers> = BTreeMap::new();
    paint(&mut parts, markings, frame, ground);
    parts
}

/// Adds the strips of `markings` to `parts`, just above the surface `surface` gives the
/// height of.
pub fn paint(
    parts: &mut BTreeMap<Part, MeshBuffers>,
    markings: &[Marking],
    frame: &TileFrame,
    surface: &dyn Elevation,
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
/// node), so a line cut at a junction or a tile edge keeps its rhythm.
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
/// across (a triangle narrowing to `b` when `tip`), clipped to the tile: a piece across an edge is cut along it, at the same points in
/// both tiles.
fn strip(
    buffers: &mut MeshBuffers,
    frame: &TileFrame,
    ground: &dyn Elevation,
    marking: &Marking,
    (a, b): (Point, Point),
    tip: bool,
) {
    let length = distance(a, b);
    if length <= 0.0 {
        return;
    }
    let half = marking.width_m * marking.metre / 2.0;
    let (nu, nv) = (
        -(b[1] - a[1]) / length * half,
        (b[0] - a[0]) / length * half,
    );
    let outline = if tip {
        vec![[a[0] + nu, a[1] + nv], b, [a[0] - nu, a[1] - nv]]
    } else {
        vec![
            [a[0] + nu, a[1] + nv],
            [b[0] + nu, b[1] + nv],
            [b[0] - nu, b[1] - nv],
            [a[0] - nu, a[1] - nv],
        ]
    };
    let clipped = clip_to_rect(&outline, &tile_rect(frame.tile));
    if clipped.len() < 3 {
        return;
    }
    let corners: Vec<[f64; 3]> = clipped
        .iter()
        .map(|&p| {
            let (x, z) = frame.uv_to_local(p[0], p[1]);
            let lift = LIFT_M * frame.scale_at(z);
            [x, frame.elevation_to_y(ground.elevation_uv(p), z) + lift, z]
        })
        .collect();
    buffers.push_flat_polygon(&corners, [0.0, 1.0, 0.0], marking.feature);
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
    fn a_solid_line_is_painted_whole() {
        let runs = painted(&marking(Pattern::Solid, 10.0));
        assert_eq!(runs, vec![vec![[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]]]);
    }
}
