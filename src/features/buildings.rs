//! Buildings: footprints (ways and multipolygons with courtyards) with a height.
//!
//! Height: `height`, else `building:levels` (+ `roof:levels`) × the level height, else a default
//! by building type (a pitched roof stands on top of `building:levels` counted alone, see
//! [`RoofSpec::over_levels`]); the bottom at `min_height`, else `building:min_level` × the level
//! height.
//! Nonsense values (negative, not numbers, absurdly tall) are ignored with a debug log.
//!
//! `building:part` areas replace the outline they lie in (Simple 3D Buildings): an outline
//! with parts is not drawn, only cut out of the ground.

use std::collections::HashMap;

use tracing::debug;

use super::{
    facades, inference, Area, BuildingShape, FeatureClass, FeatureSet, FeatureSettings,
    InferredTags, Projection, Surface,
};
use crate::geometry::Point;
use crate::osm::units::{parse_count, parse_length_m};
use crate::osm::{ElementRef, Relation, Tags};

/// Taller than any building ever built (metres); a larger value is a tagging mistake.
const MAX_HEIGHT_M: f64 = 1000.0;
/// More levels than any building has.
const MAX_LEVELS: f64 = 200.0;

pub fn is_building(tags: &Tags) -> bool {
    tags.is_set("building")
        && tags.get("location") != Some("underground")
        && tags.get("building") != Some("construction")
}

pub fn is_building_part(tags: &Tags) -> bool {
    tags.is_set("building:part") && tags.get("location") != Some("underground")
}

/// The bottom of a building or part above the ground, metres: `min_height`, else
/// `building:min_level` × the level height, else 0.
pub fn min_height_m(tags: &Tags, settings: &FeatureSettings) -> f64 {
    if let Some(raw) = tags.get("min_height") {
        match parse_length_m(raw) {
            Some(h) if (0.0..MAX_HEIGHT_M).contains(&h) => return h,
            _ => debug!(min_height = raw, "implausible min_height ignored"),
        }
    }
    tags.get("building:min_level")
        .and_then(parse_count)
        .filter(|l| (0.0..=MAX_LEVELS).contains(l))
        .map_or(0.0, |l| l * settings.level_height_m)
}

/// Links the members of `type=building` relations: every `part` stands on the base of the
/// `outline`, which is then drawn only through its parts (it still cuts the ground).
pub(super) fn link_building_relations(set: &mut FeatureSet, relations: &[&Relation]) {
    let mut by_element: HashMap<ElementRef, Vec<usize>> = HashMap::new();
    for (index, building) in set.buildings.iter().enumerate() {
        if let Some(element) = set.features[building.feature as usize].element {
            by_element.entry(element).or_default().push(index);
        }
    }
    for relation in relations {
        if relation.tags.get("type") != Some("building") {
            continue;
        }
        let members = |role: &'static str| {
            relation
                .members
                .iter()
                .filter(move |m| m.role == role)
                .filter_map(|m| by_element.get(&m.element))
                .flatten()
                .copied()
        };
        let Some(outline) = members("outline").next() else {
            debug!(
                relation = relation.id,
                "building relation without its outline here"
            );
            continue;
        };
        let parts: Vec<usize> = members("part").filter(|&p| p != outline).collect();
        for &part in &parts {
            set.buildings[part].base = Some(outline);
        }
        if !parts.is_empty() {
            set.buildings[outline].drawn = false;
        }
    }
}

/// Hides the outlines that hold `building:part`s (Simple 3D Buildings: once a building has
/// parts, the parts are the building and the outline only marks its place), and stands every
/// part on the base of the outline it lies in (parts that a `type=building` relation placed
/// already keep theirs).
pub(super) fn replace_outlines_by_parts(set: &mut FeatureSet) {
    let is_part = |b: &BuildingShape| {
        set.features[b.feature as usize]
            .tags
            .is_set("building:part")
    };
    let parts: Vec<usize> = (0..set.buildings.len())
        .filter(|&i| is_part(&set.buildings[i]) && set.buildings[i].base.is_none())
        .collect();
    if parts.is_empty() {
        return;
    }
    let outlines: Vec<usize> = (0..set.buildings.len())
        .filter(|&i| !is_part(&set.buildings[i]))
        .collect();
    let mut has_parts = vec![false; set.buildings.len()];
    for &p in &parts {
        let footprint = &set.buildings[p].footprint;
        let probe = interior_point(footprint);
        let owner = outlines.iter().copied().find(|&o| {
            let outline = &set.buildings[o].footprint;
            outline.bounds().contains(probe) && outline.contains(probe)
        });
        if let Some(o) = owner {
            has_parts[o] = true;
            set.buildings[p].base = Some(o);
        }
    }
    for o in outlines {
        if has_parts[o] {
            set.buildings[o].drawn = false;
        }
    }
}

/// Opens the buildings that roads pass through (`tunnel=building_passage`): each such road's
/// surface is marked a passage (the ground under it is the road's, not the building's), and
/// every building drawn on the ground whose footprint its pieces may reach is given them, so
/// its walls open over the road and its floors stand above it.
pub(super) fn open_passages(set: &mut FeatureSet) {
    let FeatureSet {
        features,
        surfaces,
        buildings,
        ..
    } = set;
    for surface in surfaces.iter_mut() {
        let info = &features[surface.feature as usize];
        if surface.class != FeatureClass::Road
            || info.tags.get("tunnel") != Some("building_passage")
        {
            continue;
        }
        surface.passage = true;
        for building in buildings.iter_mut() {
            let footprint = building.footprint.bounds();
            if !building.drawn
                || building.min_height_m > 0.0
                || !footprint.intersects(&surface.bounds)
            {
                continue;
            }
            building.passages.extend(
                surface
                    .pieces
                    .iter()
                    .filter(|piece| piece.bounds().intersects(&footprint))
                    .cloned(),
            );
        }
    }
}

/// A point inside a polygon: the centroid of the first of its triangles.
fn interior_point(polygon: &crate::geometry::Polygon) -> crate::geometry::Point {
    crate::geometry::constrained::triangulate_polygon(polygon)
        .first()
        .map(|t| {
            [
                (t[0][0] + t[1][0] + t[2][0]) / 3.0,
                (t[0][1] + t[1][1] + t[2][1]) / 3.0,
            ]
        })
        .unwrap_or(polygon.outer[0])
}

/// Height when nothing is tagged, by `building` value, in metres.
fn default_height_m(building: &str, settings: &FeatureSettings) -> f64 {
    match building {
        "garage" | "garages" | "shed" | "carport" | "hut" | "kiosk" | "roof" | "cabin" => 3.0,
        "apartments" | "office" | "hotel" | "commercial" | "hospital" => {
            4.0 * settings.level_height_m
        }
        _ => settings.default_building_height_m,
    }
}

pub use super::roof_shape::RoofShape;

/// The roof a building's tags ask for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoofSpec {
    pub shape: RoofShape,
    /// Height of the ridge above the eaves, metres, when tagged.
    pub height_m: Option<f64>,
    /// Rise per unit of run when no height is tagged.
    pub pitch: f64,
    /// `roof:direction`: the compass direction (degrees from north, clockwise) the main face of
    /// the roof looks towards.
    pub direction_deg: Option<f64>,
    /// `roof:orientation=across`: the ridge runs across the longer side, not along it.
    pub across: bool,
    /// The building's height counts the levels under the roof only (`building:levels`, with
    /// neither `height` nor `roof:levels`): the roof stands on top of them instead of being
    /// carved out of them.
    pub over_levels: bool,
}

/// Pitch of a roof with neither a height nor an angle tagged: 30°.
const DEFAULT_PITCH_DEG: f64 = 30.0;

/// The roof from `roof:shape` (or its synonym `building:roof:shape`), `roof:height`,
/// `roof:levels`, `roof:angle`, `roof:direction` and `roof:orientation`. An unknown shape is
/// drawn flat, with a debug log.
pub fn roof_spec(tags: &Tags, settings: &FeatureSettings) -> RoofSpec {
    let tagged_shape = tags
        .get("roof:shape")
        .or_else(|| tags.get("building:roof:shape"));
    // Untagged, flat: a building's own roof is inferred from more than its tags
    // (`super::inference`), a part's is flat (Simple 3D Buildings).
    let shape = match tagged_shape {
        None => RoofShape::Flat,
        Some(value) => RoofShape::from_tag(value).unwrap_or_else(|| {
            debug!(roof_shape = value, "unknown roof shape drawn flat");
            RoofShape::Flat
        }),
    };
    let height_m = tags
        .get("roof:height")
        .and_then(parse_length_m)
        .filter(|h| *h > 0.0 && *h <= 100.0)
        .or_else(|| {
            tags.get("roof:levels")
                .and_then(parse_count)
                .filter(|l| *l > 0.0 && *l <= 20.0)
                .map(|l| l * settings.level_height_m)
        });
    let angle = tags
        .get("roof:angle")
        .and_then(|a| a.trim().parse::<f64>().ok())
        .filter(|a| *a > 0.0 && *a < 80.0)
        .unwrap_or(DEFAULT_PITCH_DEG);
    let direction_deg = tags.get("roof:direction").and_then(|raw| {
        let parsed = parse_direction(raw);
        if parsed.is_none() {
            debug!(roof_direction = raw, "unknown roof:direction ignored");
        }
        parsed
    });
    RoofSpec {
        shape,
        height_m,
        pitch: angle.to_radians().tan(),
        direction_deg,
        across: tags.get("roof:orientation") == Some("across"),
        over_levels: tagged_height_m(tags).is_none()
            && tagged_levels(tags).is_some()
            && tagged_roof_levels(tags).is_none(),
    }
}

/// A plausible `height`, metres.
fn tagged_height_m(tags: &Tags) -> Option<f64> {
    tags.get("height")
        .and_then(parse_length_m)
        .filter(|&h| h > 0.0 && h <= MAX_HEIGHT_M)
}

/// A plausible `building:levels`.
fn tagged_levels(tags: &Tags) -> Option<f64> {
    tags.get("building:levels")
        .and_then(parse_count)
        .filter(|&l| l > 0.0 && l <= MAX_LEVELS)
}

/// A plausible `roof:levels` (counted in a building's levels when its height is).
fn tagged_roof_levels(tags: &Tags) -> Option<f64> {
    tags.get("roof:levels")
        .and_then(parse_count)
        .filter(|l| (0.0..=20.0).contains(l))
}

/// A compass direction in degrees: a number, or a point of the compass (`N`, `NNE`, … `NW`).
pub fn parse_direction(raw: &str) -> Option<f64> {
    let raw = raw.trim();
    if let Ok(degrees) = raw.parse::<f64>() {
        return degrees.is_finite().then(|| degrees.rem_euclid(360.0));
    }
    const POINTS: [&str; 16] = [
        "N", "NNE", "NE", "ENE", "E", "ESE", "SE", "SSE", "S", "SSW", "SW", "WSW", "W", "WNW",
        "NW", "NNW",
    ];
    let upper = raw.to_ascii_uppercase();
    POINTS
        .iter()
        .position(|p| *p == upper)
        .map(|i| i as f64 * 22.5)
}

/// The colours of a building's walls and roof, linear RGBA, and how they reflect light.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Appearance {
    pub walls: [u8; 4],
    pub roof: [u8; 4],
    pub wall_finish: Finish,
    pub roof_finish: Finish,
}

/// How a surface reflects light: each finish is a glTF material of its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub enum Finish {
    /// Masonry, plaster, tiles, wood: not metallic, rough.
    #[default]
    Matte,
    /// Sheet metal, copper, zinc.
    Metal,
    /// Glass curtain walls and glazed roofs: smooth.
    Glass,
}

impl Finish {
    /// The finish of a `building:material` or `roof:material` value.
    pub fn of_material(material: &str) -> Finish {
        match material {
            "glass" | "mirror" => Finish::Glass,
            "metal" | "steel" | "tin" | "copper" | "zinc" | "aluminium" | "aluminum" => {
                Finish::Metal
            }
            _ => Finish::Matte,
        }
    }

    /// glTF's metallic factor and roughness factor.
    pub fn metallic_roughness(self) -> (f32, f32) {
        match self {
            Finish::Matte => (0.0, 0.85),
            Finish::Metal => (0.8, 0.4),
            Finish::Glass => (0.0, 0.08),
        }
    }
}

/// Walls and roofs with no colour or material tagged (linear RGB).
const DEFAULT_WALLS: [f64; 3] = [0.86, 0.80, 0.70];
const DEFAULT_ROOF: [f64; 3] = [0.62, 0.36, 0.30];

/// From `building:colour` and `roof:colour` (names or `#rrggbb`), else the colour of
/// `building:material` and `roof:material`, else the defaults.
pub fn appearance(tags: &Tags) -> Appearance {
    appearance_or(tags, (DEFAULT_WALLS, DEFAULT_ROOF))
}

/// As [`appearance`], with the walls' and the roof's colours (linear RGB) where nothing is
/// tagged for them.
pub fn appearance_or(tags: &Tags, (walls, roof): ([f64; 3], [f64; 3])) -> Appearance {
    let pick =
        |colour_key: &str, material_key: &str, material: fn(&str) -> Option<[f64; 3]>, default| {
            let srgb = tags
                .get(colour_key)
                .and_then(|c| {
                    let parsed = parse_colour(c);
                    if parsed.is_none() {
                        debug!(colour = c, "unknown colour ignored");
                    }
                    parsed
                })
                .or_else(|| tags.get(material_key).and_then(material));
            let linear = srgb.map_or(default, |c: [f64; 3]| c.map(srgb_to_linear));
            let [r, g, b] = linear.map(|c: f64| (c.clamp(0.0, 1.0) * 255.0).round() as u8);
            [r, g, b, 255]
        };
    Appearance {
        walls: pick("building:colour", "building:material", wall_material, walls),
        roof: pick("roof:colour", "roof:material", roof_material, roof),
        wall_finish: tags
            .get("building:material")
            .map_or(Finish::Matte, Finish::of_material),
        roof_finish: tags
            .get("roof:material")
            .map_or(Finish::Matte, Finish::of_material),
    }
}

/// Walls' and roof's sRGB colours as linear RGB.
fn linear((walls, roof): ([f64; 3], [f64; 3])) -> ([f64; 3], [f64; 3]) {
    (walls.map(srgb_to_linear), roof.map(srgb_to_linear))
}

fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// A colour as sRGB in 0..1: `#rgb`, `#rrggbb` or a common name (CSS names and the words
/// mappers use most).
pub fn parse_colour(value: &str) -> Option<[f64; 3]> {
    let value = value.trim().to_ascii_lowercase();
    if let Some(hex) = value.strip_prefix('#') {
        let digits: Vec<u32> = hex.chars().map(|c| c.to_digit(16)).collect::<Option<_>>()?;
        let channel = |hi: u32, lo: u32| f64::from(hi * 16 + lo) / 255.0;
        return match digits.as_slice() {
            [r, g, b] => Some([channel(*r, *r), channel(*g, *g), channel(*b, *b)]),
            [r1, r2, g1, g2, b1, b2] => {
                Some([channel(*r1, *r2), channel(*g1, *g2), channel(*b1, *b2)])
            }
            _ => None,
        };
    }
    let rgb: [u8; 3] = match value.replace(['_', ' ', '-'], "").as_str() {
        "white" => [255, 255, 255],
        "black" => [0, 0, 0],
        "grey" | "gray" => [128, 128, 128],
        "lightgrey" | "lightgray" => [211, 211, 211],
        "darkgrey" | "darkgray" => [169, 169, 169],
        "silver" => [192, 192, 192],
        "red" => [255, 0, 0],
        "darkred" | "maroon" => [128, 0, 0],
        "brown" => [165, 42, 42],
        "sienna" => [160, 82, 45],
        "beige" => [245, 245, 220],
        "tan" => [210, 180, 140],
        "cream" | "ivory" => [255, 253, 208],
        "wheat" => [245, 222, 179],
        "yellow" => [255, 255, 0],
        "lightyellow" => [255, 255, 224],
        "orange" => [255, 165, 0],
        "salmon" => [250, 128, 114],
        "pink" => [255, 192, 203],
        "green" => [0, 128, 0],
        "darkgreen" => [0, 100, 0],
        "lightgreen" => [144, 238, 144],
        "olive" => [128, 128, 0],
        "blue" => [0, 0, 255],
        "lightblue" => [173, 216, 230],
        "navy" => [0, 0, 128],
        "teal" => [0, 128, 128],
        "terracotta" => [226, 114, 91],
        _ => return None,
    };
    Some(rgb.map(|c| f64::from(c) / 255.0))
}

/// The usual colour of a wall material (sRGB).
fn wall_material(material: &str) -> Option<[f64; 3]> {
    Some(match material {
        "brick" => [0.62, 0.33, 0.24],
        "stone" | "sandstone" | "limestone" => [0.74, 0.70, 0.62],
        "concrete" | "cement_block" => [0.74, 0.74, 0.72],
        "plaster" | "render" => [0.93, 0.90, 0.84],
        "glass" | "mirror" => [0.55, 0.66, 0.74],
        "wood" | "timber_framing" => [0.55, 0.40, 0.26],
        "metal" | "steel" | "aluminium" | "aluminum" => [0.62, 0.64, 0.67],
        _ => return None,
    })
}

/// The usual colour of a roof material (sRGB).
fn roof_material(material: &str) -> Option<[f64; 3]> {
    Some(match material {
        "roof_tiles" | "tile" | "tiles" => [0.70, 0.36, 0.25],
        "slate" => [0.33, 0.35, 0.38],
        "metal" | "tin" | "steel" | "zinc" | "aluminium" | "aluminum" => [0.60, 0.62, 0.65],
        "copper" => [0.38, 0.62, 0.52],
        "concrete" => [0.70, 0.70, 0.68],
        "glass" => [0.55, 0.66, 0.74],
        "grass" | "plants" => [0.36, 0.52, 0.26],
        "tar_paper" | "asphalt" | "bitumen" => [0.27, 0.27, 0.28],
        "gravel" => [0.62, 0.60, 0.56],
        "thatch" => [0.62, 0.52, 0.32],
        "wood" => [0.50, 0.38, 0.26],
        _ => return None,
    })
}

/// The height of the underground levels of a building whose height counts levels (no valid
/// `height`): `building:levels:underground` × the level height, metres; 0 otherwise.
pub fn basement_m(tags: &Tags, settings: &FeatureSettings) -> f64 {
    let explicit = tags
        .get("height")
        .and_then(parse_length_m)
        .is_some_and(|h| h > 0.0 && h <= MAX_HEIGHT_M);
    let Some(raw) = tags.get("building:levels:underground") else {
        return 0.0;
    };
    match parse_count(raw) {
        Some(levels) if (0.0..=MAX_LEVELS).contains(&levels) => {
            let counted = tags
                .get("building:levels")
                .and_then(parse_count)
                .is_some_and(|l| l > 0.0 && l <= MAX_LEVELS);
            if explicit || !counted {
                0.0
            } else {
                levels * settings.level_height_m
            }
        }
        _ => {
            debug!(
                levels = raw,
                "implausible building:levels:underground ignored"
            );
            0.0
        }
    }
}

/// The building's height in metres and whether it was tagged.
pub fn height_m(tags: &Tags, settings: &FeatureSettings) -> (f64, bool) {
    if let Some(raw) = tags.get("height") {
        match tagged_height_m(tags) {
            Some(h) => return (h, true),
            None => debug!(height = raw, "implausible building height ignored"),
        }
    }
    if let Some(raw) = tags.get("building:levels") {
        match tagged_levels(tags) {
            Some(levels) => {
                let roof_levels = tagged_roof_levels(tags).unwrap_or(0.0);
                return ((levels + roof_levels) * settings.level_height_m, true);
            }
            None => debug!(levels = raw, "implausible building:levels ignored"),
        }
    }
    let building = tags.get("building").unwrap_or("yes");
    (default_height_m(building, settings), false)
}

/// Puts what was inferred for a building into its height and roof where its tags are silent;
/// returns the values inferred, as the tags they stand for.
fn apply_inferred(
    guess: &inference::Inferred,
    tags: &Tags,
    settings: &FeatureSettings,
    (height, roof): (&mut f64, &mut RoofSpec),
) -> InferredTags {
    let mut inferred = InferredTags::default();
    if let Some(levels) = guess.levels {
        *height = f64::from(levels) * settings.level_height_m;
        // The walls are the levels; a pitched roof stands on them.
        roof.over_levels = true;
        inferred.levels = Some(levels);
    }
    if let Some(guessed) = guess.roof {
        roof.shape = guessed.shape;
        if !tags.is_set("roof:angle") && guessed.pitch_deg > 0.0 {
            roof.pitch = guessed.pitch_deg.to_radians().tan();
        }
        inferred.roof_shape = Some(guessed.shape);
        if let Some(direction) = guessed
            .direction_deg
            .filter(|_| roof.direction_deg.is_none())
        {
            roof.direction_deg = Some(direction);
            inferred.roof_direction_deg = Some(direction);
        }
    }
    let untagged = |colour, material| !tags.is_set(colour) && !tags.is_set(material);
    let srgb = |c: [f64; 3]| c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8);
    if untagged("building:colour", "building:material") {
        inferred.building_colour = Some(srgb(guess.colours.0));
    }
    if untagged("roof:colour", "roof:material") {
        inferred.roof_colour = Some(srgb(guess.colours.1));
    }
    inferred
}

/// Adds a building (or a part) of `area`; `rows` holds the bearing of the shared wall of each
/// building in a row ([`super::rows`]).
pub(super) fn add_area(
    set: &mut FeatureSet,
    area: &Area<'_>,
    projection: &Projection,
    settings: &FeatureSettings,
    (rows, shops): (&HashMap<ElementRef, f64>, &[Point]),
) {
    let part = is_building_part(area.tags);
    if !is_building(area.tags) && !part {
        return;
    }
    let footprints: Vec<_> = area
        .polygons
        .iter()
        .filter_map(|p| projection.polygon(p))
        .collect();
    if footprints.is_empty() {
        debug!(element = ?area.element, "building without a usable footprint skipped");
        return;
    }
    let (mut height, tagged) = height_m(area.tags, settings);
    let basement = basement_m(area.tags, settings);
    let mut roof = roof_spec(area.tags, settings);
    let mut appearance = appearance(area.tags);
    let mut inferred = InferredTags::default();
    let mut levels = tagged_levels(area.tags);
    let largest = inference::largest(area.polygons.iter().map(|p| p.outer.as_slice()));
    if let Some((outline, footprint)) = largest.as_ref().filter(|_| !part) {
        let tagged_height = tagged.then_some(height);
        let row = rows.get(&area.element).copied();
        if let Some(guess) = inference::building(
            area.tags,
            (outline, footprint),
            tagged_height,
            area.element,
            row,
        ) {
            inferred = apply_inferred(&guess, area.tags, settings, (&mut height, &mut roof));
            appearance = appearance_or(area.tags, linear(guess.colours));
            levels = levels.or(guess.levels.map(f64::from));
        }
    }
    let footprint = largest.as_ref().map(|(_, footprint)| footprint);
    let mut facade = facades::facade(area.tags, footprint, levels, settings);
    let lat = area
        .polygons
        .first()
        .and_then(|p| p.outer.first())
        .map_or(0.0, |p| p.lat);
    let widest = projection
        .metres(facades::WIDEST_WITH_SHOP_NODES_M, lat)
        .min(facades::WIDEST_WITH_SHOP_NODES_DEG / 360.0 * projection.tiles_per_axis());
    if !part && facades::has_shop_inside(&footprints, shops, widest) {
        facade = facade.with_shop_inside();
    }
    let min_height = min_height_m(area.tags, settings).min(height);
    let feature = set.add_feature(Some(area.element), FeatureClass::Building, area.tags);
    set.features[feature as usize].inferred = inferred;
    for footprint in &footprints {
        set.buildings.push(BuildingShape {
            feature,
            footprint: footprint.clone(),
            height_m: height,
            height_tagged: tagged,
            basement_m: basement,
            roof,
            min_height_m: min_height,
            drawn: true,
            base: None,
            appearance,
            facade,
            passages: Vec::new(),
        });
    }
    if part {
        // Parts stand in their outline, which cuts the ground.
        return;
    }
    if let Some(surface) = Surface::from_polygons(FeatureClass::Building, feature, footprints) {
        set.surfaces.push(surface);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::osm::tags;

    #[test]
    fn height_from_tags_levels_or_default() {
        let s = FeatureSettings::default();
        assert_eq!(
            height_m(&tags(&[("building", "yes"), ("height", "12 m")]), &s),
            (12.0, true)
        );
        assert_eq!(
            height_m(&tags(&[("building", "yes"), ("building:levels", "4")]), &s),
            (12.0, true)
        );
        assert_eq!(height_m(&tags(&[("building", "yes")]), &s), (6.0, false));
        assert_eq!(height_m(&tags(&[("building", "garage")]), &s), (3.0, false));
    }

    #[test]
    fn roof_tags_choose_the_shape_and_its_height() {
        let s = FeatureSettings::default();
        let roof = roof_spec(
            &tags(&[("roof:shape", "gabled"), ("roof:height", "4 m")]),
            &s,
        );
        assert_eq!((roof.shape, roof.height_m), (RoofShape::Gabled, Some(4.0)));
        let roof = roof_spec(&tags(&[("roof:shape", "hipped"), ("roof:levels", "1")]), &s);
        assert_eq!((roof.shape, roof.height_m), (RoofShape::Hipped, Some(3.0)));
        let roof = roof_spec(&tags(&[("roof:shape", "gabled"), ("roof:angle", "45")]), &s);
        assert!((roof.pitch - 1.0).abs() < 1e-12 && roof.height_m.is_none());
        assert_eq!(roof_spec(&tags(&[]), &s).shape, RoofShape::Flat);
        assert_eq!(
            roof_spec(&tags(&[("roof:shape", "cone")]), &s).shape,
            RoofShape::Pyramidal
        );
        assert_eq!(
            roof_spec(&tags(&[("roof:shape", "mansard")]), &s).shape,
            RoofShape::Mansard
        );
        // Untagged, the roof is inferred from more than tags (`super::inference`).
        assert_eq!(
            roof_spec(&tags(&[("building", "house")]), &s).shape,
            RoofShape::Flat
        );
        assert_eq!(
            roof_spec(&tags(&[("roof:shape", "something")]), &s).shape,
            RoofShape::Flat
        );
        let skillion = roof_spec(
            &tags(&[
                ("roof:shape", "skillion"),
                ("roof:direction", "SW"),
                ("roof:orientation", "across"),
            ]),
            &s,
        );
        assert_eq!(skillion.shape, RoofShape::Skillion);
        assert_eq!(skillion.direction_deg, Some(225.0));
        assert!(skillion.across);
        assert_eq!(parse_direction("-90"), Some(270.0));
        assert_eq!(parse_direction("nne"), Some(22.5));
        assert_eq!(parse_direction("uphill"), None);
        // The documented values name every shape once.
        let named: Vec<Option<RoofShape>> = [
            "flat",
            "skillion",
            "gabled",
            "hipped",
            "half-hipped",
            "side_hipped",
            "side_half-hipped",
            "hipped-and-gabled",
            "pyramidal",
            "dome",
            "onion",
            "round",
            "gambrel",
            "mansard",
            "saltbox",
            "sawtooth",
            "butterfly",
        ]
        .iter()
        .map(|v| RoofShape::from_tag(v))
        .collect();
        assert_eq!(named, RoofShape::ALL.map(Some).to_vec());
    }

    #[test]
    fn colours_and_materials_choose_the_paint() {
        assert_eq!(parse_colour("#ff8000"), Some([1.0, 128.0 / 255.0, 0.0]));
        assert_eq!(parse_colour("#FFF"), Some([1.0, 1.0, 1.0]));
        assert_eq!(parse_colour("Light Grey"), parse_colour("lightgray"));
        assert_eq!(parse_colour("#12345"), None);
        assert_eq!(parse_colour("sparkly"), None);
        let white = appearance(&tags(&[("building:colour", "white")]));
        assert_eq!(white.walls, [255, 255, 255, 255]);
        // Mid grey in sRGB is darker in linear light.
        let grey = appearance(&tags(&[("roof:colour", "#808080")]));
        assert_eq!(grey.roof, [55, 55, 55, 255]);
        let brick = appearance(&tags(&[("building:material", "brick")]));
        assert_ne!(brick.walls, appearance(&tags(&[])).walls);
        let painted_brick = appearance(&tags(&[
            ("building:material", "brick"),
            ("building:colour", "white"),
        ]));
        assert_eq!(painted_brick.walls, [255, 255, 255, 255]);
        assert_eq!(painted_brick.wall_finish, Finish::Matte);
        let copper = appearance(&tags(&[("roof:material", "copper")]));
        assert_eq!(copper.roof_finish, Finish::Metal);
        let glass = appearance(&tags(&[("building:material", "glass")]));
        assert_eq!(
            (glass.wall_finish, glass.roof_finish),
            (Finish::Glass, Finish::Matte)
        );
    }

    #[test]
    fn min_height_from_tags_or_levels() {
        let s = FeatureSettings::default();
        assert_eq!(min_height_m(&tags(&[("min_height", "4 m")]), &s), 4.0);
        assert_eq!(min_height_m(&tags(&[("building:min_level", "2")]), &s), 6.0);
        assert_eq!(min_height_m(&tags(&[("min_height", "-3")]), &s), 0.0);
        assert_eq!(min_height_m(&tags(&[]), &s), 0.0);
    }

    #[test]
    fn a_road_tagged_as_a_building_passage_opens_the_buildings_it_reaches() {
        use crate::geometry::Polygon;
        let rect = |x0: f64, y0: f64, x1: f64, y1: f64| Polygon {
            outer: vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1]],
            holes: Vec::new(),
        };
        let mut set = FeatureSet::default();
        let s = FeatureSettings::default();
        for x in [0.0, 10.0] {
            let t = tags(&[("building", "yes")]);
            let feature = set.add_feature(None, FeatureClass::Building, &t);
            set.buildings.push(BuildingShape {
                feature,
                footprint: rect(x, 0.0, x + 4.0, 4.0),
                height_m: 10.0,
                height_tagged: true,
                basement_m: 0.0,
                roof: roof_spec(&t, &s),
                min_height_m: 0.0,
                drawn: true,
                base: None,
                appearance: appearance(&t),
                facade: Default::default(),
                passages: Vec::new(),
            });
        }
        let mut road = |pairs: &[(&str, &str)], piece: Polygon| {
            let feature = set.add_feature(None, FeatureClass::Road, &tags(pairs));
            let surface = Surface::from_polygons(FeatureClass::Road, feature, vec![piece]);
            set.surfaces.extend(surface);
        };
        // A passage through the first building; a street through the second.
        road(
            &[("highway", "service"), ("tunnel", "building_passage")],
            rect(1.0, -2.0, 2.0, 6.0),
        );
        road(&[("highway", "residential")], rect(11.0, -2.0, 12.0, 6.0));
        open_passages(&mut set);
        assert!(set.surfaces[0].passage);
        assert!(!set.surfaces[1].passage);
        assert_eq!(set.buildings[0].passages, vec![rect(1.0, -2.0, 2.0, 6.0)]);
        assert!(set.buildings[1].passages.is_empty());
    }

    #[test]
    fn parts_that_cover_their_outline_replace_it() {
        use crate::geometry::Polygon;
        let square = |x0: f64, x1: f64| Polygon {
            outer: vec![[x0, 0.0], [x1, 0.0], [x1, 1.0], [x0, 1.0]],
            holes: Vec::new(),
        };
        let mut set = FeatureSet::default();
        let s = FeatureSettings::default();
        let add = |set: &mut FeatureSet, pairs: &[(&str, &str)], footprint: Polygon| {
            let t = tags(pairs);
            let element = ElementRef {
                element_type: crate::osm::ElementType::Way,
                id: set.buildings.len() as i64 + 1,
            };
            let feature = set.add_feature(Some(element), FeatureClass::Building, &t);
            set.buildings.push(BuildingShape {
                feature,
                footprint,
                height_m: 10.0,
                height_tagged: true,
                basement_m: 0.0,
                roof: roof_spec(&t, &s),
                min_height_m: min_height_m(&t, &s),
                drawn: true,
                base: None,
                appearance: appearance(&t),
                facade: Default::default(),
                passages: Vec::new(),
            });
        };
        add(&mut set, &[("building", "yes")], square(0.0, 2.0));
        add(&mut set, &[("building:part", "yes")], square(0.0, 1.0));
        add(
            &mut set,
            &[("building:part", "yes"), ("min_height", "3")],
            square(1.0, 2.0),
        );
        // A second building with one small part is drawn through its part alone; a third,
        // without parts, stays drawn.
        add(&mut set, &[("building", "yes")], square(5.0, 9.0));
        add(&mut set, &[("building:part", "yes")], square(5.0, 6.0));
        add(&mut set, &[("building", "yes")], square(10.0, 11.0));
        replace_outlines_by_parts(&mut set);
        let drawn: Vec<bool> = set.buildings.iter().map(|b| b.drawn).collect();
        assert_eq!(drawn, vec![false, true, true, false, true, true]);
        assert_eq!(set.buildings[1].base, Some(0));
        assert_eq!(set.buildings[4].base, Some(3));
        assert_eq!(set.buildings[2].min_height_m, 3.0);

        // A building relation ties a part to its outline even where the part reaches beyond it
        // (ways 7 and 8), and takes precedence over the part's position.
        add(&mut set, &[("building", "yes")], square(20.0, 22.0));
        add(&mut set, &[("building:part", "yes")], square(21.0, 25.0));
        let way = |id| crate::osm::Member {
            element: ElementRef {
                element_type: crate::osm::ElementType::Way,
                id,
            },
            role: String::new(),
        };
        let relation = Relation {
            id: 1,
            tags: tags(&[("type", "building")]),
            members: vec![
                crate::osm::Member {
                    role: "outline".into(),
                    ..way(7)
                },
                crate::osm::Member {
                    role: "part".into(),
                    ..way(8)
                },
            ],
        };
        link_building_relations(&mut set, &[&relation]);
        replace_outlines_by_parts(&mut set);
        assert_eq!(set.buildings[7].base, Some(6));
        assert!(!set.buildings[6].drawn && set.buildings[7].drawn);
        assert!(set.buildings[5].drawn);
    }

    #[test]
    fn underground_levels_count_where_levels_give_the_height() {
        let s = FeatureSettings::default();
        let levels = [
            ("building:levels", "5"),
            ("building:levels:underground", "2"),
        ];
        assert_eq!(basement_m(&tags(&levels), &s), 6.0);
        let with_height = [levels[0], levels[1], ("height", "20")];
        assert_eq!(basement_m(&tags(&with_height), &s), 0.0);
        assert_eq!(
            basement_m(&tags(&[("building:levels:underground", "2")]), &s),
            0.0
        );
        assert_eq!(
            basement_m(
                &tags(&[
                    ("building:levels", "5"),
                    ("building:levels:underground", "-1")
                ]),
                &s
            ),
            0.0
        );
    }

    #[test]
    fn nonsense_heights_fall_back() {
        let s = FeatureSettings::default();
        for bad in ["-5", "tall", "5000"] {
            assert_eq!(
                height_m(&tags(&[("building", "yes"), ("height", bad)]), &s),
                (6.0, false)
            );
        }
        assert_eq!(
            height_m(
                &tags(&[("building", "yes"), ("building:levels", "1000")]),
                &s
            ),
            (6.0, false)
        );
    }
}
