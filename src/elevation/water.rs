//! Water surfaces lie flat, no higher than their shore (thesis §4.2; its figure 4.8 shows a lake
//! above its banks).
//!
//! The level of a water area is the lowest ground along its whole outline, sampled every
//! [`SHORE_STEP_M`] from its first vertex: a function of the whole OSM area and the terrain
//! alone, so every tile that shows the water computes the same level, and the shore (where the
//! outline's vertices take the level) is never below it. The sea lies at 0 m. A waterway drawn
//! at its width is not flattened (it runs downhill).

use crate::features::{FeatureClass, FeatureSet, Surface};
use crate::geometry::{distance_to_segment, Point, Polygon, Rect};
use crate::terrain::Elevation;

/// Spacing of the samples along a water area's outline, metres.
pub const SHORE_STEP_M: f64 = 5.0;

/// A point this close to a water area's outline (global tile units: a few micrometres at zoom
/// 14) takes its level: vertices on the outline belong to the water as well as to the shore.
const ON_OUTLINE: f64 = 1e-9;

/// One flat water area.
#[derive(Debug, Clone)]
pub struct WaterLevel {
    pub feature: u32,
    pub pieces: Vec<Polygon>,
    pub bounds: Rect,
    /// Metres above sea level.
    pub level: f64,
    cells: CellIndex,
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
    pub fn new(feature: u32, pieces: Vec<Polygon>, bounds: Rect, level: f64) -> WaterLevel {
        let cells = CellIndex::new(&pieces, bounds);
        WaterLevel {
            feature,
            pieces,
            bounds,
            level,
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
            if tags.is_set("waterway") {
                return None;
            }
            let level = if tags.get("natural") == Some("sea") {
                0.0
            } else {
                shore_minimum(surface, terrain, metres_per_unit)?
            };
            Some(WaterLevel::new(
                surface.feature,
                surface.pieces.clone(),
                surface.bounds,
                level,
            ))
        })
        .collect()
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

/// Puts every vertex of a water area's triangles at its level: the outline's vertices already
/// are, and this catches a vertex the triangulation attached to the water from just outside its
/// outline. Vertices on the tile's edges stay as the terrain model settled them (identically in
/// both tiles). `size_m` is the tile's size in local metres.
pub fn flatten(
    ground: &mut crate::mesh::ground::Ground,
    surfaces: &[Surface],
    water: &[WaterLevel],
    size_m: f64,
) {
    let level_of: std::collections::HashMap<u32, f64> =
        water.iter().map(|w| (w.feature, w.level)).collect();
    let on_edge = |p: Point| p[0] == 0.0 || p[1] == 0.0 || p[0] == size_m || p[1] == size_m;
    let mut settled: Vec<Option<f64>> = vec![None; ground.vertices.len()];
    for triangle in &ground.triangles {
        let Some(surface) = triangle.surface.and_then(|s| surfaces.get(s as usize)) else {
            continue;
        };
        let Some(&level) = level_of.get(&surface.feature) else {
            continue;
        };
        for &v in &triangle.vertices {
            let slot = &mut settled[v as usize];
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
            .map(|w| w.level)
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
        assert!((water[0].level - 10.0).abs() < 1e-9, "{}", water[0].level);
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
}
