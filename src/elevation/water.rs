//! Water surfaces lie flat, no higher than their shore (thesis §4.2; its figure 4.8 shows a lake
//! above its banks), and waterways never flow uphill.
//!
//! The level of a water area is the lowest ground along its whole outline, sampled every
//! [`SHORE_STEP_M`] from its first vertex: a function of the whole OSM area and the terrain
//! alone, so every tile that shows the water computes the same level, and the shore (where the
//! outline's vertices take the level) is never below it. The sea lies at 0 m. A waterway drawn
//! at its width follows the lowest ground met so far along its whole way (sampled as often),
//! level across each station, so its water only ever runs down.

use crate::features::{FeatureClass, FeatureSet, Surface};
use crate::geometry::{distance_to_segment, Point, Polygon, Rect};
use crate::terrain::Elevation;

/// Spacing of the samples along a water area's outline, metres.
pub const SHORE_STEP_M: f64 = 5.0;

/// A point this close to a water area's outline (global tile units: a few micrometres at zoom
/// 14) takes its level: vertices on the outline belong to the water as well as to the shore.
const ON_OUTLINE: f64 = 1e-9;

/// One water surface and the elevation its water takes.
#[derive(Debug, Clone)]
pub struct WaterLevel {
    pub feature: u32,
    pub pieces: Vec<Polygon>,
    pub bounds: Rect,
    pub rule: Rule,
    cells: CellIndex,
}

/// The elevation of a water surface.
#[derive(Debug, Clone, PartialEq)]
pub enum Rule {
    /// Flat, metres above sea level.
    Level(f64),
    /// Down a waterway: the profile's elevation at the point's station along its line.
    Downstream {
        stations: Stations,
        /// Distance along the line (tile units) and elevation, never increasing.
        profile: Vec<(f64, f64)>,
    },
}

impl Rule {
    pub fn elevation(&self, p: Point) -> f64 {
        match self {
            Rule::Level(level) => *level,
            Rule::Downstream { stations, profile } => {
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

impl WaterLevel {
    pub fn new(feature: u32, pieces: Vec<Polygon>, bounds: Rect, rule: Rule) -> WaterLevel {
        let cells = CellIndex::new(&pieces, bounds);
        WaterLevel {
            feature,
            pieces,
            bounds,
            rule,
            cells,
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

/// The water areas of a feature set with their levels; `metres_per_unit` is the tile's size.
pub fn levels(set: &FeatureSet, terrain: &dyn Elevation, metres_per_unit: f64) -> Vec<WaterLevel> {
    set.surfaces
        .iter()
        .filter(|s| s.class == FeatureClass::Water)
        .filter_map(|surface| {
            let tags = &set.features[surface.feature as usize].tags;
            let rule = if tags.is_set("waterway") {
                downstream(&surface.centreline, terrain, metres_per_unit)?
            } else if tags.get("natural") == Some("sea") {
                Rule::Level(0.0)
            } else {
                Rule::Level(shore_minimum(surface, terrain, metres_per_unit)?)
            };
            Some(WaterLevel::new(
                surface.feature,
                surface.pieces.clone(),
                surface.bounds,
                rule,
            ))
        })
        .collect()
}

/// The lowest ground met so far along a waterway's line, sampled every [`SHORE_STEP_M`].
fn downstream(line: &[Point], terrain: &dyn Elevation, metres_per_unit: f64) -> Option<Rule> {
    if line.len() < 2 {
        return None;
    }
    let step = SHORE_STEP_M / metres_per_unit;
    let mut profile: Vec<(f64, f64)> = Vec::new();
    let mut start = 0.0;
    let mut lowest = f64::INFINITY;
    let mut sample = |along: f64, p: Point, profile: &mut Vec<(f64, f64)>| {
        lowest = lowest.min(terrain.elevation_uv(p));
        profile.push((along, lowest));
    };
    for pair in line.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let length = (b[0] - a[0]).hypot(b[1] - a[1]);
        let steps = (length / step).ceil().max(1.0) as usize;
        for k in 0..steps {
            let t = k as f64 / steps as f64;
            let p = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
            sample(start + t * length, p, &mut profile);
        }
        start += length;
    }
    let end = line[line.len() - 1];
    sample(start, end, &mut profile);
    Some(Rule::Downstream {
        stations: Stations::new(line),
        profile,
    })
}

/// The lowest ground along the rings of a surface's pieces.
fn shore_minimum(surface: &Surface, terrain: &dyn Elevation, metres_per_unit: f64) -> Option<f64> {
    let step = SHORE_STEP_M / metres_per_unit;
    let mut lowest: Option<f64> = None;
    for ring in surface.pieces.iter().flat_map(Polygon::rings) {
        for i in 0..ring.len() {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            let length = (b[0] - a[0]).hypot(b[1] - a[1]);
            let steps = (length / step).ceil().max(1.0) as usize;
            for k in 0..steps {
                let t = k as f64 / steps as f64;
                let h = terrain.elevation_uv([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
                lowest = Some(lowest.map_or(h, |l: f64| l.min(h)));
            }
        }
    }
    lowest
}

/// Puts every vertex of a water surface's triangles at the water's elevation: the outline's
/// vertices already are, and this catches a vertex the triangulation attached to the water from
/// just outside its outline. Vertices on the tile's edges stay as the ground model settled them
/// (identically in both tiles).
pub fn flatten(
    ground: &mut crate::mesh::ground::Ground,
    surfaces: &[Surface],
    water: &[WaterLevel],
    frame: &crate::tile::TileFrame,
) {
    let size_m = frame.size_m;
    let rule_of: std::collections::HashMap<u32, &Rule> =
        water.iter().map(|w| (w.feature, &w.rule)).collect();
    let on_edge = |p: Point| p[0] == 0.0 || p[1] == 0.0 || p[0] == size_m || p[1] == size_m;
    let mut settled: Vec<Option<f64>> = vec![None; ground.vertices.len()];
    for triangle in &ground.triangles {
        let Some(surface) = triangle.surface.and_then(|s| surfaces.get(s as usize)) else {
            continue;
        };
        let Some(rule) = rule_of.get(&surface.feature) else {
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
    for (v, level) in settled.into_iter().enumerate() {
        if let Some(level) = level {
            if !on_edge(ground.vertices[v]) {
                ground.elevations[v] = level;
            }
        }
    }
}

/// The ground: the terrain, with water areas flat at their levels.
pub struct Ground<'a> {
    pub terrain: &'a dyn Elevation,
    pub water: &'a [WaterLevel],
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
        water.unwrap_or_else(|| self.terrain.elevation_uv(p))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Ground rising eastwards: one metre per hundredth of a unit.
    struct Slope;
    impl Elevation for Slope {
        fn elevation_uv(&self, p: [f64; 2]) -> f64 {
            p[0] * 100.0
        }
    }

    #[test]
    fn a_pond_on_a_slope_lies_flat_at_its_lowest_shore() {
        let pond = Polygon {
            outer: vec![[0.10, 0.10], [0.20, 0.10], [0.20, 0.20], [0.10, 0.20]],
            holes: Vec::new(),
        };
        let mut set = FeatureSet::default();
        let tags = crate::osm::Tags::from_pairs([("natural", "water")]);
        let feature = set.add_feature(None, FeatureClass::Water, &tags);
        set.surfaces.push(
            Surface::from_polygons(FeatureClass::Water, feature, vec![pond]).expect("a surface"),
        );
        let water = levels(&set, &Slope, 1000.0);
        assert_eq!(water.len(), 1);
        assert_eq!(water[0].rule, Rule::Level(10.0));
        let ground = Ground {
            terrain: &Slope,
            water: &water,
        };
        // Flat inside and on the outline (the high side too), the terrain outside.
        for p in [[0.15, 0.15], [0.2, 0.15], [0.1, 0.1], [0.2, 0.2]] {
            assert!((ground.elevation_uv(p) - 10.0).abs() < 1e-9, "{p:?}");
        }
        assert!((ground.elevation_uv([0.3, 0.15]) - 30.0).abs() < 1e-9);
        // The terrain along the shore is nowhere below the water; beyond it, the ground is the
        // terrain's.
        for k in 0..=40 {
            let t = 0.1 + 0.1 * f64::from(k) / 40.0;
            for p in [[t, 0.1], [t, 0.2], [0.1, t], [0.2, t]] {
                assert!(Slope.elevation_uv(p) >= 10.0 - 1e-9, "{p:?}");
            }
        }
        assert_eq!(
            ground.elevation_uv([0.095, 0.15]),
            Slope.elevation_uv([0.095, 0.15])
        );
    }

    #[test]
    fn a_waterway_never_runs_uphill() {
        // A stream drawn eastwards up the slope, round two right-angle bends, then back west
        // down it.
        let line = vec![[0.10, 0.5], [0.30, 0.5], [0.30, 0.7], [0.05, 0.7]];
        let rule = downstream(&line, &Slope, 1000.0).expect("a profile");
        let Rule::Downstream { profile, .. } = &rule else {
            panic!("{rule:?}");
        };
        assert!(profile
            .windows(2)
            .all(|w| w[1].1 <= w[0].1 && w[1].0 >= w[0].0));
        // Level at its source's height up the slope, then down with the ground.
        assert!((rule.elevation([0.25, 0.5]) - 10.0).abs() < 1e-9);
        let back = rule.elevation([0.06, 0.7]);
        assert!((back - 6.0).abs() < 0.5, "{back}");
        // Along the water, never up: on both banks, and round the bends' insides.
        for bank in [-0.01, 0.01] {
            let mut last = f64::INFINITY;
            for k in 0..=100 {
                let t = f64::from(k) / 100.0 * 0.65;
                let p = if t < 0.2 {
                    [0.1 + t, 0.5 + bank]
                } else if t < 0.4 {
                    [0.3 - bank, 0.5 + (t - 0.2)]
                } else {
                    [0.3 - (t - 0.4), 0.7 - bank]
                };
                let h = rule.elevation(p);
                assert!(h <= last + 1e-9, "{p:?}: {h} after {last}");
                last = h;
            }
        }
        // The station runs on without a step through the inside of a bend.
        let inside = [0.29, 0.51];
        let stations = Stations::new(&line);
        let (a, b) = (stations.at([0.29, 0.509]), stations.at(inside));
        assert!((a - b).abs() < 0.005, "{a} {b}");
    }
}
