//! Whether a closed way is an area or a closed line, from its tags.
//!
//! OSM leaves it to the tags: `area=yes` and `area=no` decide outright; otherwise some keys imply
//! an area (a `building`, a `landuse`) and others a line (a `highway` roundabout, a `barrier`
//! around a garden), some keys only for some values (`natural=water` is an area,
//! `natural=coastline` a line). The lists follow the OSM wiki's "Key:area" page and the area
//! keys editors use.

use super::Tags;

/// Keys whose every value (but `no`) makes a closed way an area, unless listed in
/// [`LINEAR_VALUES`].
const AREA_KEYS: &[&str] = &[
    "building",
    "building:part",
    "landuse",
    "leisure",
    "amenity",
    "natural",
    "water",
    "wetland",
    "place",
    "shop",
    "tourism",
    "historic",
    "military",
    "office",
    "craft",
    "aeroway",
    "area:highway",
    "man_made",
    "golf",
    "indoor",
    "disused:amenity",
];

/// Values of area keys that are lines all the same.
const LINEAR_VALUES: &[(&str, &str)] = &[
    ("natural", "coastline"),
    ("natural", "cliff"),
    ("natural", "ridge"),
    ("natural", "arete"),
    ("natural", "tree_row"),
    ("natural", "valley"),
    ("natural", "earth_bank"),
    ("natural", "gorge"),
    ("leisure", "track"),
    ("leisure", "slipway"),
    ("aeroway", "runway"),
    ("aeroway", "taxiway"),
    ("aeroway", "parking_position"),
    ("man_made", "pier"),
    ("man_made", "breakwater"),
    ("man_made", "groyne"),
    ("man_made", "embankment"),
    ("man_made", "cutline"),
    ("man_made", "pipeline"),
    ("man_made", "dyke"),
    ("amenity", "bench"),
];

/// Keys that make an area only for these values.
const AREA_VALUES: &[(&str, &[&str])] = &[
    (
        "waterway",
        &["riverbank", "dock", "boatyard", "dam", "fuel"],
    ),
    (
        "railway",
        &["platform", "station", "turntable", "roundhouse"],
    ),
    (
        "power",
        &["plant", "substation", "generator", "transformer"],
    ),
    ("highway", &["services", "rest_area", "platform"]),
    ("public_transport", &["platform", "station"]),
    ("barrier", &["city_wall"]),
];

/// True when a closed way with these tags is an area.
pub fn is_area(tags: &Tags) -> bool {
    match tags.get("area") {
        Some("yes") => return true,
        Some("no") => return false,
        _ => {}
    }
    let has = |key: &str| tags.get(key).is_some_and(|v| v != "no");
    let area_key = AREA_KEYS.iter().any(|&key| {
        has(key)
            && !LINEAR_VALUES
                .iter()
                .any(|&(k, v)| k == key && tags.get(k) == Some(v))
    });
    area_key
        || AREA_VALUES
            .iter()
            .any(|&(key, values)| tags.get(key).is_some_and(|v| values.contains(&v)))
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::osm::tags;

    #[test]
    fn tags_decide_between_area_and_closed_line() {
        assert!(is_area(&tags(&[("building", "yes")])));
        assert!(is_area(&tags(&[("landuse", "grass")])));
        assert!(is_area(&tags(&[("natural", "water")])));
        assert!(is_area(&tags(&[("waterway", "riverbank")])));
        assert!(is_area(&tags(&[
            ("highway", "pedestrian"),
            ("area", "yes")
        ])));
        assert!(!is_area(&tags(&[("highway", "residential")])));
        assert!(!is_area(&tags(&[
            ("junction", "roundabout"),
            ("highway", "primary")
        ])));
        assert!(!is_area(&tags(&[("barrier", "hedge")])));
        assert!(!is_area(&tags(&[("natural", "coastline")])));
        assert!(!is_area(&tags(&[("natural", "tree_row")])));
        assert!(!is_area(&tags(&[("waterway", "stream")])));
        assert!(!is_area(&tags(&[("building", "yes"), ("area", "no")])));
        assert!(!is_area(&tags(&[("building", "no")])));
        assert!(!is_area(&tags(&[])));
    }
}
