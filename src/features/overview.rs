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

mod blocks;

use std::collections::HashSet;

use super::buildings;
use super::{
    areas_of, coastline, landcover, railways, roads, tile_rect, water, widened_surface,
    FeatureClass, FeatureSet, FeatureSettings, Projection,
};
use crate::geometry::{Point, Polygon, Rect};
use crate::osm::far::{FarSource, Generalised};
use crate::osm::index::Selection;
use crate::osm::{ElementRef, ElementType, Relation, Tags, Way};
use crate::tile::{LonLatBounds, TileId};

/// Buildings are drawn as blocks up to this many levels above the served zoom.
pub const BLOCKS_UP_TO: u8 = 4;
/// Fraction of a tile's ground size that its lines are simplified to.
const TOLERANCE_PER_TILE: f64 = 1.0 / 1024.0;
/// Roads and railways are drawn at least this many tolerances wide.
const MIN_WIDTH_TOLERANCES: f64 = 1.5;
/// Areas smaller than a square this many tolerances wide are left out.
const MIN_AREA_TOLERANCES: f64 = 8.0;

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

/// The generalised features of `level`'s tile: made from the data near it, or from its
/// generalised data (a selection with the blocks it owns), whose lines are simplified already.
pub fn collect(selection: &Selection<'_>, level: Level, settings: &FeatureSettings) -> FeatureSet {
    let far = selection.blocks;
    let tile = level.tile;
    let projection = Projection::new(tile.z);
    let mut set = FeatureSet::default();
    set.add_feature(None, FeatureClass::Terrain, &Tags::default());

    let simplified = match far {
        Some(_) => Vec::new(),
        None => simplify_ways(&selection.ways, &projection, level.tolerance_uv()),
    };
    let coastlines = simplify_ways(&selection.coastlines, &projection, level.tolerance_uv());
    let generalised = Selection {
        ways: match far {
            Some(_) => selection.ways.clone(),
            None => simplified.iter().collect(),
        },
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
        let owned: Vec<(Polygon, f64)> = match far {
            Some(kept) => kept
                .iter()
                .map(|b| (blocks::from_world(b, tile.z), b.height_m))
                .collect(),
            None => {
                let footprints = blocks::of_buildings(&areas_of(selection), &projection, settings);
                blocks::owned(&footprints, level)
            }
        };
        let shown = owned
            .into_iter()
            .filter(|(outline, _)| blocks::large_enough(outline, level.tolerance_uv()))
            .collect();
        add_blocks(&mut set, shown, settings);
    }
    set.retain_touching(&tile_rect(tile));
    set
}

/// Adds the blocks a tile owns.
fn add_blocks(set: &mut FeatureSet, owned: Vec<(Polygon, f64)>, settings: &FeatureSettings) {
    let tags = Tags::from_pairs([("building", "block")]);
    for (outline, height_m) in owned {
        let feature = set.add_feature(None, FeatureClass::Building, &tags);
        set.buildings
            .push(blocks::block_shape(feature, outline, height_m, settings));
    }
}

/// The generalised data of a far tile (see [`crate::osm::far`]): the ways and relations its
/// features are made from, lines simplified to its tolerance, the areas it cannot show left
/// out; and the blocks it owns, made from the buildings as mapped or from the finer level's
/// blocks, those too small to draw kept for a coarser level to join. Heights are those of the
/// default settings.
pub fn generalise(source: &FarSource<'_>) -> Generalised {
    let tile = source.tile;
    let level = Level {
        tile,
        levels_above: source.served_zoom.saturating_sub(tile.z).max(1),
        data: None,
    };
    let projection = Projection::new(tile.z);
    let tolerance = level.tolerance_uv();
    let min_area = (MIN_AREA_TOLERANCES * tolerance).powi(2);
    let relations: Vec<Relation> = source
        .relations
        .iter()
        .filter(|r| r.tags.get("type") == Some("multipolygon") && draws_area(&r.tags))
        .map(|&r| r.clone())
        .collect();
    let members: HashSet<i64> = relations
        .iter()
        .flat_map(|r| &r.members)
        .filter(|m| m.element.element_type == ElementType::Way)
        .map(|m| m.element.id)
        .collect();
    let kept: Vec<&Way> = source
        .ways
        .iter()
        .copied()
        .filter(|w| {
            members.contains(&w.id)
                || coastline::is_coastline(w)
                || draws_line(w, level)
                || (draws_area(&w.tags) && box_area(w, &projection) >= min_area)
        })
        .collect();
    let mut ways = simplify_ways(&kept, &projection, tolerance);
    ways.sort_by_key(|w| w.id);
    ways.dedup_by_key(|w| w.id);
    let blocks = if level.levels_above <= BLOCKS_UP_TO {
        let footprints = match source.blocks {
            Some(finer) => blocks::of_blocks(finer, tile.z),
            None => {
                let selection = Selection {
                    ways: source.ways.to_vec(),
                    relations: source.relations.to_vec(),
                    ..Selection::default()
                };
                let settings = FeatureSettings::default();
                blocks::of_buildings(&areas_of(&selection), &projection, &settings)
            }
        };
        blocks::owned(&footprints, level)
            .iter()
            .map(|(outline, height_m)| blocks::to_world(outline, *height_m, tile.z))
            .collect()
    } else {
        Vec::new()
    };
    Generalised {
        ways,
        relations,
        blocks,
    }
}

/// Whether an area with these tags is drawn at far views: water or land cover.
fn draws_area(tags: &Tags) -> bool {
    water::is_water_area(tags) || landcover::Cover::from_tags(tags).is_some()
}

/// The area of a way's box, in the projection's units squared: no piece of it is larger.
fn box_area(way: &Way, projection: &Projection) -> f64 {
    if way.positions.is_empty() {
        return 0.0;
    }
    let r = Rect::around(&projection.points(&way.positions));
    (r.max[0] - r.min[0]) * (r.max[1] - r.min[1])
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
    if !draws_line(way, level) {
        return;
    }
    let (class, width) = if way.tags.get("highway").is_some() {
        (FeatureClass::Road, roads::width_m(&way.tags, settings))
    } else if way.tags.get("railway").is_some() {
        let width = railways::width_m(way.tags.get("gauge"), false);
        (FeatureClass::Railway, Some(width))
    } else {
        water::add_waterway(set, way, projection);
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

/// Whether `level` draws the way as a line: a major road, a railway or a river.
fn draws_line(way: &Way, level: Level) -> bool {
    if way.positions.len() < 2 || super::structures::is_off_ground(&way.tags) || is_area(&way.tags)
    {
        return false;
    }
    if let Some(highway) = way.tags.get("highway") {
        level.draws_road(highway)
    } else if let Some(railway) = way.tags.get("railway") {
        matches!(railway, "rail" | "light_rail" | "narrow_gauge")
    } else {
        matches!(way.tags.get("waterway"), Some("river" | "canal"))
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
