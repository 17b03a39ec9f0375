//! The ground as elevation settles it: surfaces whose elevation follows a rule instead of the
//! terrain (water lying flat, a cut down to a tunnel's portal, ground raised over a tunnel's
//! roof), and the ground model that puts them together.

use crate::geometry::{distance_to_segment, Point, Polygon, Rect};
use crate::terrain::Elevation;

/// A point this close to a settled surface's outline (global tile units: a few micrometres at zoom
/// 14) takes its rule: vertices on the outline belong to the surface as well as to what is around it.
const ON_OUTLINE: f64 = 1e-9;

/// One surface and the elevation the ground takes on it.
#[derive(Debug, Clone)]
pub struct Level {
    /// The surface's index in its feature set.
    pub surface: u32,
    pub pieces: Vec<Polygon>,
    pub bounds: Rect,
    pub rule: Rule,
    /// The rule is a floor: where the terrain is higher, the terrain stays.
    pub at_least: bool,
    cells: CellIndex,
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
}

impl Rule {
    pub fn elevation(&self, p: Point) -> f64 {
        match self {
            Rule::Level(level) => *level,
            Rule::Along { stations, profile } => {
                let along = stations.at(p);
                let k = profile.partition_point(|&(s, _)| s <= along);
                match (
                    k.checked_sub(1).and_then(|i| profile.get(i)),
                    profile.get(k),
                ) {
                    (Some(&(s0, h0)), Some(&(s1, h1))) if s1 > s0 => {
                        h0 + (h1 - h0) * (along - s0) / (s1 - s0)
                    }
                    (Some(&(_, h)), _) | (None, Some(&(_, h))) => h,
                    (None, None) => 0.0,
                }
            }
        }
    }
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
        best.map_or(0.0, |(_, along)| along)
    }
}

/// Cells per side of the grid that answers "is this point on the water" quickly.
const CELLS: usize = 48;

/// The area's bounds in a grid of cells, each wholly inside, wholly outside, or crossed by
/// the outline (with the segments that cross it).
#[derive(Debug, Clone)]
struct CellIndex {
    bounds: Rect,
    cells: Vec<Cell>,
}

#[derive(Debug, Clone)]
enum Cell {
    Inside,
    Outside,
    /// Segments of the outline near the cell: `(a, b)` pairs.
    Crossed(Vec<(Point, Point)>),
}

impl CellIndex {
    fn new(pieces: &[Polygon], bounds: Rect) -> CellIndex {
        let bounds = Rect {
            min: [bounds.min[0] - ON_OUTLINE, bounds.min[1] - ON_OUTLINE],
            max: [bounds.max[0] + ON_OUTLINE, bounds.max[1] + ON_OUTLINE],
        };
        let size = [
            (bounds.max[0] - bounds.min[0]) / CELLS as f64,
            (bounds.max[1] - bounds.min[1]) / CELLS as f64,
        ];
        let mut crossed: Vec<Vec<(Point, Point)>> = vec![Vec::new(); CELLS * CELLS];
        for ring in pieces.iter().flat_map(Polygon::rings) {
            for i in 0..ring.len() {
                let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
                let span = |axis: usize| {
                    let lo = a[axis].min(b[axis]) - ON_OUTLINE - bounds.min[axis];
                    let hi = a[axis].max(b[axis]) + ON_OUTLINE - bounds.min[axis];
                    let cell = |v: f64| ((v / size[axis]).floor().max(0.0) as usize).min(CELLS - 1);
                    cell(lo)..=cell(hi)
                };
                for row in span(1) {
                    for column in span(0) {
                        crossed[row * CELLS + column].push((a, b));
                    }
                }
            }
        }
        let cells = crossed
            .into_iter()
            .enumerate()
            .map(|(k, segments)| {
                if !segments.is_empty() {
                    return Cell::Crossed(segments);
                }
                // No outline in the cell: its centre tells for all of it.
                let centre = [
                    bounds.min[0] + ((k % CELLS) as f64 + 0.5) * size[0],
                    bounds.min[1] + ((k / CELLS) as f64 + 0.5) * size[1],
                ];
                if pieces.iter().any(|piece| piece.contains(centre)) {
                    Cell::Inside
                } else {
                    Cell::Outside
                }
            })
            .collect();
        CellIndex { bounds, cells }
    }

    fn cell(&self, p: Point) -> Option<&Cell> {
        if !self.bounds.contains(p) {
            return None;
        }
        let index = |axis: usize| {
            let size = (self.bounds.max[axis] - self.bounds.min[axis]) / CELLS as f64;
            (((p[axis] - self.bounds.min[axis]) / size).floor().max(0.0) as usize).min(CELLS - 1)
        };
        self.cells.get(index(1) * CELLS + index(0))
    }
}

impl Level {
    pub fn new(surface: u32, pieces: Vec<Polygon>, bounds: Rect, rule: Rule) -> Level {
        let cells = CellIndex::new(&pieces, bounds);
        Level {
            surface,
            pieces,
            bounds,
            rule,
            at_least: false,
            cells,
        }
    }

    /// The same area as a floor that belongs to no surface of the feature set (nothing of it
    /// is drawn; it only bounds the ground from below).
    pub fn detached(self) -> Level {
        Level {
            surface: u32::MAX,
            at_least: true,
            ..self
        }
    }

    /// The same surface with its rule as a floor under the terrain.
    pub fn at_least(self) -> Level {
        Level {
            at_least: true,
            ..self
        }
    }

    /// True for a point inside the area or on its outline.
    pub fn covers(&self, p: Point) -> bool {
        match self.cells.cell(p) {
            None | Some(Cell::Outside) => false,
            Some(Cell::Inside) => true,
            Some(Cell::Crossed(segments)) => {
                segments
                    .iter()
                    .any(|&(a, b)| distance_to_segment(p, a, b) <= ON_OUTLINE)
                    || self.pieces.iter().any(|piece| piece.contains(p))
            }
        }
    }
}

/// Puts every vertex of a settled surface's triangles at its rule's elevation (the lowest,
/// where surfaces meet): the outline's vertices already are, and this catches a vertex the
/// triangulation attached to the surface from just outside its outline. Vertices on the tile's
/// edges stay as the ground model settled them (identically in both tiles). Floors
/// ([`Level::at_least`]) are left to the ground model.
pub fn flatten(
    ground: &mut crate::mesh::ground::Ground,
    levels: &[&Level],
    frame: &crate::tile::TileFrame,
) {
    let size_m = frame.size_m;
    let rule_of: std::collections::HashMap<u32, &Rule> = levels
        .iter()
        .filter(|l| !l.at_least)
        .map(|l| (l.surface, &l.rule))
        .collect();
    let on_edge = |p: Point| p[0] == 0.0 || p[1] == 0.0 || p[0] == size_m || p[1] == size_m;
    let mut settled: Vec<Option<f64>> = vec![None; ground.vertices.len()];
    for triangle in &ground.triangles {
        let Some(rule) = triangle.surface.and_then(|s| rule_of.get(&s)) else {
            continue;
        };
        for &vertex in &triangle.vertices {
            let [x, z] = ground.vertices[vertex as usize];
            let (u, v) = frame.local_to_uv(x, z);
            let level = rule.elevation([u, v]);
            let slot = &mut settled[vertex as usize];
            *slot = Some(slot.map_or(level, |l: f64| l.min(level)));
        }
    }
    let floors: Vec<&&Level> = levels.iter().filter(|l| l.at_least).collect();
    for (v, level) in settled.into_iter().enumerate() {
        if let Some(level) = level {
            let [x, z] = ground.vertices[v];
            let (u, w) = frame.local_to_uv(x, z);
            let raised = floors.iter().any(|f| f.covers([u, w]));
            if !on_edge(ground.vertices[v]) && !raised {
                ground.elevations[v] = level;
            }
        }
    }
}

/// The ground: the terrain, with water areas flat at their levels and the ground reshaped
/// around bridges and tunnels.
pub struct Ground<'a> {
    pub terrain: &'a dyn Elevation,
    pub water: &'a [Level],
    /// Where tunnels cut into the ground or run under raised ground.
    pub cuts: &'a [Level],
}

impl Elevation for Ground<'_> {
    fn elevation_uv(&self, p: [f64; 2]) -> f64 {
        // Where water areas overlap, the lowest level wins.
        let water = self
            .water
            .iter()
            .filter(|w| w.covers(p))
            .map(|w| w.rule.elevation(p))
            .fold(None, |low: Option<f64>, l| {
                Some(low.map_or(l, |x| x.min(l)))
            });
        if let Some(level) = water {
            return level;
        }
        // Ground raised over a tunnel's roof wins over another way's cut beside it (two
        // carriageways whose portals are not abreast), so no tube shows through.
        let mut cut: Option<f64> = None;
        let mut raised: Option<f64> = None;
        for level in self.cuts.iter().filter(|c| c.covers(p)) {
            let h = level.rule.elevation(p);
            if level.at_least {
                raised = Some(raised.map_or(h, |r: f64| r.max(h)));
            } else if cut.is_none() {
                cut = Some(h);
            }
        }
        match (raised, cut) {
            (Some(raised), _) => raised.max(self.terrain.elevation_uv(p)),
            (None, Some(cut)) => cut,
            (None, None) => self.terrain.elevation_uv(p),
        }
    }
}
