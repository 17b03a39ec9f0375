//! Railways as ground surfaces: the track gauge plus ballast on each side.

use super::{widened_surface, FeatureClass, FeatureSet, Projection};
use crate::osm::units::parse_length_m;
use crate::osm::{ElementRef, ElementType, Way};

/// Standard gauge, metres.
const STANDARD_GAUGE_M: f64 = 1.435;
/// Ballast bed beyond the rails on each side, metres (a typical ballast shoulder).
const BALLAST_M: f64 = 0.8;
/// Paving beside the rails of a track embedded in a road, on each side, metres.
const EMBEDDED_MARGIN_M: f64 = 0.3;

pub fn drawn(railway: &str) -> bool {
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

/// True for a track laid in a road's surface: trams unless tagged `embedded=no`, and any track
/// tagged `embedded=yes`.
pub fn is_embedded(tags: &crate::osm::Tags) -> bool {
    match tags.get("embedded") {
        Some("yes") => true,
        Some("no") => false,
        _ => tags.get("railway") == Some("tram"),
    }
}

/// Width of the track bed in metres: the gauge with ballast, or with a narrow margin for a track
/// embedded in a road.
pub fn width_m(gauge: Option<&str>, embedded: bool) -> f64 {
    let gauge_m = gauge
        .and_then(|g| g.split(';').next())
        .and_then(|g| g.trim().parse::<f64>().ok())
        .map(|mm| mm / 1000.0)
        .filter(|m| (0.3..=3.0).contains(m))
        .unwrap_or(STANDARD_GAUGE_M);
    gauge_m
        + 2.0
            * if embedded {
                EMBEDDED_MARGIN_M
            } else {
                BALLAST_M
            }
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
        .unwrap_or_else(|| width_m(way.tags.get("gauge"), is_embedded(&way.tags)));
    let line = projection.points(&way.positions);
    let half_width = projection.metres(width / 2.0, way.positions[0].lat);
    let element = ElementRef {
        element_type: ElementType::Way,
        id: way.id,
    };
    let feature = set.add_feature(Some(element), FeatureClass::Railway, &way.tags);
    match widened_surface(FeatureClass::Railway, feature, &line, half_width) {
        Some(mut surface) => {
            surface.embedded = is_embedded(&way.tags);
            set.surfaces.push(surface);
        }
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
        assert!((width_m(None, false) - 3.035).abs() < 1e-12);
        assert!((width_m(Some("1000"), false) - 2.6).abs() < 1e-12);
        assert!((width_m(Some("nonsense"), false) - 3.035).abs() < 1e-12);
        assert!((width_m(None, true) - 2.035).abs() < 1e-12);
    }

    #[test]
    fn trams_lie_in_the_road_unless_tagged_otherwise() {
        let tags = |pairs: &[(&str, &str)]| crate::osm::Tags::from_pairs(pairs.to_vec());
        assert!(is_embedded(&tags(&[("railway", "tram")])));
        assert!(!is_embedded(&tags(&[
            ("railway", "tram"),
            ("embedded", "no")
        ])));
        assert!(!is_embedded(&tags(&[("railway", "rail")])));
        assert!(is_embedded(&tags(&[
            ("railway", "rail"),
            ("embedded", "yes")
        ])));
    }
}
