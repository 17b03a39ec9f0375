//! Facades: what a building's walls show, from its tags and its size.
//!
//! A facade is a rhythm of bays (a window and the wall beside it) across each wall and levels
//! up it; the glazing says what fills a bay. Houses, flats and hotels have windows punched in
//! the wall; offices, schools and hospitals wide windows between narrow piers; a shop, a café or
//! a retail building has shop windows on its ground floor; a glass building is a curtain wall.
//! Garages, sheds, tanks, single-storey industrial halls and farm buildings have blank walls,
//! as do buildings too small to live in; halls and farm buildings of two levels or more have
//! windows.

use super::inference::Footprint;
use super::FeatureSettings;
use crate::geometry::{Point, Polygon, Rect};
use crate::osm::units::{parse_count, parse_length_m};
use crate::osm::Tags;

/// What fills a bay of a facade: each glazing is a material of its own, textured one bay wide
/// and one level high.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Glazing {
    /// A window punched in the wall, one a bay: houses, flats, hotels, churches.
    Punched,
    /// Wide windows between narrow piers: offices, schools, hospitals, multi-storey halls.
    Ribbon,
    /// Shop windows from nearly the floor to under the fascia.
    Shopfront,
    /// Glass from floor to floor between mullions.
    CurtainWall,
}

impl Glazing {
    pub const ALL: [Glazing; 4] = [
        Glazing::Punched,
        Glazing::Ribbon,
        Glazing::Shopfront,
        Glazing::CurtainWall,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            Glazing::Punched => "punched",
            Glazing::Ribbon => "ribbon",
            Glazing::Shopfront => "shopfront",
            Glazing::CurtainWall => "curtain_wall",
        }
    }

    /// The width of a bay of this glazing when nothing else decides it, metres.
    pub fn bay_m(self) -> f64 {
        match self {
            Glazing::Punched => 3.2,
            Glazing::Ribbon => 3.0,
            Glazing::Shopfront => 4.5,
            Glazing::CurtainWall => 3.0,
        }
    }
}

/// What a building's walls show.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Facade {
    /// The glazing of every level but the ground floor's (and of the ground floor too when
    /// `ground` is `None`); `None` for blank walls.
    pub upper: Option<Glazing>,
    /// The ground floor's own glazing, when it differs (shop windows).
    pub ground: Option<Glazing>,
    /// The height of a level, metres: the walls take the whole number of levels nearest it.
    pub level_m: f64,
    /// The width of a bay of the upper levels, metres: each wall takes the whole number of
    /// bays nearest it.
    pub bay_m: f64,
}

impl Facade {
    /// Whether the walls show anything but wall.
    pub fn is_glazed(&self) -> bool {
        self.upper.is_some() || self.ground.is_some()
    }
}

/// Smaller than this (square metres), a building is a shed or a kiosk without windows of its own.
const SMALLEST_GLAZED_M2: f64 = 20.0;
/// An untagged building this large (square metres) is more likely a shop, office or hall than a
/// house: wide windows.
const LARGE_UNTAGGED_M2: f64 = 1000.0;
/// Level heights (metres) for a building whose height is tagged without its levels.
const CHURCH_LEVEL_M: f64 = 7.0;
const HALL_LEVEL_M: f64 = 4.5;
const OFFICE_LEVEL_M: f64 = 3.5;
/// A level is no lower and no higher than these (metres) when height over levels gives it.
const LEVEL_RANGE_M: (f64, f64) = (2.4, 8.0);

/// Types whose walls are blank whatever their size.
fn is_blank(building: &str) -> bool {
    matches!(
        building,
        "garage"
            | "garages"
            | "carport"
            | "shed"
            | "roof"
            | "storage_tank"
            | "tank"
            | "silo"
            | "bunker"
            | "transformer_tower"
            | "water_tower"
            | "service"
            | "ruins"
            | "bridge"
            | "container"
            | "tent"
            | "digester"
    )
}

/// Halls: blank walls on one level, wide windows above.
fn is_hall(building: &str) -> bool {
    matches!(
        building,
        "industrial" | "warehouse" | "manufacture" | "factory" | "hangar" | "sports_hall"
    )
}

/// Farm buildings: blank walls on one level (a shed, a stall), small windows on the walls of
/// two levels or more (the gables stay blank).
fn is_farm_building(building: &str) -> bool {
    matches!(
        building,
        "barn" | "cowshed" | "stable" | "sty" | "farm_auxiliary"
    )
}

/// Types with wide windows.
fn is_ribbon(building: &str) -> bool {
    matches!(
        building,
        "office"
            | "commercial"
            | "retail"
            | "supermarket"
            | "school"
            | "university"
            | "college"
            | "kindergarten"
            | "hospital"
            | "public"
            | "civic"
            | "government"
            | "train_station"
            | "transportation"
            | "parking"
    )
}

fn is_worship(building: &str) -> bool {
    matches!(
        building,
        "church" | "chapel" | "cathedral" | "mosque" | "temple" | "synagogue" | "shrine"
    )
}

/// Whether the ground floor is a shop, a café or a bank: shop windows.
fn has_shop(tags: &Tags, building: &str) -> bool {
    matches!(building, "retail" | "supermarket" | "kiosk" | "commercial") || is_shop(tags)
}

/// Whether tags (a building's, or a node's inside one) map a shop, a café, a bank…
pub fn is_shop(tags: &Tags) -> bool {
    tags.is_set("shop")
        || matches!(
            tags.get("amenity"),
            Some(
                "restaurant"
                    | "cafe"
                    | "bar"
                    | "pub"
                    | "fast_food"
                    | "bank"
                    | "pharmacy"
                    | "ice_cream"
            )
        )
}

impl Facade {
    /// The facade of a building with a shop mapped inside it (a node): shop windows on its
    /// ground floor, where its walls have windows at all and are not glass.
    pub fn with_shop_inside(mut self) -> Facade {
        if self.ground.is_none() && matches!(self.upper, Some(Glazing::Punched | Glazing::Ribbon)) {
            self.ground = Some(Glazing::Shopfront);
        }
        self
    }
}

/// The widest building, metres and degrees of longitude across its bounds, whose shops mapped
/// as nodes inside it give it shop windows: every tile that draws a building this small reads
/// the nodes inside it (a tile reads the nodes within `QUERY_MARGIN_DEG`, 0.002°, of its
/// edges), so all agree on its facade.
pub const WIDEST_WITH_SHOP_NODES_M: f64 = 150.0;
pub const WIDEST_WITH_SHOP_NODES_DEG: f64 = 0.0018;

/// Whether a shop node (`shops`, global tile units) lies inside one of a building's
/// `footprints`, when the building is at most `widest` (tile units) across, small enough for
/// every tile that draws it to see them.
pub fn has_shop_inside(footprints: &[Polygon], shops: &[Point], widest: f64) -> bool {
    if shops.is_empty() {
        return false;
    }
    let Some(bounds) = Rect::around_all(footprints) else {
        return false;
    };
    let across = (bounds.max[0] - bounds.min[0]).max(bounds.max[1] - bounds.min[1]);
    if across > widest {
        return false;
    }
    shops
        .iter()
        .any(|&p| bounds.contains(p) && footprints.iter().any(|f| f.contains(p)))
}

/// The facade of a building (or part) from its tags and its footprint (`None` when it could
/// not be measured), with the levels its height counts (`None` when nothing gives them).
pub fn facade(
    tags: &Tags,
    footprint: Option<&Footprint>,
    levels: Option<f64>,
    settings: &FeatureSettings,
) -> Facade {
    let building = tags
        .get("building")
        .filter(|b| *b != "yes")
        .or_else(|| tags.get("building:part"))
        .unwrap_or("yes");
    let area = footprint.map_or(f64::INFINITY, |f| f.area_m2);
    let glass = matches!(tags.get("building:material"), Some("glass" | "mirror"));
    let several_levels = levels.is_some_and(|l| l >= 2.0);
    let upper = if glass {
        Some(Glazing::CurtainWall)
    } else if is_blank(building) || area < SMALLEST_GLAZED_M2 || building == "kiosk" {
        None
    } else if is_hall(building) {
        several_levels.then_some(Glazing::Ribbon)
    } else if is_farm_building(building) {
        several_levels.then_some(Glazing::Punched)
    } else if is_ribbon(building) || (building == "yes" && area >= LARGE_UNTAGGED_M2) {
        Some(Glazing::Ribbon)
    } else {
        Some(Glazing::Punched)
    };
    let ground =
        (!glass && has_shop(tags, building) && !is_blank(building)).then_some(Glazing::Shopfront);
    let worship = is_worship(building);
    Facade {
        upper,
        ground,
        level_m: level_m(tags, building, settings),
        bay_m: if worship {
            4.0
        } else {
            upper.map_or(Glazing::Punched.bay_m(), Glazing::bay_m)
        },
    }
}

/// The height of a level: the tagged height over the tagged levels, the configured level
/// height where the levels give the height, else one by type.
fn level_m(tags: &Tags, building: &str, settings: &FeatureSettings) -> f64 {
    let height = tags.get("height").and_then(parse_length_m);
    let levels = tags
        .get("building:levels")
        .and_then(parse_count)
        .filter(|l| *l >= 1.0);
    let roof_levels = tags
        .get("roof:levels")
        .and_then(parse_count)
        .filter(|l| *l >= 0.0)
        .unwrap_or(0.0);
    match (height, levels) {
        (Some(height), Some(levels)) => {
            (height / (levels + roof_levels)).clamp(LEVEL_RANGE_M.0, LEVEL_RANGE_M.1)
        }
        (Some(_), None) if is_worship(building) => CHURCH_LEVEL_M,
        (Some(_), None) if is_hall(building) || matches!(building, "retail" | "supermarket") => {
            HALL_LEVEL_M
        }
        (Some(_), None) if is_ribbon(building) => OFFICE_LEVEL_M,
        _ if is_worship(building) && levels.is_none() => CHURCH_LEVEL_M,
        _ => settings.level_height_m,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::osm::tags;

    fn house(area_m2: f64) -> Footprint {
        Footprint {
            area_m2,
            corners: 4,
            rectilinear: true,
            elongation: 1.5,
        }
    }

    #[test]
    fn houses_and_flats_have_windows_garages_and_sheds_none() {
        let s = FeatureSettings::default();
        let of = |pairs: &[(&str, &str)], area| facade(&tags(pairs), Some(&house(area)), None, &s);
        assert_eq!(
            of(&[("building", "house")], 90.0).upper,
            Some(Glazing::Punched)
        );
        assert_eq!(
            of(&[("building", "yes")], 120.0).upper,
            Some(Glazing::Punched)
        );
        assert_eq!(
            of(&[("building", "apartments")], 400.0).upper,
            Some(Glazing::Punched)
        );
        assert_eq!(
            of(&[("building", "office")], 400.0).upper,
            Some(Glazing::Ribbon)
        );
        for blank in ["garage", "shed", "barn", "stable", "storage_tank", "roof"] {
            let facade = of(&[("building", blank)], 60.0);
            assert!(!facade.is_glazed(), "{blank}: {facade:?}");
        }
        // Too small to have a window of its own.
        assert!(!of(&[("building", "yes")], 12.0).is_glazed());
    }

    #[test]
    fn an_industrial_hall_is_blank_on_one_level_and_glazed_on_several() {
        let s = FeatureSettings::default();
        let hall = tags(&[("building", "industrial")]);
        assert_eq!(
            facade(&hall, Some(&house(3000.0)), Some(1.0), &s).upper,
            None
        );
        assert_eq!(facade(&hall, Some(&house(3000.0)), None, &s).upper, None);
        assert_eq!(
            facade(&hall, Some(&house(3000.0)), Some(3.0), &s).upper,
            Some(Glazing::Ribbon)
        );
    }

    #[test]
    fn a_barn_of_two_levels_has_windows() {
        let s = FeatureSettings::default();
        let barn = tags(&[("building", "barn")]);
        assert_eq!(
            facade(&barn, Some(&house(200.0)), Some(1.0), &s).upper,
            None
        );
        assert_eq!(
            facade(&barn, Some(&house(200.0)), Some(2.0), &s).upper,
            Some(Glazing::Punched)
        );
    }

    #[test]
    fn a_shop_on_the_ground_floor_has_shop_windows_under_the_flats() {
        let s = FeatureSettings::default();
        let shop = facade(
            &tags(&[("building", "apartments"), ("shop", "bakery")]),
            Some(&house(300.0)),
            Some(5.0),
            &s,
        );
        assert_eq!(shop.ground, Some(Glazing::Shopfront));
        assert_eq!(shop.upper, Some(Glazing::Punched));
        let retail = facade(&tags(&[("building", "retail")]), None, None, &s);
        assert_eq!(retail.ground, Some(Glazing::Shopfront));
        let kiosk = facade(&tags(&[("building", "kiosk")]), Some(&house(8.0)), None, &s);
        assert_eq!(
            (kiosk.upper, kiosk.ground),
            (None, Some(Glazing::Shopfront))
        );
    }

    #[test]
    fn a_glass_building_is_a_curtain_wall_even_with_a_shop() {
        let s = FeatureSettings::default();
        let glass = facade(
            &tags(&[
                ("building", "office"),
                ("building:material", "glass"),
                ("shop", "yes"),
            ]),
            None,
            None,
            &s,
        );
        assert_eq!(
            (glass.upper, glass.ground),
            (Some(Glazing::CurtainWall), None)
        );
    }

    #[test]
    fn levels_are_the_tagged_height_over_the_tagged_levels_within_reason() {
        let s = FeatureSettings::default();
        let level = |pairs: &[(&str, &str)]| facade(&tags(pairs), None, None, &s).level_m;
        assert_eq!(
            level(&[
                ("building", "yes"),
                ("height", "16"),
                ("building:levels", "4")
            ]),
            4.0
        );
        assert_eq!(
            level(&[
                ("building", "house"),
                ("height", "9"),
                ("building:levels", "2"),
                ("roof:levels", "1")
            ]),
            3.0
        );
        // A nonsense ratio is held to a plausible level.
        assert_eq!(
            level(&[
                ("building", "yes"),
                ("height", "3"),
                ("building:levels", "9")
            ]),
            2.4
        );
        assert_eq!(
            level(&[("building", "yes"), ("building:levels", "-3")]),
            s.level_height_m
        );
        assert_eq!(
            level(&[("building", "church"), ("height", "20")]),
            CHURCH_LEVEL_M
        );
        assert_eq!(level(&[("building", "house")]), s.level_height_m);
    }

    #[test]
    fn a_shop_node_inside_a_small_building_gives_it_shop_windows() {
        let square = |x0: f64, side: f64| Polygon {
            outer: vec![[x0, 0.0], [x0 + side, 0.0], [x0 + side, side], [x0, side]],
            holes: Vec::new(),
        };
        let courtyard = Polygon {
            outer: square(0.0, 10.0).outer,
            holes: vec![square(4.0, 2.0)
                .outer
                .iter()
                .map(|p| [p[0], p[1] + 4.0])
                .collect()],
        };
        let widest = 50.0;
        assert!(has_shop_inside(&[square(0.0, 10.0)], &[[5.0, 5.0]], widest));
        assert!(!has_shop_inside(
            &[square(0.0, 10.0)],
            &[[15.0, 5.0]],
            widest
        ));
        assert!(!has_shop_inside(&[courtyard], &[[5.0, 5.0]], widest));
        // Too wide for every tile drawing it to see the node.
        assert!(!has_shop_inside(
            &[square(0.0, 60.0)],
            &[[5.0, 5.0]],
            widest
        ));
        let s = FeatureSettings::default();
        let flats = facade(
            &tags(&[("building", "apartments")]),
            Some(&house(400.0)),
            None,
            &s,
        );
        assert_eq!(flats.ground, None);
        assert_eq!(flats.with_shop_inside().ground, Some(Glazing::Shopfront));
        let garage = facade(
            &tags(&[("building", "garage")]),
            Some(&house(40.0)),
            None,
            &s,
        );
        assert_eq!(garage.with_shop_inside().ground, None);
    }
}
