//! What tags say about bridges and tunnels: which ways are part of one, and the measures the
//! elevation solver and the geometry take from them (thesis §4.2, with defaults where the tags
//! are silent).
//!
//! Maximum inclines by class. The thesis used one 35 % bound for every way; design guides are
//! much stricter for fast roads and for railways, and a bound that is too loose lets a ramp
//! come out implausibly steep, one that is too tight makes real steep streets (Monaco has many)
//! report violations. The values are near the upper ends of European guides: motorways 6 %,
//! trunk and primary roads 8 %, secondary and tertiary 10 %, minor and service roads 15 %,
//! tracks 20 %, paths and footways 25 % (ramps for people), steps none; main-line railways
//! 4 %, light rail and trams 8 %, funiculars none.

use std::collections::HashMap;

use crate::osm::structures::{Group, StructureKind};
use crate::osm::units::parse_length_m;
use crate::osm::{ElementRef, ElementType, Tags, Way};
use crate::tile::TileId;

use super::roads::Paving;
use super::{railways, roads, FeatureClass, FeatureSet, FeatureSettings, Projection};

/// Whether a way is part of a bridge or a tunnel that is drawn as such, with its layer (`1` for
/// an untagged bridge, `-1` for an untagged tunnel, as OSM reads them).
pub fn classify(tags: &Tags) -> Option<(StructureKind, i32)> {
    let carries = tags
        .get("highway")
        .is_some_and(|h| roads::default_width_m(h).is_some())
        || tags.get("railway").is_some_and(railways::drawn);
    if !carries || tags.get("area") == Some("yes") {
        return None;
    }
    let layer = layer(tags);
    if tags.is_set("bridge") {
        Some((StructureKind::Bridge, layer.unwrap_or(1)))
    } else if is_tunnel(tags) {
        Some((StructureKind::Tunnel, layer.unwrap_or(-1)))
    } else {
        None
    }
}

/// True for a way under the ground: `tunnel=*` but a passage through a building, which runs
/// on the ground.
fn is_tunnel(tags: &Tags) -> bool {
    tags.is_set("tunnel") && tags.get("tunnel") != Some("building_passage")
}

/// The `layer` tag, if it is a whole number.
pub fn layer(tags: &Tags) -> Option<i32> {
    tags.get("layer").and_then(|l| l.trim().parse::<i32>().ok())
}

/// True for footways, paths, cycleways and steps: light structures, people-sized clearances.
fn is_for_people(tags: &Tags) -> bool {
    matches!(
        tags.get("highway"),
        Some("footway" | "path" | "cycleway" | "steps" | "bridleway" | "pedestrian")
    )
}

/// The width of a structure's way in metres.
pub fn width_m(tags: &Tags, settings: &FeatureSettings) -> f64 {
    if tags.get("railway").is_some() {
        return tags
            .get("width")
            .and_then(parse_length_m)
            .filter(|w| (0.5..=30.0).contains(w))
            .unwrap_or_else(|| railways::width_m(tags.get("gauge"), railways::is_embedded(tags)));
    }
    roads::width_m(tags, settings).unwrap_or(5.0)
}

/// Thickness of a bridge deck below its surface, metres.
pub fn deck_thickness_m(tags: &Tags) -> f64 {
    if is_for_people(tags) {
        0.5
    } else {
        1.2
    }
}

/// Free height inside a tunnel, metres: `maxheight`, else a default for what runs in it
/// (road vehicles 4.5 m, electrified railways 6 m, people 2.5 m).
pub fn tunnel_height_m(tags: &Tags) -> f64 {
    if let Some(h) = maxheight_m(tags) {
        return h;
    }
    if tags.get("railway").is_some() {
        6.0
    } else if is_for_people(tags) {
        2.5
    } else {
        4.5
    }
}

/// Thickness of a tunnel's roof above its free height, metres.
pub const TUNNEL_ROOF_M: f64 = 0.5;

/// `maxheight` (or `maxheight:physical`) in metres, if plausible.
fn maxheight_m(tags: &Tags) -> Option<f64> {
    ["maxheight:physical", "maxheight"]
        .iter()
        .filter_map(|k| tags.get(k))
        .find_map(parse_length_m)
        .filter(|h| (1.5..=12.0).contains(h))
}

/// The free height a bridge must leave over a way it crosses, metres: the way's `maxheight`,
/// else a default for what the way carries; `None` for what a bridge need not clear (ways that
/// are themselves in a tunnel, proposed or abandoned ways).
pub fn clearance_over_m(tags: &Tags) -> Option<f64> {
    if tags.is_set("tunnel") {
        return None;
    }
    if let Some(railway) = tags.get("railway") {
        return railways::drawn(railway).then(|| {
            maxheight_m(tags).unwrap_or(match railway {
                "tram" | "light_rail" => 4.5,
                _ => 5.5,
            })
        });
    }
    if let Some(highway) = tags.get("highway") {
        roads::default_width_m(highway)?;
        return Some(maxheight_m(tags).unwrap_or(if is_for_people(tags) { 2.5 } else { 4.5 }));
    }
    match tags.get("waterway")? {
        "river" | "canal" => Some(3.0),
        "stream" | "tidal_channel" => Some(1.0),
        "drain" | "ditch" => Some(0.5),
        _ => None,
    }
}

/// Tunnel roofs stay this far under a building, metres (a foundation slab and footings), and
/// a storey deeper for each underground level.
pub const FOUNDATION_DEPTH_M: f64 = 3.0;
/// A storey below ground, metres.
const UNDERGROUND_LEVEL_M: f64 = 3.0;
/// Tunnel roofs stay this far under a tree, metres (its roots).
pub const ROOT_DEPTH_M: f64 = 1.5;

/// How deep what the tags describe reaches into the ground (a building's foundations and
/// underground levels, a tree's roots), `None` for what does not.
pub fn foundation_depth_m(tags: &Tags) -> Option<f64> {
    if tags.get("natural") == Some("tree") {
        return Some(ROOT_DEPTH_M);
    }
    let building = tags.get("building")?;
    if building == "no" || tags.get("location") == Some("underground") {
        return None;
    }
    let underground = tags
        .get("building:levels:underground")
        .and_then(crate::osm::units::parse_count)
        .filter(|l| (0.0..=10.0).contains(l))
        .unwrap_or(0.0);
    Some(FOUNDATION_DEPTH_M + underground.round() * UNDERGROUND_LEVEL_M)
}

/// The steepest grade (rise per run) a way may have, `None` for no bound.
pub fn max_incline(tags: &Tags) -> Option<f64> {
    if let Some(railway) = tags.get("railway") {
        return match railway {
            "funicular" | "rack" => None,
            "tram" | "light_rail" | "subway" | "monorail" | "miniature" => Some(0.08),
            _ if tags.is_set("rack") => None,
            _ => Some(0.04),
        };
    }
    match tags.get("highway")? {
        "steps" => None,
        "motorway" | "motorway_link" => Some(0.06),
        "trunk" | "trunk_link" | "primary" | "primary_link" => Some(0.08),
        "secondary" | "secondary_link" | "tertiary" | "tertiary_link" => Some(0.10),
        "track" => Some(0.20),
        "footway" | "path" | "cycleway" | "bridleway" | "pedestrian" => Some(0.25),
        _ => Some(0.15),
    }
}

/// What `incline=*` says of a way's grade along its direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Incline {
    /// Rises (or, negative, falls) by this much per metre.
    Grade(f64),
    Up,
    Down,
}

/// Parses `incline=*`: `10%`, `-5 %`, `3°`, a bare number as percent (`12`), `up`, `down`;
/// `None` for anything else (and for grades steeper than 100 %, taken as mistakes). A grade
/// is the steepest the way gets, its sign the way it rises.
pub fn incline(tags: &Tags) -> Option<Incline> {
    let value = tags.get("incline")?.trim();
    match value {
        "up" => return Some(Incline::Up),
        "down" => return Some(Incline::Down),
        _ => {}
    }
    let grade = if let Some(percent) = value.strip_suffix('%') {
        percent.trim().parse::<f64>().ok()? / 100.0
    } else if let Some(degrees) = value.strip_suffix('°') {
        degrees.trim().parse::<f64>().ok()?.to_radians().tan()
    } else {
        value.parse::<f64>().ok()? / 100.0
    };
    (grade.is_finite() && grade.abs() <= 1.0).then_some(Incline::Grade(grade))
}

/// The paving a structure's way shows: its road's, or `None` for a railway.
pub fn paving_of(way: &Way) -> Option<Paving> {
    way.tags
        .get("highway")
        .is_some()
        .then(|| Paving::from_tags(&way.tags))
}

/// Free height inside a tunnel along `way`, metres (see [`tunnel_height_m`]).
pub fn tunnel_height_of(way: &Way) -> f64 {
    tunnel_height_m(&way.tags)
}

/// What the tags say of a way's grade: the steepest it may be, and `incline=*`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Slope {
    pub max_incline: Option<f64>,
    pub incline: Option<Incline>,
}

impl Slope {
    pub fn of(way: &Way) -> Slope {
        let tags = &way.tags;
        Slope {
            max_incline: max_incline(tags),
            incline: incline(tags),
        }
    }
}

/// What the tags say of a way that settling and drawing bridges and tunnels needs, read once:
/// the way a structure is made of, or one it passes over.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WayTraits {
    /// Carries rails (else a road or a path).
    pub railway: bool,
    /// `layer=*`, 0 when untagged.
    pub layer: i32,
    pub width_m: f64,
    /// From a bridge's deck to its underside.
    pub deck_thickness_m: f64,
    /// Free height inside a tunnel.
    pub tunnel_height_m: f64,
    /// The free height a bridge must leave over this way, `None` for none.
    pub clearance_m: Option<f64>,
    pub slope: Slope,
    /// The road's paving, `None` for a railway.
    pub paving: Option<Paving>,
}

impl WayTraits {
    pub fn of(way: &Way, settings: &FeatureSettings) -> WayTraits {
        let tags = &way.tags;
        WayTraits {
            railway: tags.get("railway").is_some(),
            layer: layer(tags).unwrap_or(0),
            width_m: width_m(tags, settings),
            deck_thickness_m: deck_thickness_m(tags),
            tunnel_height_m: tunnel_height_m(tags),
            clearance_m: clearance_over_m(tags),
            slope: Slope::of(way),
            paving: paving_of(way),
        }
    }
}

/// True for ways drawn below or away from the ground surface (bridges and tunnels are drawn as
/// structures of their own).
pub fn is_off_ground(tags: &Tags) -> bool {
    is_tunnel(tags)
        || classify(tags).is_some()
        || tags.get("indoor").is_some_and(|v| v != "no")
        || tags.get("location") == Some("underground")
        || tags.get("area") == Some("yes")
}

/// How far beyond the tile a structure way may lie and still be drawn in it (its half width),
/// metres.
const STRUCTURE_REACH_M: f64 = 30.0;

/// Adds a feature row for each bridge or tunnel way that reaches into the tile, and one for
/// the lines painted on it where its tags call for any ([`super::markings::lane_plan`]);
/// returns the rows by way index.
pub fn rows(
    set: &mut FeatureSet,
    groups: &[&Group],
    all_ways: &[Way],
    tile: TileId,
) -> HashMap<u32, u32> {
    let projection = Projection::new(tile.z);
    let rect = super::tile_rect(tile);
    let mut rows = HashMap::new();
    for group in groups {
        for chain in &group.chains {
            let class = match chain.kind {
                StructureKind::Bridge => FeatureClass::Bridge,
                StructureKind::Tunnel => FeatureClass::Tunnel,
            };
            for chain_way in &chain.ways {
                let Some(way) = all_ways.get(chain_way.way as usize) else {
                    continue;
                };
                if rows.contains_key(&chain_way.way) {
                    continue;
                }
                if reaches(way, &projection, &rect) {
                    let element = ElementRef {
                        element_type: ElementType::Way,
                        id: way.id,
                    };
                    rows.insert(
                        chain_way.way,
                        set.add_feature(Some(element), class, &way.tags),
                    );
                    if let Some(plan) = super::markings::lane_plan(&way.tags) {
                        let painted = set.add_feature(
                            Some(element),
                            FeatureClass::Marking,
                            &super::markings::painting_tags(&way.tags),
                        );
                        set.structure_lines.insert(chain_way.way, (painted, plan));
                    }
                }
            }
        }
    }
    rows
}

/// True for a group with a way that reaches into the tile: a group without one is neither
/// drawn there nor cuts its ground.
pub fn group_reaches(group: &Group, all_ways: &[Way], tile: TileId) -> bool {
    let projection = Projection::new(tile.z);
    let rect = super::tile_rect(tile);
    group
        .chains
        .iter()
        .flat_map(|chain| &chain.ways)
        .filter_map(|chain_way| all_ways.get(chain_way.way as usize))
        .any(|way| reaches(way, &projection, &rect))
}

/// True for a way within [`STRUCTURE_REACH_M`] of `rect` (the tile, projected).
fn reaches(way: &Way, projection: &Projection, rect: &crate::geometry::Rect) -> bool {
    let Some(first) = way.positions.first() else {
        return false;
    };
    let reach = projection.metres(STRUCTURE_REACH_M, first.lat);
    let near = crate::geometry::Rect::around(&projection.points(&way.positions));
    near.min[0] - reach <= rect.max[0]
        && near.max[0] + reach >= rect.min[0]
        && near.min[1] - reach <= rect.max[1]
        && near.max[1] + reach >= rect.min[1]
}

/// Adds the row of a tunnel's approach cut: the element of the structure way's row
/// `structure_row`, drawn as `class` with `way`'s tags.
pub fn add_cut_row(
    set: &mut FeatureSet,
    structure_row: u32,
    class: FeatureClass,
    way: &Way,
) -> u32 {
    let element = set.features[structure_row as usize].element;
    set.add_feature(element, class, &way.tags)
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::osm::tags;

    use crate::osm::LonLat;

    /// Three tunnel ways joined end to end around the tile 14/8529/5974, `gap` degrees
    /// outside its west, north and east sides (inside where negative), from south of it.
    fn tunnel_around(gap: f64) -> (TileId, Vec<Way>) {
        let tile = TileId {
            z: 14,
            x: 8529,
            y: 5974,
        };
        let b = tile.bounds();
        let (west, east, north) = (b.west - gap, b.east + gap, b.north + gap.abs());
        let corners = [
            LonLat {
                lon: west,
                lat: b.south - 0.001,
            },
            LonLat {
                lon: west,
                lat: north,
            },
            LonLat {
                lon: east,
                lat: north,
            },
            LonLat {
                lon: east,
                lat: b.south - 0.001,
            },
        ];
        let ways = (0..3)
            .map(|k| Way {
                id: k as i64 + 1,
                tags: crate::osm::tags(&[("highway", "primary"), ("tunnel", "yes")]),
                nodes: vec![k as i64 + 10, k as i64 + 11],
                positions: vec![corners[k], corners[k + 1]],
            })
            .collect();
        (tile, ways)
    }

    #[test]
    fn a_group_reaches_a_tile_exactly_when_the_tile_draws_one_of_its_ways() {
        for (gap, reaches) in [(0.005, false), (-0.001, true)] {
            let (tile, ways) = tunnel_around(gap);
            let groups = crate::osm::structures::find(&ways, classify);
            assert_eq!(groups.len(), 1, "one group of three ways");
            let group = &groups[0];
            let b = tile.bounds();
            let spans = group.bounds.west < b.west && group.bounds.east > b.east;
            assert!(spans || reaches, "the group's box spans the tile");
            assert_eq!(group_reaches(group, &ways, tile), reaches, "gap {gap}");
            let drawn = rows(&mut FeatureSet::default(), &[group], &ways, tile);
            assert_eq!(!drawn.is_empty(), reaches, "gap {gap}");
        }
    }

    #[test]
    fn bridges_and_tunnels_take_their_layers() {
        assert_eq!(
            classify(&tags(&[("highway", "primary"), ("bridge", "viaduct")])),
            Some((StructureKind::Bridge, 1))
        );
        assert_eq!(
            classify(&tags(&[
                ("railway", "rail"),
                ("tunnel", "yes"),
                ("layer", "-3")
            ])),
            Some((StructureKind::Tunnel, -3))
        );
        for not_one in [
            &[("highway", "primary"), ("bridge", "no")][..],
            &[("highway", "footway"), ("tunnel", "building_passage")],
            &[("waterway", "stream"), ("tunnel", "culvert")],
            &[("highway", "proposed"), ("bridge", "yes")],
        ] {
            assert_eq!(classify(&tags(not_one)), None, "{not_one:?}");
        }
    }

    #[test]
    fn inclines_parse_in_percent_and_degrees() {
        let parse = |v: &str| incline(&tags(&[("incline", v)]));
        assert_eq!(parse("10%"), Some(Incline::Grade(0.10)));
        assert_eq!(parse("-5 %"), Some(Incline::Grade(-0.05)));
        assert_eq!(parse("up"), Some(Incline::Up));
        let Some(Incline::Grade(g)) = parse("45°") else {
            panic!("degrees");
        };
        assert!((g - 1.0).abs() < 1e-12);
        assert_eq!(parse("12"), Some(Incline::Grade(0.12)));
        assert_eq!(parse("steep"), None);
        assert_eq!(parse("300%"), None);
    }

    #[test]
    fn clearances_come_from_maxheight_or_what_is_below() {
        assert_eq!(
            clearance_over_m(&tags(&[("highway", "primary")])),
            Some(4.5)
        );
        assert_eq!(
            clearance_over_m(&tags(&[("highway", "primary"), ("maxheight", "3.8")])),
            Some(3.8)
        );
        assert_eq!(clearance_over_m(&tags(&[("railway", "rail")])), Some(5.5));
        assert_eq!(
            clearance_over_m(&tags(&[("waterway", "stream")])),
            Some(1.0)
        );
        assert_eq!(
            clearance_over_m(&tags(&[("highway", "primary"), ("tunnel", "yes")])),
            None
        );
        assert_eq!(clearance_over_m(&tags(&[("waterway", "dam")])), None);
    }
}
