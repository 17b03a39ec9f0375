//! Buildings: footprints (ways and multipolygons with courtyards) with a height.
//!
//! Height: `height`, else `building:levels` (+ `roof:levels`) × the level height, else a default
//! by building type; `min_height` is not yet honoured. Nonsense values (negative, not numbers,
//! absurdly tall) are ignored with a debug log.

use tracing::debug;

use super::{Area, BuildingShape, FeatureClass, FeatureSet, FeatureSettings, Projection, Surface};
use crate::osm::units::{parse_count, parse_length_m};
use crate::osm::Tags;

/// Taller than any building ever built (metres); a larger value is a tagging mistake.
const MAX_HEIGHT_M: f64 = 1000.0;
/// More levels than any building has.
const MAX_LEVELS: f64 = 200.0;

pub fn is_building(tags: &Tags) -> bool {
    tags.is_set("building")
        && tags.get("location") != Some("underground")
        && tags.get("building") != Some("construction")
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

/// A roof the mesh stage can build.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RoofShape {
    Flat,
    /// Every side slopes up to the ridges (the straight skeleton raised).
    Hipped,
    /// Slopes on the long sides, vertical gables at the ends of each wing.
    Gabled,
    /// Straight faces from every side to a point over the middle (also `cone`).
    Pyramidal,
    /// A quarter circle in section, up to a point over the middle.
    Dome,
    /// Bulging out past the walls, then drawn in to a point.
    Onion,
}

/// The roof a building's tags ask for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoofSpec {
    pub shape: RoofShape,
    /// Height of the ridge above the eaves, metres, when tagged.
    pub height_m: Option<f64>,
    /// Rise per unit of run when no height is tagged.
    pub pitch: f64,
}

/// Pitch of a roof with neither a height nor an angle tagged: 30°.
const DEFAULT_PITCH_DEG: f64 = 30.0;

/// The roof from `roof:shape`, `roof:height`, `roof:levels` and `roof:angle`. A shape not built
/// yet is drawn flat, with a debug log.
pub fn roof_spec(tags: &Tags, settings: &FeatureSettings) -> RoofSpec {
    let shape = match tags.get("roof:shape") {
        // Untagged, small houses and sheds have gabled roofs far more often than flat ones.
        None if matches!(
            tags.get("building"),
            Some(
                "house"
                    | "detached"
                    | "semidetached_house"
                    | "farm"
                    | "bungalow"
                    | "cabin"
                    | "hut"
                    | "shed"
                    | "barn"
                    | "farm_auxiliary"
                    | "chapel"
                    | "church"
            )
        ) =>
        {
            RoofShape::Gabled
        }
        None | Some("flat") => RoofShape::Flat,
        Some("hipped" | "half-hipped" | "side_hipped" | "mansard") => RoofShape::Hipped,
        Some("pyramidal" | "cone") => RoofShape::Pyramidal,
        Some("dome") => RoofShape::Dome,
        Some("onion") => RoofShape::Onion,
        Some("gabled" | "saltbox" | "gambrel") => RoofShape::Gabled,
        Some(other) => {
            debug!(roof_shape = other, "roof shape drawn flat");
            RoofShape::Flat
        }
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
    RoofSpec {
        shape,
        height_m,
        pitch: angle.to_radians().tan(),
    }
}

/// The building's height in metres and whether it was tagged.
pub fn height_m(tags: &Tags, settings: &FeatureSettings) -> (f64, bool) {
    if let Some(raw) = tags.get("height") {
        match parse_length_m(raw) {
            Some(h) if h > 0.0 && h <= MAX_HEIGHT_M => return (h, true),
            _ => debug!(height = raw, "implausible building height ignored"),
        }
    }
    if let Some(raw) = tags.get("building:levels") {
        match parse_count(raw) {
            Some(levels) if levels > 0.0 && levels <= MAX_LEVELS => {
                let roof_levels = tags
                    .get("roof:levels")
                    .and_then(parse_count)
                    .filter(|l| (0.0..=20.0).contains(l))
                    .unwrap_or(0.0);
                return ((levels + roof_levels) * settings.level_height_m, true);
            }
            _ => debug!(levels = raw, "implausible building:levels ignored"),
        }
    }
    let building = tags.get("building").unwrap_or("yes");
    (default_height_m(building, settings), false)
}

pub(super) fn add_area(
    set: &mut FeatureSet,
    area: &Area<'_>,
    projection: &Projection,
    settings: &FeatureSettings,
) {
    if !is_building(area.tags) {
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
    let (height, tagged) = height_m(area.tags, settings);
    let roof = roof_spec(area.tags, settings);
    let feature = set.add_feature(Some(area.element), FeatureClass::Building, area.tags);
    for footprint in &footprints {
        set.buildings.push(BuildingShape {
            feature,
            footprint: footprint.clone(),
            height_m: height,
            height_tagged: tagged,
            roof,
        });
    }
    if let Some(surface) = Surface::from_polygons(FeatureClass::Building, feature, footprints) {
        set.surfaces.push(surface);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tags(pairs: &[(&str, &str)]) -> Tags {
        Tags::from_pairs(pairs.iter().copied())
    }

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
            roof_spec(&tags(&[("building", "house")]), &s).shape,
            RoofShape::Gabled
        );
        assert_eq!(
            roof_spec(&tags(&[("roof:shape", "something")]), &s).shape,
            RoofShape::Flat
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
