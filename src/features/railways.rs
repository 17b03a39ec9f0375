//! Railways as ground surfaces: the track gauge plus ballast on each side.

use super::{widened_surface, FeatureClass, FeatureSet, Projection};
use crate::osm::units::parse_length_m;
use crate::osm::{ElementRef, ElementType, Way};

/// Standard gauge, metres.
const STANDARD_GAUGE_M: f64 = 1.435;
/// Ballast bed beyond the rails on each side, metres (a typical ballast shoulder).
const BALLAST_M: f64 = 0.8;

fn drawn(railway: &str) -> bool {
    matches!(
        railway,
        "rail"
            | "light_rail"
            | "subway"
            | "tram"
            | "narrow_gauge"
            | "funicular"
            | "monorail"
            | "preserved"
            | "miniature"
    )
}

/// Width of the track bed in metres.
pub fn width_m(gauge: Option<&str>) -> f64 {
    let gauge_m = gauge
        .and_then(|g| g.split(';').next())
        .and_then(|g| g.trim().parse::<f64>().ok())
        .map(|mm| mm / 1000.0)
        .filter(|m| (0.3..=3.0).contains(m))
        .unwrap_or(STANDARD_GAUGE_M);
    gauge_m + 2.0 * BALLAST_M
}

pub(super) fn add_way(set: &mut FeatureSet, way: &Way, projection: &Projection) {
    let Some(railway) = way.tags.get("railway") else {
        return;
    };
    if !drawn(railway) || super::roads::is_off_ground(&way.tags) {
        return;
    }
    let width = way
        .tags
        .get("width")
        .and_then(parse_length_m)
        .filter(|w| (0.5..=30.0).contains(w))
        .unwrap_or_else(|| width_m(way.tags.get("gauge")));
    let line = projection.points(&way.positions);
    let half_width = projection.metres(width / 2.0, way.positions[0].lat);
    let element = ElementRef {
        element_type: ElementType::Way,
        id: way.id,
    };
    let feature = set.add_feature(Some(element), FeatureClass::Railway, &way.tags);
    match widened_surface(FeatureClass::Railway, feature, &line, half_width) {
        Some(surface) => set.surfaces.push(surface),
        None => {
            set.features.pop();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauge_sets_the_width() {
        assert!((width_m(None) - 3.035).abs() < 1e-12);
        assert!((width_m(Some("1000")) - 2.6).abs() < 1e-12);
        assert!((width_m(Some("nonsense")) - 3.035).abs() < 1e-12);
    }
}
