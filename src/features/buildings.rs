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
    let feature = set.add_feature(Some(area.element), FeatureClass::Building, area.tags);
    for footprint in &footprints {
        set.buildings.push(BuildingShape {
            feature,
            footprint: footprint.clone(),
            height_m: height,
            height_tagged: tagged,
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
