//! Water: areas (`natural=water`, `waterway=riverbank`, `landuse=reservoir|basin`) and
//! waterways as surfaces of their width (thesis §2.3.3).

use super::{widened_surface, Area, FeatureClass, FeatureSet, Projection};
use crate::osm::units::parse_length_m;
use crate::osm::{ElementRef, ElementType, Tags, Way};

pub fn is_water_area(tags: &Tags) -> bool {
    tags.get("natural") == Some("water")
        || tags.get("waterway") == Some("riverbank")
        || matches!(tags.get("landuse"), Some("reservoir" | "basin"))
        || tags
            .get("water")
            .is_some_and(|_| tags.get("natural") == Some("water"))
}

/// Default width of a waterway in metres, `None` for values not drawn.
pub fn default_width_m(waterway: &str) -> Option<f64> {
    Some(match waterway {
        "river" => 10.0,
        "canal" => 8.0,
        "stream" => 2.0,
        "ditch" | "drain" => 1.0,
        _ => return None,
    })
}

pub(super) fn add_area(set: &mut FeatureSet, area: &Area<'_>, projection: &Projection) {
    if !is_water_area(area.tags) || area.tags.is_set("tunnel") {
        return;
    }
    set.add_area_surface(area, FeatureClass::Water, projection);
}

pub(super) fn add_waterway(set: &mut FeatureSet, way: &Way, projection: &Projection) {
    let Some(default) = way.tags.get("waterway").and_then(default_width_m) else {
        return;
    };
    if way.tags.is_set("tunnel") {
        return;
    }
    let width = way
        .tags
        .get("width")
        .and_then(parse_length_m)
        .filter(|w| (0.3..=500.0).contains(w))
        .unwrap_or(default);
    let line = projection.points(&way.positions);
    let half_width = projection.metres(width / 2.0, way.positions[0].lat);
    let element = ElementRef {
        element_type: ElementType::Way,
        id: way.id,
    };
    let feature = set.add_feature(Some(element), FeatureClass::Water, &way.tags);
    match widened_surface(FeatureClass::Water, feature, &line, half_width) {
        Some(surface) => set.surfaces.push(surface),
        None => {
            set.features.pop();
        }
    }
}
