//! The features of a tile coarser than the served zoom (a parent of the 3D Tiles hierarchy, seen
//! from afar): what such a view shows, generalised to the tile's own scale.
//!
//! * every line and ring is simplified to the level's tolerance (a 1,024th of the tile's ground
//!   size) before the feature families read it, so a way is simplified alike in every tile it
//!   crosses, and neighbours' edges meet where its outline crosses them;
//! * land cover and water areas and rivers, as at the served zoom, without the areas smaller
//!   than the level can show; the sea decided from the coastline over the part of the tile the
//!   OSM data covers, as a served-zoom tile decides its own (the union of the seas the
//!   served-zoom tiles under it find where the extract cuts a coastline open inside that part);
//! * major roads and railways (fewer classes the coarser the level), widened to at least one and
//!   a half tolerances so they stay visible, draped on the ground;
//! * buildings merged into blocks: the footprints of one height band are closed (grown by a
//!   tolerance and shrunk back) so buildings nearer each other than two tolerances join, then
//!   simplified; a block keeps the mean height of its buildings (weighted by area), has a flat
//!   roof and is drawn by the one tile that owns the centre of its bounds.
//!
//! Left out: minor roads, paths, tunnels, bridges' structures, trees, objects, barriers, power
//! lines, steps. Coarser than [`BLOCKS_UP_TO`] levels above the served zoom, no buildings.

use geo::algorithm::buffer::{BufferStyle, LineJoin};
use geo::{Area as _, Buffer, SimplifyVwPreserve};

use super::buildings;
use super::{
    areas_of, coastline, landcover, railways, roads, tile_rect, water, widened_surface, Area,
    BuildingShape, FeatureClass, FeatureSet, FeatureSettings, Projection,
};
use crate::geometry::{Point, Polygon, Rect};
use crate::osm::index::Selection;
use crate::osm::{ElementRef, ElementType, Tags, Way};
use crate::tile::{LonLatBounds, TileId};

/// Buildings are drawn as blocks up to this many levels above the served zoom.
pub const BLOCKS_UP_TO: u8 = 4;
/// Fraction of a tile's ground size that its lines are simplified to.
const TOLERANCE_PER_TILE: f64 = 1.0 / 1024.0;
/// Roads and railways are drawn at least this many tolerances wide.
const MIN_WIDTH_TOLERANCES: f64 = 1.5;
/// Areas smaller than a square this many tolerances wide are left out.
const MIN_AREA_TOLERANCES: f64 = 8.0;
/// Blocks smaller than a square this many tolerances wide are left out.
const MIN_BLOCK_TOLERANCES: f64 = 3.0;
/// The upper bounds of the height bands buildings merge within, metres.
const HEIGHT_BANDS_M: [f64; 4] = [12.0, 24.0, 48.0, 96.0];

/// How far a tile is generalised.
#[derive(Debug, Clone, Copy)]
pub struct Level {
    pub tile: TileId,
    /// Zooms between the tile and the served zoom (at least one).
    pub levels_above: u8,
    /// The box of the OSM data over the tile: a coarse tile reaches past its extracts, and
    /// where the data ends nothing is known, not even which side of the coast it is.
    pub data: Option<LonLatBounds>,
}

impl Level {
    /// The level of `tile` when the served zoom is `served_zoom` and the OSM data covers the
    /// boxes of `coverage`.
    pub fn new(tile: TileId, served_zoom: u8, coverage: &[LonLatBounds]) -> Level {
        let bounds = tile.bounds();
        let data = coverage
            .iter()
            .filter(|c| c.intersects(&bounds))
            .copied()
            .reduce(|a, b| LonLatBounds {
                west: a.west.min(b.west),
                south: a.south.min(b.south),
                east: a.east.max(b.east),
                north: a.north.max(b.north),
            });
        Level {
            tile,
            levels_above: served_zoom.saturating_sub(tile.z).max(1),
            data,
        }
    }

    /// The part of the tile (and a little past it) where the sea can be known, in global tile
    /// units: the tile's square grown as at the served zoom, cut to the data's box.
    fn sea_rect(&self, projection: &Projection) -> Option<Rect> {
        let data = self.data?;
        let corner = |lon: f64, lat: f64| projection.point(crate::osm::LonLat { lon, lat });
        let [west, north] = corner(data.west, data.north);
        let [east, south] = corner(data.east, data.south);
        let tile = tile_rect(self.tile);
        let margin = super::SEA_BEYOND;
        let rect = Rect {
            min: [
                (tile.min[0] - margin).max(west),
                (tile.min[1] - margin).max(north),
            ],
            max: [
                (tile.max[0] + margin).min(east),
                (tile.max[1] + margin).min(south),
            ],
        };
        (rect.min[0] < rect.max[0] && rect.min[1] < rect.max[1]).then_some(rect)
    }

    /// The simplification tolerance, in global tile units at the tile's zoom.
    pub fn tolerance_uv(&self) -> f64 {
        TOLERANCE_PER_TILE
    }

    /// The road classes drawn at this level.
    fn draws_road(&self, highway: &str) -> bool {
        let base = highway.strip_suffix("_link").unwrap_or(highway);
        let rank = match base {
            "motorway" | "trunk" => 0,
            "primary" => 1,
            "secondary" => 2,
            "tertiary" => 3,
            _ => return false,
        };
        let coarsest = match self.levels_above {
            1 => 3,
            2 | 3 => 2,
            4 | 5 => 1,
            _ => 0,
        };
        rank <= coarsest
    }
}

/// The generalised features of `level`'s tile.
pub fn collect(selection: &Selection<'_>, level: Level, settings: &FeatureSettings) -> FeatureSet {
    let tile = level.tile;
    let projection = Projection::new(tile.z);
    let mut set = FeatureSet::default();
    set.add_feature(None, FeatureClass::Terrain, &Tags::default());

    let simplified = simplify_ways(&selection.ways, &projection, level.tolerance_uv());
    let coastlines = simplify_ways(&selection.coastlines, &projection, level.tolerance_uv());
    let generalised = Selection {
        ways: simplified.iter().collect(),
        relations: selection.relations.clone(),
        coastlines: coastlines.iter().collect(),
        ..Selection::default()
    };
    let min_area = (MIN_AREA_TOLERANCES * level.tolerance_uv()).powi(2);
    for way in &generalised.ways {
        add_line(&mut set, way, &projection, level, settings);
    }
    for area in areas_of(&generalised) {
        water::add_area(&mut set, &area, &projection);
        landcover::add_area(&mut set, &area, &projection);
    }
    drop_small_pieces(&mut set, min_area);
    // As at the served zoom: outlines just across an edge weigh the terrain error there too.
    set.nearby_outlines = set.weighing_outlines();
    add_sea(&mut set, &generalised, level, &projection);
    water::drop_waterways_in_water_areas(&mut set);
    if level.levels_above <= BLOCKS_UP_TO {
        add_blocks(&mut set, &areas_of(selection), &projection, level, settings);
    }
    set.retain_touching(&tile_rect(tile));
    set
}

/// The sea of the tile, decided over the part of it the data covers as a served-zoom tile
/// decides its own: from the coastline across the whole of it. Where the extract cuts a
/// coastline open inside that part (its end lies inside, so no side of it is known there), the
/// sea is instead the union of the seas the served-zoom tiles under it find, each decided as
/// that tile decides it, so the open end only misleads the cells near it. The coast's runs are
/// the outline.
fn add_sea(set: &mut FeatureSet, selection: &Selection<'_>, level: Level, projection: &Projection) {
    let Some(rect) = level.sea_rect(projection) else {
        return;
    };
    let project = |way: &Way| projection.points(&way.positions);
    let near_ways: Vec<&Way> = selection
        .ways
        .iter()
        .copied()
        .filter(|w| coastline::is_coastline(w))
        .collect();
    let near = coastline::chains(&near_ways, &project);
    if near.is_empty() && selection.coastlines.is_empty() {
        return;
    }
    let all = coastline::chains(&selection.coastlines, &project);
    let tile = tile_rect(level.tile);
    let strictly_inside = |p: &Point| (0..2).all(|k| rect.min[k] < p[k] && p[k] < rect.max[k]);
    let cut_open_inside = near.iter().any(|c| {
        !c.closed
            && (c.points.first().is_some_and(strictly_inside)
                || c.points.last().is_some_and(strictly_inside))
    });
    let (pieces, mut coast) = if cut_open_inside {
        sea_by_cells(&near, &all, rect, level)
    } else {
        let sea = coastline::sea(&near, &|| all.clone(), &rect);
        (sea.polygons, sea.coast)
    };
    set.nearby_outlines
        .extend(near.into_iter().map(|c| c.points));
    if pieces.is_empty() {
        return;
    }
    // Where the data ends inside the tile, the sea ends along it: the sides of its pieces there.
    coast.extend(sides_on(&pieces, &data_edges(&rect, &tile)));
    let tags = Tags::from_pairs([("natural", "sea")]);
    let feature = set.add_feature(None, FeatureClass::Water, &tags);
    match super::Surface::from_parts(FeatureClass::Water, feature, pieces, coast) {
        Some(mut surface) => {
            surface.water = Some(water::WaterBody::of(&tags));
            set.surfaces.push(surface);
        }
        None => {
            set.features.pop();
        }
    }
}

/// The sea of `rect` as the union of the seas of the served-zoom tiles under `level`'s tile
/// (each cell decided alone, the first and last of a row or column reaching out to `rect`),
/// cells wholly at sea along a row joined into one piece; and the coast's runs.
fn sea_by_cells(
    near: &[coastline::Chain],
    all: &[coastline::Chain],
    rect: Rect,
    level: Level,
) -> (Vec<Polygon>, Vec<Vec<Point>>) {
    let near_bounds: Vec<Rect> = near.iter().map(|c| Rect::around(&c.points)).collect();
    let cells = 1u32 << level.levels_above.min(MAX_SEA_LEVELS);
    let tile = tile_rect(level.tile);
    let mut pieces: Vec<Polygon> = Vec::new();
    let mut coast: Vec<Vec<Point>> = Vec::new();
    for row in 0..cells {
        // A run of cells wholly at sea, joined as it grows: (first cell's min u, last's max u).
        let mut open_run: Option<Rect> = None;
        for column in 0..cells {
            let (u0, u1) = cell_span(column, cells, tile.min[0], rect.min[0], rect.max[0]);
            let (v0, v1) = cell_span(row, cells, tile.min[1], rect.min[1], rect.max[1]);
            let cell = Rect {
                min: [u0, v0],
                max: [u1, v1],
            };
            if cell.min[0] >= cell.max[0] || cell.min[1] >= cell.max[1] {
                continue;
            }
            let crossing: Vec<coastline::Chain> = near
                .iter()
                .zip(&near_bounds)
                .filter(|(_, b)| b.intersects(&cell))
                .map(|(c, _)| c.clone())
                .collect();
            let sea = coastline::sea(&crossing, &|| all.to_vec(), &cell);
            coast.extend(sea.coast);
            let whole = sea.polygons.len() == 1
                && sea.polygons[0].holes.is_empty()
                && (sea.polygons[0].area() - area_of(&cell)).abs() <= 1e-12 * area_of(&cell);
            if whole {
                open_run = Some(match open_run {
                    Some(run) if run.max[0] == cell.min[0] && run.min[1] == cell.min[1] => Rect {
                        min: run.min,
                        max: [cell.max[0], run.max[1].max(cell.max[1])],
                    },
                    Some(run) => {
                        pieces.push(rectangle(&run));
                        cell
                    }
                    None => cell,
                });
                continue;
            }
            if let Some(run) = open_run.take() {
                pieces.push(rectangle(&run));
            }
            pieces.extend(sea.polygons);
        }
        if let Some(run) = open_run.take() {
            pieces.push(rectangle(&run));
        }
    }
    (pieces, coast)
}

/// Sea cells along one axis at most this many levels below the tile (a 64 × 64 grid).
const MAX_SEA_LEVELS: u8 = 6;

/// Cell `k` of `cells` along one axis of a tile starting at `start` (one unit long), the first
/// and last reaching out to `low` and `high` (the tile's margin), cut to `low..high`.
fn cell_span(k: u32, cells: u32, start: f64, low: f64, high: f64) -> (f64, f64) {
    let step = 1.0 / f64::from(cells);
    let from = if k == 0 {
        low
    } else {
        start + f64::from(k) * step
    };
    let to = if k + 1 == cells {
        high
    } else {
        start + f64::from(k + 1) * step
    };
    (from.max(low), to.min(high))
}

fn area_of(rect: &Rect) -> f64 {
    (rect.max[0] - rect.min[0]) * (rect.max[1] - rect.min[1])
}

fn rectangle(rect: &Rect) -> Polygon {
    Polygon {
        outer: vec![
            rect.min,
            [rect.max[0], rect.min[1]],
            rect.max,
            [rect.min[0], rect.max[1]],
        ],
        holes: Vec::new(),
    }
}

/// Where the data ends inside `tile`: the lines `u = c` (first) and `v = c` (second) of the
/// sides of `rect` that cross the tile's inside.
fn data_edges(rect: &Rect, tile: &Rect) -> (Vec<f64>, Vec<f64>) {
    let inside = |c: f64, axis: usize| tile.min[axis] < c && c < tile.max[axis];
    let u = [rect.min[0], rect.max[0]]
        .into_iter()
        .filter(|&c| inside(c, 0))
        .collect();
    let v = [rect.min[1], rect.max[1]]
        .into_iter()
        .filter(|&c| inside(c, 1))
        .collect();
    (u, v)
}

/// The sides of the pieces' rings that lie on the lines `edges`, each as a segment.
fn sides_on(pieces: &[Polygon], (u, v): &(Vec<f64>, Vec<f64>)) -> Vec<Vec<Point>> {
    let mut sides = Vec::new();
    for ring in pieces.iter().flat_map(|p| p.rings()) {
        for (k, &a) in ring.iter().enumerate() {
            let b = ring[(k + 1) % ring.len()];
            let on_u = a[0] == b[0] && u.contains(&a[0]);
            let on_v = a[1] == b[1] && v.contains(&a[1]);
            if (on_u || on_v) && a != b {
                sides.push(vec![a, b]);
            }
        }
    }
    sides
}

/// The ways with their lines simplified (Ramer–Douglas–Peucker on the projected points, ends
/// kept); buildings are left out (they become blocks from the ways as mapped).
fn simplify_ways(ways: &[&Way], projection: &Projection, tolerance: f64) -> Vec<Way> {
    ways.iter()
        .filter(|w| !buildings::is_building(&w.tags) && !buildings::is_building_part(&w.tags))
        .map(|way| {
            let points = projection.points(&way.positions);
            let kept = crate::geometry::simplified_indices(&points, tolerance);
            Way {
                id: way.id,
                tags: way.tags.clone(),
                nodes: kept.iter().map(|&i| way.nodes[i]).collect(),
                positions: kept.iter().map(|&i| way.positions[i]).collect(),
            }
        })
        .collect()
}

/// A major road, a railway or a river, widened to at least the level's smallest width.
fn add_line(
    set: &mut FeatureSet,
    way: &Way,
    projection: &Projection,
    level: Level,
    settings: &FeatureSettings,
) {
    if way.positions.len() < 2 || super::structures::is_off_ground(&way.tags) || is_area(&way.tags)
    {
        return;
    }
    let (class, width) = if let Some(highway) = way.tags.get("highway") {
        if !level.draws_road(highway) {
            return;
        }
        (FeatureClass::Road, roads::width_m(&way.tags, settings))
    } else if let Some(railway) = way.tags.get("railway") {
        if !matches!(railway, "rail" | "light_rail" | "narrow_gauge") {
            return;
        }
        let width = railways::width_m(way.tags.get("gauge"), false);
        (FeatureClass::Railway, Some(width))
    } else if matches!(way.tags.get("waterway"), Some("river" | "canal")) {
        water::add_waterway(set, way, projection);
        return;
    } else {
        return;
    };
    let Some(width) = width else {
        return;
    };
    let line = projection.points(&way.positions);
    let min_width = MIN_WIDTH_TOLERANCES * level.tolerance_uv();
    let half_width = projection
        .metres(width / 2.0, way.positions[0].lat)
        .max(min_width / 2.0);
    let element = ElementRef {
        element_type: ElementType::Way,
        id: way.id,
    };
    let feature = set.add_feature(Some(element), class, &way.tags);
    match widened_surface(class, feature, &line, half_width) {
        Some(mut surface) => {
            if class == FeatureClass::Road {
                surface.paving = Some(roads::Paving::from_tags(&way.tags));
            }
            set.surfaces.push(surface);
        }
        None => {
            set.features.pop();
        }
    }
}

fn is_area(tags: &Tags) -> bool {
    tags.get("area") == Some("yes")
}

/// Leaves out the area pieces smaller than `min_area` (tile units squared), and the surfaces
/// left without pieces; surfaces drawn along a line keep theirs.
fn drop_small_pieces(set: &mut FeatureSet, min_area: f64) {
    set.surfaces.retain_mut(|surface| {
        if !surface.centreline.is_empty()
            || !matches!(surface.class, FeatureClass::Water | FeatureClass::LandCover)
        {
            return true;
        }
        let before = surface.pieces.len();
        surface.pieces.retain(|p| p.area() >= min_area);
        if surface.pieces.len() == before {
            return true;
        }
        if surface.pieces.is_empty() {
            return false;
        }
        surface.outline = surface
            .pieces
            .iter()
            .flat_map(|p| p.rings())
            .map(|ring| {
                let mut closed = ring.clone();
                closed.push(ring[0]);
                closed
            })
            .collect();
        surface.bounds = Rect::around_all(&surface.pieces).unwrap_or(surface.bounds);
        true
    });
}

/// A building footprint with the height it stands to.
struct Footprint {
    polygon: Polygon,
    height_m: f64,
    area: f64,
    centre: Point,
}

/// Adds the blocks the tile owns, built from the buildings of `areas`.
fn add_blocks(
    set: &mut FeatureSet,
    areas: &[Area<'_>],
    projection: &Projection,
    level: Level,
    settings: &FeatureSettings,
) {
    let mut bands: Vec<Vec<Footprint>> = (0..=HEIGHT_BANDS_M.len()).map(|_| Vec::new()).collect();
    for area in areas {
        if !buildings::is_building(area.tags) {
            continue;
        }
        let (height_m, _) = buildings::height_m(area.tags, settings);
        let band = HEIGHT_BANDS_M
            .iter()
            .position(|&top| height_m < top)
            .unwrap_or(HEIGHT_BANDS_M.len());
        for polygon in area.polygons.iter().filter_map(|p| projection.polygon(p)) {
            let bounds = polygon.bounds();
            bands[band].push(Footprint {
                area: polygon.area(),
                centre: centre_of(&bounds),
                polygon,
                height_m,
            });
        }
    }
    let tile = tile_rect(level.tile);
    let tags = Tags::from_pairs([("building", "block")]);
    for footprints in bands.iter().filter(|b| !b.is_empty()) {
        for (outline, height_m) in blocks_of(footprints, level.tolerance_uv()) {
            if !tile.owns(centre_of(&outline.bounds())) {
                continue;
            }
            let feature = set.add_feature(None, FeatureClass::Building, &tags);
            set.buildings
                .push(block_shape(feature, outline, height_m, settings));
        }
    }
}

fn centre_of(rect: &Rect) -> Point {
    [
        (rect.min[0] + rect.max[0]) / 2.0,
        (rect.min[1] + rect.max[1]) / 2.0,
    ]
}

/// A flat-roofed block standing on its lowest ground.
fn block_shape(
    feature: u32,
    footprint: Polygon,
    height_m: f64,
    settings: &FeatureSettings,
) -> BuildingShape {
    let flat = Tags::from_pairs([("roof:shape", "flat")]);
    BuildingShape {
        feature,
        footprint,
        height_m,
        height_tagged: true,
        basement_m: 0.0,
        roof: buildings::roof_spec(&flat, settings),
        min_height_m: 0.0,
        drawn: true,
        base: None,
        appearance: buildings::appearance(&Tags::default()),
        // Far views draw walls without windows.
        facade: Default::default(),
        passages: Vec::new(),
    }
}

/// The blocks of one height band: the footprints closed by `tolerance`, simplified, the small
/// ones left out; each with the area-weighted mean height of the footprints whose centre it
/// holds.
fn blocks_of(footprints: &[Footprint], tolerance: f64) -> Vec<(Polygon, f64)> {
    let all = geo::MultiPolygon::new(footprints.iter().map(|f| to_geo(&f.polygon)).collect());
    let style = |distance: f64| BufferStyle::new(distance).line_join(LineJoin::Miter(2.0));
    let closed = all
        .buffer_with_style(style(tolerance))
        .buffer_with_style(style(-tolerance));
    let min_area = (MIN_BLOCK_TOLERANCES * tolerance).powi(2);
    let mut blocks: Vec<(Polygon, f64)> = closed
        .0
        .iter()
        .map(|p| p.simplify_vw_preserve(tolerance * tolerance))
        .filter(|p| p.unsigned_area() >= min_area)
        .filter_map(|p| from_geo(&p))
        .filter_map(|polygon| {
            let bounds = polygon.bounds();
            let (mut weighted, mut total) = (0.0, 0.0);
            for f in footprints {
                if bounds.contains(f.centre) && polygon.contains(f.centre) {
                    weighted += f.height_m * f.area;
                    total += f.area;
                }
            }
            (total > 0.0).then(|| (polygon, weighted / total))
        })
        .collect();
    // The order the overlay returns them in, made independent of it.
    blocks.sort_by(|a, b| {
        let (ka, kb) = (a.0.outer[0], b.0.outer[0]);
        ka[0].total_cmp(&kb[0]).then(ka[1].total_cmp(&kb[1]))
    });
    blocks
}

fn to_geo(polygon: &Polygon) -> geo::Polygon<f64> {
    let ring = |points: &[Point]| {
        geo::LineString::from(points.iter().map(|p| (p[0], p[1])).collect::<Vec<_>>())
    };
    geo::Polygon::new(
        ring(&polygon.outer),
        polygon.holes.iter().map(|h| ring(h)).collect(),
    )
}

fn from_geo(polygon: &geo::Polygon<f64>) -> Option<Polygon> {
    let ring = |line: &geo::LineString<f64>| {
        crate::geometry::dedup_ring(&line.coords().map(|c| [c.x, c.y]).collect::<Vec<_>>())
    };
    let outer = ring(polygon.exterior());
    if outer.len() < 3 {
        return None;
    }
    let holes = polygon
        .interiors()
        .iter()
        .map(ring)
        .filter(|h| h.len() >= 3)
        .collect();
    Some(Polygon { outer, holes })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::osm::LonLat;

    fn way(id: i64, tags: &[(&str, &str)], points: &[(f64, f64)]) -> Way {
        Way {
            id,
            tags: Tags::from_pairs(tags.iter().copied()),
            nodes: (0..points.len() as i64).map(|i| id * 1000 + i).collect(),
            positions: points
                .iter()
                .map(|&(lon, lat)| LonLat { lon, lat })
                .collect(),
        }
    }

    fn square(x: f64, y: f64, size: f64) -> Polygon {
        Polygon {
            outer: vec![[x, y], [x + size, y], [x + size, y + size], [x, y + size]],
            holes: Vec::new(),
        }
    }

    fn footprint(polygon: Polygon, height_m: f64) -> Footprint {
        let bounds = polygon.bounds();
        Footprint {
            area: polygon.area(),
            centre: centre_of(&bounds),
            polygon,
            height_m,
        }
    }

    #[test]
    fn buildings_nearer_than_two_tolerances_merge_into_one_block() {
        let t = 0.001;
        let near = [
            footprint(square(0.0, 0.0, 0.01), 10.0),
            footprint(square(0.0115, 0.0, 0.01), 20.0),
        ];
        let blocks = blocks_of(&near, t);
        assert_eq!(blocks.len(), 1);
        // Weighted by area (equal here): the mean.
        assert!((blocks[0].1 - 15.0).abs() < 1e-9);
        let far = [
            footprint(square(0.0, 0.0, 0.01), 10.0),
            footprint(square(0.0130, 0.0, 0.01), 20.0),
        ];
        assert_eq!(blocks_of(&far, t).len(), 2);
    }

    #[test]
    fn blocks_smaller_than_the_level_shows_are_left_out() {
        let t = 0.001;
        let tiny = [footprint(square(0.0, 0.0, 0.002), 10.0)];
        assert!(blocks_of(&tiny, t).is_empty());
        let large = [footprint(square(0.0, 0.0, 0.004), 10.0)];
        assert_eq!(blocks_of(&large, t).len(), 1);
    }

    #[test]
    fn a_block_keeps_its_footprints_outline_within_the_tolerance() {
        let t = 0.001;
        // An L of two touching rectangles with a notch far smaller than the tolerance.
        let l = Polygon {
            outer: vec![
                [0.0, 0.0],
                [0.02, 0.0],
                [0.02, 0.0001],
                [0.0201, 0.0001],
                [0.0201, 0.01],
                [0.01, 0.01],
                [0.01, 0.02],
                [0.0, 0.02],
            ],
            holes: Vec::new(),
        };
        let blocks = blocks_of(&[footprint(l.clone(), 9.0)], t);
        assert_eq!(blocks.len(), 1);
        let block = &blocks[0].0;
        assert!(block.outer.len() < l.outer.len(), "{:?}", block.outer);
        for p in &block.outer {
            let off = l
                .outer
                .iter()
                .zip(l.outer.iter().cycle().skip(1))
                .map(|(&a, &b)| crate::geometry::distance_to_segment(*p, a, b))
                .fold(f64::INFINITY, f64::min);
            assert!(off <= t, "{p:?} lies {off} from the footprint");
        }
        assert!((block.area() - l.area()).abs() < 0.02 * l.area());
    }

    #[test]
    fn coarser_levels_draw_fewer_road_classes() {
        let tile = TileId { z: 13, x: 0, y: 0 };
        let at = |above: u8| Level {
            tile,
            levels_above: above,
            data: None,
        };
        assert!(at(1).draws_road("tertiary"));
        assert!(!at(2).draws_road("tertiary"));
        assert!(at(2).draws_road("secondary"));
        assert!(at(4).draws_road("primary_link"));
        assert!(!at(4).draws_road("secondary"));
        assert!(at(6).draws_road("motorway"));
        assert!(!at(6).draws_road("primary"));
        assert!(!at(1).draws_road("residential"));
    }

    #[test]
    fn a_way_is_simplified_alike_whichever_tile_asks() {
        let projection = Projection::new(12);
        let wiggly: Vec<(f64, f64)> = (0..50)
            .map(|i| {
                let x = 7.40 + f64::from(i) * 0.001;
                (x, 43.73 + if i % 2 == 0 { 0.0 } else { 0.000_01 })
            })
            .collect();
        let road = way(1, &[("highway", "primary")], &wiggly);
        let simplified = simplify_ways(&[&road], &projection, TOLERANCE_PER_TILE);
        assert_eq!(simplified[0].positions.len(), 2);
        assert_eq!(simplified[0].nodes, vec![1000, 1049]);
        let building = way(2, &[("building", "yes")], &wiggly);
        assert!(simplify_ways(&[&building], &projection, TOLERANCE_PER_TILE).is_empty());
    }
}
