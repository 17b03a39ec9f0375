//! Railways as ground surfaces: the track gauge plus ballast on each side.

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
