//! The ground as elevation settles it: surfaces whose elevation follows a rule instead of the
//! terrain (water lying flat, a cut down to a tunnel's portal, ground raised over a tunnel's
//! roof), as areas with their rule. [`super::ground`] puts them together.

use std::sync::OnceLock;

use crate::geometry::cells::{Cell, CellIndex};
use crate::geometry::{distance_to_segment, ring_contains, Point, Polygon, Rect};

/// A point this close to a settled surface's outline (global tile units: a few micrometres at zoom
/// 14) takes its rule: vertices on the outline belong to the surface as well as to what is around it.
pub(super) const ON_OUTLINE: f64 = 1e-9;

/// One surface and the elevation the ground takes on it.
#[derive(Debug, Clone)]
pub struct Level {
    /// The surface's index in its feature set.
    pub surface: u32,
    pub pieces: Vec<Polygon>,
    pub bounds: Rect,
    pub rule: Rule,
    /// How the rule bounds the ground there.
    pub bound: Bound,
    /// Where the area lies, made when it is first asked whether it covers a point: the levels
    /// of roads are found piece by piece and never need it.
    cells: OnceLock<CellIndex>,
}

/// How a level's rule bounds the ground it covers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Bound {
    /// The ground takes the rule's elevation.
    Exact,
    /// A floor: where the terrain is higher, the terrain stays (over a tunnel's roof).
    AtLeast,
    /// A ceiling over the terrain: where the terrain is lower, it stays (under a bridge's
    /// deck). Roads and water keep their own levels under it.
    AtMost,
}

/// The elevation of a settled surface.
#[derive(Debug, Clone, PartialEq)]
pub enum Rule {
    /// Flat, metres above sea level.
    Level(f64),
    /// The profile's elevation at the point's station along a line (down a waterway, down a
    /// tunnel's approach).
    Along {
        stations: Stations,
        /// Distance along the line (tile units) and elevation, by distance.
        profile: Vec<(f64, f64)>,
    },
    /// The profile's elevation at the point's station across a strip of quads (a road level
    /// across its width).
    Across {
        sections: Sections,
        /// Distance along the sections' midpoints (tile units) and elevation.
        profile: Vec<(f64, f64)>,
    },
    /// A trough along a line (the ground under a bridge's deck): the profile's elevation at
    /// the point's station within `half_width` of the line (tile units), rising by `rise`
    /// metres per tile unit beyond it, so the ground slopes back up to the terrain beside.
    Trough {
        stations: Stations,
        profile: Vec<(f64, f64)>,
        half_width: f64,
        rise: f64,
    },
}

impl Rule {
    pub fn elevation(&self, p: Point) -> f64 {
        match self {
            Rule::Level(level) => *level,
            Rule::Along { stations, profile } => at_station(profile, stations.at(p)),
            Rule::Across { sections, profile } => at_station(profile, sections.at(p)),
            Rule::Trough {
                stations,
                profile,
                half_width,
                rise,
            } => {
                let (along, off) = stations.place(p);
                at_station(profile, along) + rise * (off - half_width).max(0.0)
            }
        }
    }
}

/// Points along a line with their distance along it (tile units): each vertex, points every
/// `step` or less between them, and the last vertex.
pub fn samples_along(line: &[Point], step: f64) -> Vec<(f64, Point)> {
    let mut samples = Vec::new();
    let mut start = 0.0;
    for pair in line.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let length = (b[0] - a[0]).hypot(b[1] - a[1]);
        let steps = (length / step).ceil().max(1.0) as usize;
        for k in 0..steps {
            let t = k as f64 / steps as f64;
            samples.push((
                start + t * length,
                [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])],
            ));
        }
        start += length;
    }
    if let Some(&end) = line.last() {
        samples.push((start, end));
    }
    samples
}

/// A profile's elevation at a station, interpolated.
fn at_station(profile: &[(f64, f64)], along: f64) -> f64 {
    let k = profile.partition_point(|&(s, _)| s <= along);
    match (
        k.checked_sub(1).and_then(|i| profile.get(i)),
        profile.get(k),
    ) {
        (Some(&(s0, h0)), Some(&(s1, h1))) if s1 > s0 => h0 + (h1 - h0) * (along - s0) / (s1 - s0),
        (Some(&(_, h)), _) | (None, Some(&(_, h))) => h,
        (None, None) => 0.0,
    }
}

/// Stations over a strip of quads between cross-sections (a road widened from its line): a
/// point in the quad between sections `k` and `k + 1` lies at the share of the way given by
/// its distances to the two, so every point of a cross-section has the same station however
/// tight the bend (where bisector bands of the centre line would cross inside the strip).
#[derive(Debug, Clone, PartialEq)]
pub struct Sections {
    /// Each cross-section's two ends.
    sections: Vec<(Point, Point)>,
    /// The station of each section: the distance along the line through their midpoints.
    starts: Vec<f64>,
}

impl Sections {
    /// The sections of quads given as `[left_k, left_k+1, right_k+1, right_k]`, in order along
    /// the strip. `None` if a quad does not continue the one before.
    pub fn from_quads(quads: &[Polygon]) -> Option<Sections> {
        let mut sections: Vec<(Point, Point)> = Vec::with_capacity(quads.len() + 1);
        for quad in quads {
            let [l0, l1, r1, r0] = <[Point; 4]>::try_from(quad.outer.as_slice()).ok()?;
            match sections.last() {
                Some(&last) if last != (l0, r0) => return None,
                Some(_) => {}
                None => sections.push((l0, r0)),
            }
            sections.push((l1, r1));
        }
        let mid = |(a, b): (Point, Point)| [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
        let mut starts = Vec::with_capacity(sections.len());
        let mut along = 0.0;
        for k in 0..sections.len() {
            if k > 0 {
                let (a, b) = (mid(sections[k - 1]), mid(sections[k]));
                along += (b[0] - a[0]).hypot(b[1] - a[1]);
            }
            starts.push(along);
        }
        (sections.len() >= 2).then_some(Sections { sections, starts })
    }

    /// The station of each cross-section, in order.
    pub fn starts(&self) -> &[f64] {
        &self.starts
    }

    /// The line through the sections' midpoints.
    pub fn centre_line(&self) -> Vec<Point> {
        self.sections
            .iter()
            .map(|(a, b)| [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0])
            .collect()
    }

    /// The station of `p`: in the quad that holds it (the nearest, for a point just outside).
    pub fn at(&self, p: Point) -> f64 {
        // On a cross-section (a quad on the inside of a tight bend may fold over its
        // neighbour, so the quad that holds a point there is ambiguous).
        if let Some(k) = (0..self.sections.len()).find(|&k| {
            let (l, r) = self.sections[k];
            on_segment(p, l, r)
        }) {
            return self.starts[k];
        }
        // The first quad that holds `p`, else the nearest.
        let quad = (0..self.sections.len() - 1)
            .find(|&k| Rect::around(&self.quad(k)).contains(p) && self.outside(k, p) == 0.0)
            .or_else(|| self.nearest(p));
        quad.map_or(0.0, |k| {
            let (l0, r0) = self.sections[k];
            let (l1, r1) = self.sections[k + 1];
            let d0 = distance_to_segment(p, l0, r0);
            let d1 = distance_to_segment(p, l1, r1);
            let share = if d0 + d1 > 0.0 { d0 / (d0 + d1) } else { 0.0 };
            self.starts[k] + share * (self.starts[k + 1] - self.starts[k])
        })
    }

    /// The quad between sections `k` and `k + 1`.
    fn quad(&self, k: usize) -> [Point; 4] {
        let (l0, r0) = self.sections[k];
        let (l1, r1) = self.sections[k + 1];
        [l0, l1, r1, r0]
    }

    /// How far `p` lies outside quad `k`: 0 inside it.
    fn outside(&self, k: usize, p: Point) -> f64 {
        let ring = self.quad(k);
        if ring_contains(&ring, p) {
            0.0
        } else {
            (0..4)
                .map(|i| distance_to_segment(p, ring[i], ring[(i + 1) % 4]))
                .fold(f64::INFINITY, f64::min)
        }
    }

    /// The quad nearest `p`, the first of those as near; a quad whose box lies further than
    /// the nearest so far is passed over unmeasured.
    fn nearest(&self, p: Point) -> Option<usize> {
        let mut best: Option<(f64, usize)> = None;
        for k in 0..self.sections.len() - 1 {
            if let Some((d, _)) = best {
                if box_distance(&self.quad(k), p) > d * (1.0 + 1e-9) {
                    continue;
                }
            }
            let outside = self.outside(k, p);
            if best.is_none_or(|(d, _)| outside < d) {
                best = Some((outside, k));
            }
        }
        best.map(|(_, k)| k)
    }
}

/// How far `p` lies from the box of `points`: no further than from any of them or the
/// segments between them.
fn box_distance(points: &[Point], p: Point) -> f64 {
    let b = Rect::around(points);
    let dx = (b.min[0] - p[0]).max(p[0] - b.max[0]).max(0.0);
    let dy = (b.min[1] - p[1]).max(p[1] - b.max[1]).max(0.0);
    dx.hypot(dy)
}

/// Stations along a polyline: how far along it (tile units) a point lies. Within the band of
/// the segment whose end bisectors enclose the point (the nearest such segment), the station is
/// the share of the way from one bisector to the other. Unlike the nearest point, this is
/// continuous on the inside of a bend, so a surface that follows it has no step there.
#[derive(Debug, Clone, PartialEq)]
pub struct Stations {
    line: Vec<Point>,
    /// The normal of the bisector at each vertex: the mean of the directions either side.
    normals: Vec<Point>,
    /// The station of each vertex.
    starts: Vec<f64>,
}

impl Stations {
    pub fn new(line: &[Point]) -> Stations {
        // A repeated point would make a band of no length that takes in everything.
        let mut distinct: Vec<Point> = Vec::with_capacity(line.len());
        for &p in line {
            if distinct.last() != Some(&p) {
                distinct.push(p);
            }
        }
        let line = distinct.as_slice();
        let n = line.len();
        let unit = |d: Point| {
            let length = d[0].hypot(d[1]);
            if length > 0.0 {
                [d[0] / length, d[1] / length]
            } else {
                [0.0, 0.0]
            }
        };
        let direction = |k: usize| unit([line[k + 1][0] - line[k][0], line[k + 1][1] - line[k][1]]);
        let normals = (0..n)
            .map(|k| {
                let before = if k > 0 { direction(k - 1) } else { [0.0, 0.0] };
                let after = if k + 1 < n { direction(k) } else { [0.0, 0.0] };
                unit([before[0] + after[0], before[1] + after[1]])
            })
            .collect();
        let mut starts = Vec::with_capacity(n);
        let mut along = 0.0;
        for k in 0..n {
            starts.push(along);
            if k + 1 < n {
                along += (line[k + 1][0] - line[k][0]).hypot(line[k + 1][1] - line[k][1]);
            }
        }
        Stations {
            line: line.to_vec(),
            normals,
            starts,
        }
    }

    /// The station of `p`.
    pub fn at(&self, p: Point) -> f64 {
        self.place(p).0
    }

    /// The station of `p` and its distance from the line (tile units).
    pub fn place(&self, p: Point) -> (f64, f64) {
        let n = self.line.len();
        let dot = |a: Point, b: Point| a[0] * b[0] + a[1] * b[1];
        let mut best: Option<(f64, f64)> = None;
        for i in 0..n.saturating_sub(1) {
            let (a, b) = (self.line[i], self.line[i + 1]);
            let mut d0 = dot([p[0] - a[0], p[1] - a[1]], self.normals[i]);
            let mut d1 = -dot([p[0] - b[0], p[1] - b[1]], self.normals[i + 1]);
            // Beyond the ends, the first and last bands go on.
            if i == 0 {
                d0 = d0.max(0.0);
            }
            if i + 2 == n {
                d1 = d1.max(0.0);
            }
            if d0 < 0.0 || d1 < 0.0 {
                continue;
            }
            let share = if d0 + d1 > 0.0 { d0 / (d0 + d1) } else { 0.0 };
            let distance = distance_to_segment(p, a, b);
            if best.is_none_or(|(d, _)| distance < d) {
                let along = self.starts[i] + share * (self.starts[i + 1] - self.starts[i]);
                best = Some((distance, along));
            }
        }
        match best {
            Some((distance, along)) => (along, distance),
            None => (
                0.0,
                self.line
                    .first()
                    .map_or(0.0, |&a| distance_to_segment(p, a, a)),
            ),
        }
    }
}

/// Which of a list of levels may cover a point: a grid over their bounds, each cell listing in
/// order the levels whose bounds meet it, so a lookup reads a few levels rather than all.
#[derive(Debug, Clone, Default)]
pub struct LevelGrid {
    bounds: Option<Rect>,
    side: usize,
    /// Each cell's levels with their bounds, so a level whose bounds miss a point is passed
    /// over without being read.
    cells: Vec<Vec<(u32, Rect)>>,
}

/// Cells per side of a [`LevelGrid`], at most.
const LEVEL_CELLS: usize = 64;

impl LevelGrid {
    pub fn new(levels: &[Level]) -> LevelGrid {
        let mut all = levels.iter().map(Level::reach);
        let Some(first) = all.next() else {
            return LevelGrid::default();
        };
        let bounds = all.fold(first, |b, l| Rect {
            min: [b.min[0].min(l.min[0]), b.min[1].min(l.min[1])],
            max: [b.max[0].max(l.max[0]), b.max[1].max(l.max[1])],
        });
        let side = ((levels.len() as f64).sqrt().ceil() as usize * 2).clamp(1, LEVEL_CELLS);
        let mut grid = LevelGrid {
            bounds: Some(bounds),
            side,
            cells: vec![Vec::new(); side * side],
        };
        for (k, level) in levels.iter().enumerate() {
            let b = level.reach();
            let (lo, hi) = (grid.index(b.min), grid.index(b.max));
            for row in lo[1]..=hi[1] {
                for column in lo[0]..=hi[0] {
                    grid.cells[row * side + column].push((k as u32, b));
                }
            }
        }
        grid
    }

    /// The cell of `p`, clamped to the grid; monotone in each coordinate, so a level whose
    /// bounds hold `p` is listed in `p`'s cell.
    fn index(&self, p: Point) -> [usize; 2] {
        let Some(bounds) = self.bounds else {
            return [0, 0];
        };
        let side = self.side;
        let at = |axis: usize| {
            let size = (bounds.max[axis] - bounds.min[axis]) / side as f64;
            if size > 0.0 {
                (((p[axis] - bounds.min[axis]) / size).floor().max(0.0) as usize).min(side - 1)
            } else {
                0
            }
        };
        [at(0), at(1)]
    }

    /// The levels that may cover `p` with their bounds, in the order they were given.
    fn near(&self, p: Point) -> &[(u32, Rect)] {
        match self.bounds {
            Some(bounds) if bounds.contains(p) => {
                let [column, row] = self.index(p);
                &self.cells[row * self.side + column]
            }
            _ => &[],
        }
    }

    /// The levels of `levels` (those this grid was made of) that cover `p`, in order.
    pub fn covering<'a>(
        &'a self,
        levels: &'a [Level],
        p: Point,
    ) -> impl Iterator<Item = &'a Level> {
        self.near(p)
            .iter()
            .filter(move |(_, bounds)| bounds.contains(p))
            .map(move |&(k, _)| &levels[k as usize])
            .filter(move |l| l.covers(p))
    }
}

impl Level {
    pub fn new(surface: u32, pieces: Vec<Polygon>, bounds: Rect, rule: Rule) -> Level {
        Level {
            surface,
            pieces,
            bounds,
            rule,
            bound: Bound::Exact,
            cells: OnceLock::new(),
        }
    }

    /// The same area as a floor that belongs to no surface of the feature set (nothing of it
    /// is drawn; it only bounds the ground from below).
    pub fn detached(self) -> Level {
        Level {
            surface: u32::MAX,
            bound: Bound::AtLeast,
            ..self
        }
    }

    /// The same surface with its rule as a floor under the terrain.
    pub fn at_least(self) -> Level {
        Level {
            bound: Bound::AtLeast,
            ..self
        }
    }

    /// The same surface with its rule as a ceiling over the terrain.
    pub fn at_most(self) -> Level {
        Level {
            bound: Bound::AtMost,
            ..self
        }
    }

    /// The box of the points the level may cover: its bounds and the margin of its outline.
    pub fn reach(&self) -> Rect {
        self.bounds.widened(ON_OUTLINE)
    }

    /// True for a point inside piece `k` of the area or on that piece's outline: the area
    /// covers a point where one of its pieces does.
    pub fn piece_covers(&self, k: usize, p: Point) -> bool {
        self.pieces.get(k).is_some_and(|piece| {
            piece.contains(p)
                || piece.rings().any(|ring| {
                    (0..ring.len()).any(|i| on_segment(p, ring[i], ring[(i + 1) % ring.len()]))
                })
        })
    }

    /// True for a point inside the area or on its outline.
    pub fn covers(&self, p: Point) -> bool {
        let cells = self
            .cells
            .get_or_init(|| CellIndex::new(&self.pieces, self.bounds, ON_OUTLINE));
        match cells.cell(p) {
            None | Some(Cell::Outside) => false,
            Some(Cell::Inside) => true,
            // Inside a piece first: most points a level is asked about lie inside it, and
            // need not be measured against the outline.
            Some(Cell::Crossed(segments, near)) => {
                near.iter().any(|&i| self.pieces[i as usize].contains(p))
                    || segments.iter().any(|&(a, b)| on_segment(p, a, b))
            }
        }
    }
}

/// True for `p` within [`ON_OUTLINE`] of the segment from `a` to `b`; a point outside the
/// segment's box widened by that much is not, and is answered without the distance.
fn on_segment(p: Point, a: Point, b: Point) -> bool {
    let outside = |axis: usize| {
        p[axis] < a[axis].min(b[axis]) - ON_OUTLINE || p[axis] > a[axis].max(b[axis]) + ON_OUTLINE
    };
    !outside(0) && !outside(1) && distance_to_segment(p, a, b) <= ON_OUTLINE
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn a_trough_follows_its_profile_across_its_floor_and_rises_beyond() {
        let rule = Rule::Trough {
            stations: Stations::new(&[[0.0, 0.0], [10.0, 0.0]]),
            profile: vec![(0.0, 5.0), (10.0, 15.0)],
            half_width: 1.0,
            rise: 2.0,
        };
        assert!((rule.elevation([5.0, 0.0]) - 10.0).abs() < 1e-12);
        assert!((rule.elevation([5.0, -1.0]) - 10.0).abs() < 1e-12);
        assert!((rule.elevation([5.0, 3.0]) - 14.0).abs() < 1e-12);
        assert!((rule.elevation([2.0, -4.0]) - 13.0).abs() < 1e-12);
    }

    fn square(x: f64, y: f64, size: f64) -> Level {
        let outer = vec![[x, y], [x + size, y], [x + size, y + size], [x, y + size]];
        let bounds = Rect::around(&outer);
        let piece = Polygon {
            outer,
            holes: Vec::new(),
        };
        Level::new(0, vec![piece], bounds, Rule::Level(0.0))
    }

    proptest! {
        #[test]
        fn a_level_grid_finds_the_levels_a_scan_finds_in_the_same_order(
            squares in prop::collection::vec((0.0..1.0f64, 0.0..1.0f64, 0.0..0.3f64), 0..40),
            points in prop::collection::vec((-0.1..1.4f64, -0.1..1.4f64), 1..60),
        ) {
            let levels: Vec<Level> = squares.iter().map(|&(x, y, s)| square(x, y, s)).collect();
            let grid = LevelGrid::new(&levels);
            // The points, and every corner (on the outline, where cells meet).
            let corners = squares.iter().flat_map(|&(x, y, s)| [[x, y], [x + s, y + s]]);
            for p in points.iter().map(|&(x, y)| [x, y]).chain(corners) {
                let scanned: Vec<*const Level> =
                    levels.iter().filter(|l| l.covers(p)).map(|l| l as *const Level).collect();
                let found: Vec<*const Level> =
                    grid.covering(&levels, p).map(|l| l as *const Level).collect();
                prop_assert_eq!(scanned, found, "{:?}", p);
            }
        }

        #[test]
        fn a_level_covers_a_point_where_one_of_its_pieces_does(
            squares in prop::collection::vec((0.0..1.0f64, 0.0..1.0f64, 0.0..0.3f64), 1..12),
            points in prop::collection::vec((-0.1..1.4f64, -0.1..1.4f64), 1..60),
        ) {
            let pieces: Vec<Polygon> = squares
                .iter()
                .flat_map(|&(x, y, s)| square(x, y, s).pieces)
                .collect();
            let bounds = Rect::around_all(&pieces).expect("pieces");
            let level = Level::new(0, pieces, bounds, Rule::Level(0.0));
            // The points, every corner, and points a hair inside and outside each edge.
            let near_edges = squares.iter().flat_map(|&(x, y, s)| {
                [[x - 1e-10, y + s / 2.0], [x + 1e-10, y + s / 2.0], [x + s / 2.0, y + s + 5e-10]]
            });
            let corners = squares.iter().flat_map(|&(x, y, s)| [[x, y], [x + s, y + s]]);
            for p in points.iter().map(|&(x, y)| [x, y]).chain(corners).chain(near_edges) {
                let by_pieces = (0..level.pieces.len()).any(|k| level.piece_covers(k, p));
                prop_assert_eq!(level.covers(p), by_pieces, "{:?}", p);
            }
        }
    }
}
