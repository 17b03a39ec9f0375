//! Feature families: each module turns OSM elements into what the mesh stage needs, in global
//! tile units (`u`, `v`), so the result is the same whichever tile asks.
//!
//! * ground [`Surface`]s: areas of the ground triangulation with a class, a feature id and the
//!   outline edges to stitch into it (roads, railways, water; building footprints, which are cut
//!   out of the ground);
//! * [`BuildingShape`]s: footprints with heights, extruded by the mesh stage;
//! * the feature table: one row per feature, tracing every vertex back to its OSM element.

pub mod barriers;
pub mod buildings;
pub mod carriageways;
pub mod coastline;
pub mod crossings;
pub mod facades;
pub mod inference;
pub mod landcover;
pub mod markings;
pub mod objects;
pub mod overview;
pub mod power;
pub mod railways;
pub mod road_network;
pub mod roads;
pub mod roof_shape;
pub mod rows;
pub mod sidewalks;
pub mod stop_lines;
pub mod structures;
pub mod turn_arrows;
pub mod vegetation;
pub mod water;

use crate::geometry::{Point, Polygon, Rect};
use crate::osm::index::Selection;
use crate::osm::{multipolygon::AreaPolygon, ElementRef, ElementType, LonLat, Tags};
use crate::tile::{lon_lat_to_uv, mercator_scale, TileId};
use roof_shape::RoofShape;

/// What a feature is, as written in the feature table and used to name glTF nodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum FeatureClass {
    Terrain,
    Road,
    Railway,
    Water,
    LandCover,
    Building,
    Vegetation,
    Barrier,
    Object,
    /// Bridges: decks with their structure and piers.
    Bridge,
    /// Tunnels: floors and linings under the ground, and their portals.
    Tunnel,
    /// Lines painted on roads: one feature per road that has them.
    Marking,
}

impl FeatureClass {
    pub const ALL: [FeatureClass; 12] = [
        FeatureClass::Terrain,
        FeatureClass::Road,
        FeatureClass::Railway,
        FeatureClass::Water,
        FeatureClass::LandCover,
        FeatureClass::Building,
        FeatureClass::Vegetation,
        FeatureClass::Barrier,
        FeatureClass::Object,
        FeatureClass::Bridge,
        FeatureClass::Tunnel,
        FeatureClass::Marking,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            FeatureClass::Terrain => "terrain",
            FeatureClass::Road => "road",
            FeatureClass::Railway => "railway",
            FeatureClass::Water => "water",
            FeatureClass::LandCover => "landcover",
            FeatureClass::Vegetation => "vegetation",
            FeatureClass::Barrier => "barrier",
            FeatureClass::Object => "object",
            FeatureClass::Building => "building",
            FeatureClass::Bridge => "bridge",
            FeatureClass::Tunnel => "tunnel",
            FeatureClass::Marking => "marking",
        }
    }

    /// Which surface wins where two overlap: lower is stronger. Buildings cut the ground, roads
    /// lie on water (bridges until elevation lifts them), water on land cover, land cover on the
    /// default ground.
    pub fn ground_priority(self) -> u8 {
        match self {
            FeatureClass::Building => 0,
            FeatureClass::Road => 1,
            FeatureClass::Railway => 2,
            FeatureClass::Water => 3,
            FeatureClass::LandCover => 4,
            FeatureClass::Terrain => 5,
            // Trees, barriers, objects and paint are not ground.
            FeatureClass::Vegetation
            | FeatureClass::Barrier
            | FeatureClass::Object
            | FeatureClass::Bridge
            | FeatureClass::Tunnel
            | FeatureClass::Marking => 6,
        }
    }
}

/// One row of the feature table.
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureInfo {
    pub element: Option<ElementRef>,
    pub class: FeatureClass,
    pub tags: Tags,
    /// Values its tags leave unsaid that were inferred: what a viewer can show as guessed.
    pub inferred: InferredTags,
}

/// The values of a building's tags that were inferred where the tags are silent, each standing
/// for the tag named beside it; `None` where the tag is mapped (or nothing was inferred).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct InferredTags {
    /// `building:levels`.
    pub levels: Option<u32>,
    /// `roof:shape`.
    pub roof_shape: Option<RoofShape>,
    /// `roof:direction`, degrees.
    pub roof_direction_deg: Option<f64>,
    /// `building:colour` (sRGB).
    pub building_colour: Option<[u8; 3]>,
    /// `roof:colour` (sRGB).
    pub roof_colour: Option<[u8; 3]>,
}

impl FeatureInfo {
    pub fn name(&self) -> Option<&str> {
        self.tags.get("name")
    }
}

/// An area of the ground surface.
#[derive(Debug, Clone)]
pub struct Surface {
    pub class: FeatureClass,
    /// Row in the feature table.
    pub feature: u32,
    /// The area is the union of these polygons.
    pub pieces: Vec<Polygon>,
    /// Polylines along the area's border, stitched into the triangulation as constraint edges.
    pub outline: Vec<Vec<Point>>,
    pub bounds: Rect,
    /// The ground material of a land-cover surface.
    pub cover: Option<landcover::Cover>,
    /// The pavement of a road surface.
    pub paving: Option<roads::Paving>,
    /// Lies in the road it runs along (a tram's track): drawn over roads.
    pub embedded: bool,
    /// A road through a building (`tunnel=building_passage`): the ground under the building's
    /// raised floors, drawn over the building's footprint.
    pub passage: bool,
    /// The line a surface drawn at a width follows (a waterway's, in the direction it flows),
    /// in global tile units; empty for areas.
    pub centreline: Vec<Point>,
    /// For a road drawn by the network: the line each run of `pieces` follows.
    pub piece_lines: Vec<(std::ops::Range<usize>, road_network::StretchLine)>,
    /// For a junction: the node it is drawn round.
    pub junction_at: Option<Point>,
    /// For water: how it lies.
    pub water: Option<water::WaterBody>,
}

impl Surface {
    pub fn contains(&self, p: Point) -> bool {
        self.bounds.contains(p) && self.pieces.iter().any(|piece| piece.contains(p))
    }

    /// A surface covering the union of `pieces`, with the given outline.
    fn from_parts(
        class: FeatureClass,
        feature: u32,
        pieces: Vec<Polygon>,
        outline: Vec<Vec<Point>>,
    ) -> Option<Surface> {
        let bounds = Rect::around_all(&pieces)?;
        Some(Surface {
            class,
            feature,
            pieces,
            outline,
            bounds,
            cover: None,
            paving: None,
            embedded: false,
            passage: false,
            centreline: Vec::new(),
            piece_lines: Vec::new(),
            water: None,
            junction_at: None,
        })
    }

    /// A surface covering the union of polygons, outlined by their rings.
    pub(crate) fn from_polygons(
        class: FeatureClass,
        feature: u32,
        pieces: Vec<Polygon>,
    ) -> Option<Surface> {
        let outline: Vec<Vec<Point>> = pieces
            .iter()
            .flat_map(|p| p.rings())
            .map(|ring| {
                let mut closed = ring.clone();
                closed.push(ring[0]);
                closed
            })
            .collect();
        Surface::from_parts(class, feature, pieces, outline)
    }
}

/// A building footprint to extrude.
#[derive(Debug, Clone)]
pub struct BuildingShape {
    pub feature: u32,
    pub footprint: Polygon,
    /// Height of the top above the lowest ground under the footprint, in metres.
    pub height_m: f64,
    /// True when the height came from tags rather than a default.
    pub height_tagged: bool,
    /// Height of the underground levels (`building:levels:underground`) of a building whose
    /// height counts its levels, metres: a slope shows them on its low side, so as much of
    /// them as the ground falls under the footprint is added to the height.
    pub basement_m: f64,
    pub roof: buildings::RoofSpec,
    /// Height of the bottom above the lowest ground, metres: above zero, the part floats (an
    /// overhang, a bridge between towers).
    pub min_height_m: f64,
    /// False for an outline whose `building:part`s replace it: it still cuts the ground, the
    /// parts are drawn instead.
    pub drawn: bool,
    /// The outline whose lowest ground a part stands on (its index in the same set's
    /// buildings), so the parts of one building share their base; `None` for an outline, or a
    /// part outside any.
    pub base: Option<usize>,
    pub appearance: buildings::Appearance,
    /// What its walls show: windows by level and bay, shop windows, or nothing.
    pub facade: facades::Facade,
    /// The surfaces of the roads that pass through the building (`tunnel=building_passage`)
    /// whose bounds meet its footprint: the walls open over them, its floors above.
    pub passages: Vec<Polygon>,
}

/// Everything the features of one tile contribute.
#[derive(Debug, Clone, Default)]
pub struct FeatureSet {
    pub features: Vec<FeatureInfo>,
    pub surfaces: Vec<Surface>,
    pub buildings: Vec<BuildingShape>,
    /// Trees to plant where the ground allows.
    pub trees: Vec<vegetation::Tree>,
    /// Street lamps, benches, power poles… to stand on the ground.
    pub objects: Vec<objects::PointObject>,
    /// Power lines to hang between their supports.
    pub power_lines: Vec<power::PowerLine>,
    /// Walls, fences and hedges to stand on the ground.
    pub barriers: Vec<barriers::Barrier>,
    /// Lines where the ground steps (cliffs, retaining walls), for the elevation stage.
    pub steps: Vec<barriers::GroundStep>,
    /// Flights of steps (`highway=steps` on the ground) to draw over their ramps.
    pub stairs: Vec<carriageways::Stairs>,
    /// Lines painted on the roads on the ground, along their surfaces as drawn.
    pub markings: Vec<markings::Marking>,
    /// The lines painted on the bridge decks and tunnel floors: by structure way (index into
    /// all ways), the feature row of its lines and their plan.
    pub structure_lines: std::collections::HashMap<u32, (u32, markings::LanePlan)>,
    /// Sidewalks and verges beside the roads on the ground.
    pub sidewalks: Vec<sidewalks::Band>,
    /// Outlines of the roads, railways and water near the tile, also those just outside it:
    /// they weigh the terrain error on both sides of a shared edge alike.
    pub nearby_outlines: Vec<Vec<Point>>,
}

impl FeatureSet {
    pub(crate) fn add_feature(
        &mut self,
        element: Option<ElementRef>,
        class: FeatureClass,
        tags: &Tags,
    ) -> u32 {
        self.features.push(FeatureInfo {
            element,
            class,
            tags: tags.clone(),
            inferred: InferredTags::default(),
        });
        (self.features.len() - 1) as u32
    }

    /// Adds an area as a ground surface of `class`, with its row in the feature table; `None`
    /// (and no row) when none of its polygons survives projection.
    fn add_area_surface(
        &mut self,
        area: &Area<'_>,
        class: FeatureClass,
        projection: &Projection,
    ) -> Option<&mut Surface> {
        let pieces: Vec<_> = area
            .polygons
            .iter()
            .filter_map(|p| projection.polygon(p))
            .collect();
        let feature = self.add_feature(Some(area.element), class, area.tags);
        match Surface::from_polygons(class, feature, pieces) {
            Some(surface) => {
                self.surfaces.push(surface);
                self.surfaces.last_mut()
            }
            None => {
                self.features.pop();
                None
            }
        }
    }

    /// The outlines of the roads, railways and water, taken before the set is cut to its tile:
    /// they weigh the terrain error on both sides of a shared edge alike.
    pub(crate) fn weighing_outlines(&self) -> Vec<Vec<Point>> {
        self.surfaces
            .iter()
            .filter(|s| {
                matches!(
                    s.class,
                    FeatureClass::Road | FeatureClass::Railway | FeatureClass::Water
                )
            })
            .flat_map(|s| s.outline.iter().cloned())
            .collect()
    }

    pub fn count(&self, class: FeatureClass) -> usize {
        self.features.iter().filter(|f| f.class == class).count()
    }

    /// Drops the surfaces, buildings, barriers, steps and markings whose bounds miss `rect`, and the
    /// features left without geometry; the default ground (feature 0) stays. Feature ids are
    /// renumbered in order.
    pub fn retain_touching(&mut self, rect: &Rect) {
        self.surfaces.retain(|s| s.bounds.intersects(rect));
        self.buildings
            .retain(|b| b.footprint.bounds().intersects(rect));
        self.barriers
            .retain(|b| Rect::around(&b.line).intersects(rect));
        // A step just outside changes the ground on the edge.
        self.steps.retain(|s| s.reach().intersects(rect));
        self.power_lines
            .retain(|l| Rect::around(&l.line).intersects(rect));
        self.stairs
            .retain(|s| Rect::around(&s.line).intersects(rect));
        // A line ending just outside the tile may still paint its width into it.
        self.markings.retain(|m| {
            let half = m.width_m * m.metre / 2.0;
            let bounds = Rect::around(&m.line);
            Rect {
                min: [bounds.min[0] - half, bounds.min[1] - half],
                max: [bounds.max[0] + half, bounds.max[1] + half],
            }
            .intersects(rect)
        });
        self.sidewalks.retain(|s| {
            Rect::around(&s.outer)
                .union(&Rect::around(&s.inner))
                .intersects(rect)
        });
        let mut used = vec![false; self.features.len()];
        used[0] = true;
        for feature in self
            .surfaces
            .iter()
            .map(|s| s.feature)
            .chain(self.buildings.iter().map(|b| b.feature))
            .chain(self.barriers.iter().map(|b| b.feature))
            .chain(self.steps.iter().map(|s| s.feature))
            .chain(self.power_lines.iter().map(|l| l.feature))
            .chain(self.stairs.iter().map(|s| s.feature))
            .chain(self.markings.iter().map(|m| m.feature))
            .chain(self.sidewalks.iter().map(|s| s.feature))
        {
            used[feature as usize] = true;
        }
        let mut renumbered = vec![0u32; self.features.len()];
        let mut next = 0u32;
        for (old, keep) in used.iter().enumerate() {
            if *keep {
                renumbered[old] = next;
                next += 1;
            }
        }
        let mut index = 0;
        self.features.retain(|_| {
            let keep = used[index];
            index += 1;
            keep
        });
        for surface in &mut self.surfaces {
            surface.feature = renumbered[surface.feature as usize];
        }
        for building in &mut self.buildings {
            building.feature = renumbered[building.feature as usize];
        }
        for barrier in &mut self.barriers {
            barrier.feature = renumbered[barrier.feature as usize];
        }
        for step in &mut self.steps {
            step.feature = renumbered[step.feature as usize];
            step.face = renumbered[step.face as usize];
        }
        for line in &mut self.power_lines {
            line.feature = renumbered[line.feature as usize];
        }
        for stairs in &mut self.stairs {
            stairs.feature = renumbered[stairs.feature as usize];
        }
        for marking in &mut self.markings {
            marking.feature = renumbered[marking.feature as usize];
        }
        for band in &mut self.sidewalks {
            band.feature = renumbered[band.feature as usize];
        }
    }
}

/// Settings of the feature stage.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct FeatureSettings {
    /// Width of one lane, metres (seed 001 §4.4).
    pub lane_width_m: f64,
    /// Height of one building level, metres.
    pub level_height_m: f64,
    /// Height of a building with no height tags, metres (seed 001 §4.2).
    pub default_building_height_m: f64,
    pub vegetation: vegetation::VegetationSettings,
    /// A line longer than this, kilometres, is drawn from the part of it near each tile, on
    /// the terrain: no road profile is settled along the whole of it. What one way can cost a
    /// render stays bounded, however far its nodes lie.
    pub longest_way_km: f64,
}

impl FeatureSettings {
    /// [`FeatureSettings::longest_way_km`] in metres.
    pub fn longest_way_m(&self) -> f64 {
        self.longest_way_km * 1000.0
    }
}

impl Default for FeatureSettings {
    fn default() -> Self {
        FeatureSettings {
            lane_width_m: 3.5,
            level_height_m: 3.0,
            default_building_height_m: 6.0,
            vegetation: vegetation::VegetationSettings::default(),
            longest_way_km: 100.0,
        }
    }
}

/// The projection from degrees to global tile units at one zoom, with the ground-metre scale.
#[derive(Debug, Clone, Copy)]
pub struct Projection {
    tiles_per_axis: f64,
    tile_size_m: f64,
}

impl Projection {
    pub fn new(zoom: u8) -> Projection {
        let tiles_per_axis = f64::from(1u32 << zoom);
        Projection {
            tiles_per_axis,
            tile_size_m: crate::tile::EARTH_CIRCUMFERENCE_M / tiles_per_axis,
        }
    }

    pub fn tiles_per_axis(&self) -> f64 {
        self.tiles_per_axis
    }

    pub fn point(&self, p: LonLat) -> Point {
        let (u, v) = lon_lat_to_uv(p.lon, p.lat, self.tiles_per_axis);
        [u, v]
    }

    pub fn points(&self, ps: &[LonLat]) -> Vec<Point> {
        ps.iter().map(|&p| self.point(p)).collect()
    }

    /// Ground metres at a latitude, in tile units.
    pub fn metres(&self, metres: f64, lat: f64) -> f64 {
        metres * mercator_scale(lat) / self.tile_size_m
    }

    pub fn polygon(&self, area: &AreaPolygon) -> Option<Polygon> {
        let outer = crate::geometry::dedup_ring(&self.points(&area.outer));
        if outer.len() < 3 || crate::geometry::is_collinear(&outer) {
            return None;
        }
        let holes = area
            .holes
            .iter()
            .map(|h| crate::geometry::dedup_ring(&self.points(h)))
            .filter(|h| h.len() >= 3)
            .collect();
        Some(Polygon { outer, holes })
    }
}

/// Runs every feature family over the elements near a tile, keeping those that reach it.
pub fn collect(selection: &Selection<'_>, tile: TileId, settings: &FeatureSettings) -> FeatureSet {
    let projection = Projection::new(tile.z);
    let mut set = FeatureSet::default();
    set.add_feature(None, FeatureClass::Terrain, &Tags::default());
    // The areas and the walls they share read the selection alone: they are made on a thread
    // of their own while the roads are added.
    let ((areas, rows), carriageways) = crate::parallel::join(
        || {
            let areas = areas_of(selection);
            let rows = rows::shared_walls(&areas);
            (areas, rows)
        },
        || {
            carriageways::add_roads(
                &mut set,
                &selection.ways,
                &selection.nodes,
                &projection,
                settings,
            )
        },
    );
    let shops: Vec<Point> = selection
        .nodes
        .iter()
        .filter(|n| facades::is_shop(&n.tags))
        .map(|n| projection.point(n.position))
        .collect();
    for way in &selection.ways {
        carriageways::add_railway(&mut set, way, &projection);
        water::add_waterway(&mut set, way, &projection);
        barriers::add_way(&mut set, way, &projection);
        power::add_way(&mut set, way, selection, &projection);
    }
    for area in &areas {
        roads::add_area(&mut set, area, &projection);
        water::add_area(&mut set, area, &projection);
        landcover::add_area(&mut set, area, &projection);
        buildings::add_area(&mut set, area, &projection, settings, (&rows, &shops));
    }
    buildings::link_building_relations(&mut set, &selection.relations);
    buildings::replace_outlines_by_parts(&mut set);
    buildings::open_passages(&mut set);
    sidewalks::place(&mut set, carriageways.bands, &selection.ways, &projection);
    set.nearby_outlines = set.weighing_outlines();
    add_sea(&mut set, selection, tile, &projection);
    water::drop_waterways_in_water_areas(&mut set);
    set.retain_touching(&tile_rect(tile));
    objects::collect(
        &mut set,
        selection,
        &projection,
        &tile_rect(tile),
        (&carriageways.road_sides, &carriageways.lit),
    );
    vegetation::collect(
        &mut set,
        selection,
        &projection,
        &tile_rect(tile),
        &settings.vegetation,
    );
    set
}

/// The sea from the coastlines, as one water surface of the tile.
fn add_sea(set: &mut FeatureSet, selection: &Selection<'_>, tile: TileId, projection: &Projection) {
    if selection.coastlines.is_empty() {
        return;
    }
    // The sea reaches a little past the tile, so that the ground either side of an edge knows
    // it alike (its elevation is the sea's); the triangulation clips it to the tile.
    let rect = tile_rect(tile);
    let beyond = Rect {
        min: [rect.min[0] - SEA_BEYOND, rect.min[1] - SEA_BEYOND],
        max: [rect.max[0] + SEA_BEYOND, rect.max[1] + SEA_BEYOND],
    };
    add_sea_in(set, selection, projection, &beyond);
}

/// The sea inside `beyond` from the coastlines, as one water surface.
fn add_sea_in(
    set: &mut FeatureSet,
    selection: &Selection<'_>,
    projection: &Projection,
    beyond: &Rect,
) {
    let project = |way: &crate::osm::Way| projection.points(&way.positions);
    let near_ways: Vec<&crate::osm::Way> = selection
        .ways
        .iter()
        .copied()
        .filter(|w| coastline::is_coastline(w))
        .collect();
    let near = coastline::chains(&near_ways, &project);
    let all = || coastline::chains(&selection.coastlines, &project);
    let sea = coastline::sea(&near, &all, beyond);
    // The whole coast near the tile weighs the terrain error, also just across an edge.
    set.nearby_outlines
        .extend(near.into_iter().map(|chain| chain.points));
    if sea.polygons.is_empty() {
        return;
    }
    let tags = Tags::from_pairs([("natural", "sea")]);
    let feature = set.add_feature(None, FeatureClass::Water, &tags);
    if let Some(mut surface) =
        Surface::from_parts(FeatureClass::Water, feature, sea.polygons, sea.coast)
    {
        surface.water = Some(water::WaterBody::of(&tags));
        set.surfaces.push(surface);
    }
}

/// How far past the tile the sea is computed, tile units (about 24 m at zoom 14: more than the
/// step of the ground's normals, well within the OSM query margin).
const SEA_BEYOND: f64 = 0.01;

/// A tile's square in global tile units.
pub fn tile_rect(tile: TileId) -> Rect {
    Rect {
        min: [f64::from(tile.x), f64::from(tile.y)],
        max: [f64::from(tile.x) + 1.0, f64::from(tile.y) + 1.0],
    }
}

/// A closed way or an assembled multipolygon, with the tags that describe it.
#[derive(Debug, Clone)]
pub struct Area<'a> {
    pub element: ElementRef,
    pub tags: &'a Tags,
    pub polygons: Vec<AreaPolygon>,
}

/// Whether features are made from a relation: multipolygons (areas) and buildings (their
/// outlines and parts). Routes, boundaries and the like take no part in a tile.
pub fn reads_relation(tags: &Tags) -> bool {
    matches!(tags.get("type"), Some("multipolygon" | "building"))
}

/// Drops the relations features are not made from (see [`reads_relation`]).
pub fn keep_relations_read(relations: &mut Vec<crate::osm::Relation>) {
    relations.retain(|r| reads_relation(&r.tags));
}

/// The areas among the selected elements, in id order (ways, then relations).
fn areas_of<'a>(selection: &Selection<'a>) -> Vec<Area<'a>> {
    let mut areas = Vec::new();
    for way in &selection.ways {
        if !crate::osm::areas::is_area(&way.tags) {
            continue;
        }
        if let Some(polygon) = crate::osm::multipolygon::way_area(way) {
            let element = ElementRef {
                element_type: ElementType::Way,
                id: way.id,
            };
            let polygons = crate::osm::multipolygon::checked(element, vec![polygon]);
            if !polygons.is_empty() {
                areas.push(Area {
                    element,
                    tags: &way.tags,
                    polygons,
                });
            }
        }
    }
    let way_of = |id: i64| {
        selection
            .ways
            .binary_search_by_key(&id, |w| w.id)
            .ok()
            .map(|i| selection.ways[i])
    };
    for relation in &selection.relations {
        if !matches!(relation.tags.get("type"), Some("multipolygon")) {
            continue;
        }
        let element = ElementRef {
            element_type: ElementType::Relation,
            id: relation.id,
        };
        let polygons = crate::osm::multipolygon::checked(
            element,
            crate::osm::multipolygon::assemble(relation, way_of),
        );
        if !polygons.is_empty() {
            areas.push(Area {
                element,
                tags: &relation.tags,
                polygons,
            });
        }
    }
    areas
}

/// A linear feature widened into a ground surface: the quads between the offset polylines.
pub(crate) fn widened_surface(
    class: FeatureClass,
    feature: u32,
    line: &[Point],
    half_width: f64,
) -> Option<Surface> {
    let (left, right) = crate::geometry::offset_polyline(line, half_width)?;
    let pieces: Vec<Polygon> = (0..left.len() - 1)
        .map(|i| Polygon {
            outer: vec![left[i], left[i + 1], right[i + 1], right[i]],
            holes: Vec::new(),
        })
        .collect();
    let last = left.len() - 1;
    let outline = vec![
        left.clone(),
        right.clone(),
        vec![left[0], right[0]],
        vec![left[last], right[last]],
    ];
    let mut surface = Surface::from_parts(class, feature, pieces, outline)?;
    surface.centreline = line.to_vec();
    Some(surface)
}
