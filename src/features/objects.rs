//! Objects of street level a simple model describes well enough (paper 001 §4.3): street lamps,
//! benches, bollards, waste baskets, post boxes, fire hydrants, bus stops and shelters, bicycle
//! stands, flagpoles, memorials, traffic signals and stop and give-way signs, power poles and
//! towers, wind turbines, and doors at the entrances mapped on a building's outline. Mapped as
//! nodes, drawn as instances of one model per kind. Signals, signs and bus stops mapped on a
//! road stand at its edge ([`super::carriageways`] places them).

use super::{FeatureClass, FeatureSet, Projection};
use crate::geometry::{Point, Rect};
use crate::osm::index::Selection;
use crate::osm::{ElementRef, ElementType, Tags};

/// A kind of object.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ObjectKind {
    StreetLamp,
    Bench,
    Bollard,
    PowerPole,
    PowerTower,
    WindTurbine,
    WasteBasket,
    PostBox,
    FireHydrant,
    /// A bus stop's pole and sign.
    BusStop,
    /// A bus stop with a shelter (`shelter=yes`).
    BusShelter,
    BicycleParking,
    Flagpole,
    /// A memorial stone (not plaques and stumbling stones, which lie flat).
    Memorial,
    TrafficSignals,
    StopSign,
    GiveWaySign,
    /// A door in a building's wall, at an `entrance=*` node of its outline.
    Door,
}

impl ObjectKind {
    pub const ALL: [ObjectKind; 18] = [
        ObjectKind::StreetLamp,
        ObjectKind::Bench,
        ObjectKind::Bollard,
        ObjectKind::PowerPole,
        ObjectKind::PowerTower,
        ObjectKind::WindTurbine,
        ObjectKind::WasteBasket,
        ObjectKind::PostBox,
        ObjectKind::FireHydrant,
        ObjectKind::BusStop,
        ObjectKind::BusShelter,
        ObjectKind::BicycleParking,
        ObjectKind::Flagpole,
        ObjectKind::Memorial,
        ObjectKind::TrafficSignals,
        ObjectKind::StopSign,
        ObjectKind::GiveWaySign,
        ObjectKind::Door,
    ];

    pub fn from_tags(tags: &Tags) -> Option<ObjectKind> {
        if tags.get("highway") == Some("street_lamp") {
            return Some(ObjectKind::StreetLamp);
        }
        if tags.get("amenity") == Some("bench") || tags.get("leisure") == Some("picnic_table") {
            return Some(ObjectKind::Bench);
        }
        if tags.get("barrier") == Some("bollard") {
            return Some(ObjectKind::Bollard);
        }
        if let Some(kind) = Self::furniture(tags) {
            return Some(kind);
        }
        match tags.get("power") {
            Some("pole") => return Some(ObjectKind::PowerPole),
            Some("tower") => return Some(ObjectKind::PowerTower),
            Some("generator")
                if tags.get("generator:source") == Some("wind")
                    || tags.get("generator:method") == Some("wind_turbine") =>
            {
                return Some(ObjectKind::WindTurbine)
            }
            _ => {}
        }
        None
    }

    /// Street furniture other than lamps, benches and bollards.
    fn furniture(tags: &Tags) -> Option<ObjectKind> {
        match tags.get("highway") {
            Some("bus_stop") if tags.get("shelter") == Some("yes") => {
                return Some(ObjectKind::BusShelter)
            }
            Some("bus_stop") => return Some(ObjectKind::BusStop),
            Some("traffic_signals") => return Some(ObjectKind::TrafficSignals),
            Some("stop") => return Some(ObjectKind::StopSign),
            Some("give_way") => return Some(ObjectKind::GiveWaySign),
            _ => {}
        }
        match tags.get("amenity") {
            Some("waste_basket") => return Some(ObjectKind::WasteBasket),
            Some("post_box") => return Some(ObjectKind::PostBox),
            Some("bicycle_parking") => return Some(ObjectKind::BicycleParking),
            _ => {}
        }
        if tags.get("emergency") == Some("fire_hydrant") {
            let hidden = matches!(tags.get("fire_hydrant:type"), Some("underground" | "wall"));
            return (!hidden).then_some(ObjectKind::FireHydrant);
        }
        if tags.get("man_made") == Some("flagpole") {
            return Some(ObjectKind::Flagpole);
        }
        if tags.get("historic") == Some("memorial") {
            let flat = matches!(
                tags.get("memorial"),
                Some("plaque" | "stolperstein" | "blue_plaque")
            );
            return (!flat).then_some(ObjectKind::Memorial);
        }
        None
    }

    /// Whether the kind, mapped on a road's line, stands at its edge.
    pub fn stands_beside_the_road(self) -> bool {
        matches!(
            self,
            ObjectKind::TrafficSignals
                | ObjectKind::StopSign
                | ObjectKind::GiveWaySign
                | ObjectKind::BusStop
                | ObjectKind::BusShelter
        )
    }

    pub fn as_str(self) -> &'static str {
        match self {
            ObjectKind::StreetLamp => "street_lamp",
            ObjectKind::Bench => "bench",
            ObjectKind::Bollard => "bollard",
            ObjectKind::PowerPole => "power_pole",
            ObjectKind::PowerTower => "power_tower",
            ObjectKind::WindTurbine => "wind_turbine",
            ObjectKind::WasteBasket => "waste_basket",
            ObjectKind::PostBox => "post_box",
            ObjectKind::FireHydrant => "fire_hydrant",
            ObjectKind::BusStop => "bus_stop",
            ObjectKind::BusShelter => "bus_shelter",
            ObjectKind::BicycleParking => "bicycle_parking",
            ObjectKind::Flagpole => "flagpole",
            ObjectKind::Memorial => "memorial",
            ObjectKind::TrafficSignals => "traffic_signals",
            ObjectKind::StopSign => "stop_sign",
            ObjectKind::GiveWaySign => "give_way_sign",
            ObjectKind::Door => "door",
        }
    }

    /// Linear base colour and roughness.
    pub fn material(self) -> ([f32; 4], f32) {
        match self {
            ObjectKind::StreetLamp => ([0.18, 0.19, 0.20, 1.0], 0.5),
            ObjectKind::Bench => ([0.36, 0.24, 0.14, 1.0], 0.8),
            ObjectKind::Bollard => ([0.30, 0.30, 0.31, 1.0], 0.6),
            ObjectKind::PowerPole => ([0.30, 0.22, 0.15, 1.0], 0.9),
            ObjectKind::PowerTower => ([0.55, 0.57, 0.58, 1.0], 0.5),
            ObjectKind::WindTurbine => ([0.85, 0.86, 0.86, 1.0], 0.4),
            ObjectKind::WasteBasket => ([0.10, 0.20, 0.12, 1.0], 0.6),
            ObjectKind::PostBox => ([0.85, 0.62, 0.05, 1.0], 0.5),
            ObjectKind::FireHydrant => ([0.60, 0.05, 0.04, 1.0], 0.5),
            ObjectKind::BusStop => ([0.55, 0.58, 0.60, 1.0], 0.5),
            ObjectKind::BusShelter => ([0.48, 0.52, 0.55, 1.0], 0.3),
            ObjectKind::BicycleParking => ([0.55, 0.56, 0.57, 1.0], 0.4),
            ObjectKind::Flagpole => ([0.80, 0.80, 0.80, 1.0], 0.4),
            ObjectKind::Memorial => ([0.42, 0.41, 0.39, 1.0], 0.9),
            ObjectKind::TrafficSignals => ([0.10, 0.10, 0.11, 1.0], 0.5),
            ObjectKind::StopSign => ([0.62, 0.04, 0.04, 1.0], 0.5),
            ObjectKind::GiveWaySign => ([0.80, 0.78, 0.76, 1.0], 0.5),
            ObjectKind::Door => ([0.17, 0.11, 0.07, 1.0], 0.7),
        }
    }
}

/// Where a signal, sign or bus stop mapped on a road's node stands: beside the road, facing the
/// traffic it is for (a bus stop facing the road).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoadSide {
    pub node: i64,
    /// Global tile units.
    pub at: Point,
    /// Rotation about the vertical of the local frame (counter-clockwise seen from above) that
    /// turns a model facing north to face the oncoming traffic.
    pub rotation: f64,
}

/// The lamps a lit street is drawn with where none are mapped beside it: their places (global
/// tile units) and rotations, laid along the way so every tile lays the same.
#[derive(Debug, Clone, PartialEq)]
pub struct LitWay {
    pub way: ElementRef,
    pub places: Vec<(Point, f64)>,
    /// One metre in tile units where it lies.
    pub metre: f64,
}

/// How near a mapped street lamp stands for a lamp a lit street would be drawn with, metres.
const MAPPED_LAMP_REACH_M: f64 = 25.0;

/// An object to stand on the ground.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointObject {
    pub at: Point,
    pub kind: ObjectKind,
    /// Rotation about the vertical, radians (from `direction` where tagged).
    pub rotation: f64,
    pub feature: u32,
}

/// The facing of a `direction` tag in degrees clockwise from north (compass points too), as a
/// rotation about the vertical of the local frame (counter-clockwise seen from above).
fn direction(tags: &Tags) -> Option<f64> {
    let value = tags.get("direction")?;
    let degrees = match value {
        "N" => 0.0,
        "NE" => 45.0,
        "E" => 90.0,
        "SE" => 135.0,
        "S" => 180.0,
        "SW" => 225.0,
        "W" => 270.0,
        "NW" => 315.0,
        other => other.trim().parse::<f64>().ok().filter(|d| d.is_finite())?,
    };
    Some(-degrees.to_radians())
}

/// Adds the objects mapped as nodes of `selection` that lie in `rect`; the signals and signs a
/// road placed at its edges (`road_sides`) stand there instead, one feature for the places of a
/// node. Then the lamps of `lit` streets that lie in `rect` and stand clear of every mapped
/// street lamp, one feature a way (its element, tagged as the lamps it stands for).
pub(super) fn collect(
    set: &mut FeatureSet,
    selection: &Selection<'_>,
    projection: &Projection,
    rect: &Rect,
    (road_sides, lit): (&[RoadSide], &[LitWay]),
) {
    collect_mapped(set, selection, projection, rect, road_sides);
    collect_doors(set, selection, projection, rect);
    let mapped: Vec<Point> = selection
        .nodes
        .iter()
        .filter(|n| ObjectKind::from_tags(&n.tags) == Some(ObjectKind::StreetLamp))
        .map(|n| projection.point(n.position))
        .collect();
    let lamp_tags = Tags::from_pairs([("highway", "street_lamp")]);
    for street in lit {
        let reach = MAPPED_LAMP_REACH_M * street.metre;
        let clear = |p: &Point| {
            mapped
                .iter()
                .all(|m| (m[0] - p[0]).hypot(m[1] - p[1]) >= reach)
        };
        let places: Vec<&(Point, f64)> = street
            .places
            .iter()
            .filter(|(at, _)| rect.owns(*at) && clear(at))
            .collect();
        if places.is_empty() {
            continue;
        }
        let feature = set.add_feature(Some(street.way), FeatureClass::Object, &lamp_tags);
        for &(at, rotation) in places {
            set.objects.push(PointObject {
                at,
                kind: ObjectKind::StreetLamp,
                rotation,
                feature,
            });
        }
    }
}

/// The objects mapped as nodes: at their node, or where `road_sides` places them.
fn collect_mapped(
    set: &mut FeatureSet,
    selection: &Selection<'_>,
    projection: &Projection,
    rect: &Rect,
    road_sides: &[RoadSide],
) {
    for node in &selection.nodes {
        let Some(kind) = ObjectKind::from_tags(&node.tags) else {
            continue;
        };
        let beside: Vec<(Point, f64)> = road_sides
            .iter()
            .filter(|s| kind.stands_beside_the_road() && s.node == node.id)
            .map(|s| (s.at, s.rotation))
            .collect();
        let places = if beside.is_empty() {
            vec![(
                projection.point(node.position),
                direction(&node.tags).unwrap_or(0.0),
            )]
        } else {
            beside
        };
        let places: Vec<(Point, f64)> = places.into_iter().filter(|p| rect.owns(p.0)).collect();
        if places.is_empty() {
            continue;
        }
        let element = ElementRef {
            element_type: ElementType::Node,
            id: node.id,
        };
        let feature = set.add_feature(Some(element), FeatureClass::Object, &node.tags);
        for (at, rotation) in places {
            set.objects.push(PointObject {
                at,
                kind,
                rotation,
                feature,
            });
        }
    }
}

/// How far a door's foot stands out of its wall, metres: on the ground outside the building.
const DOOR_OUT_M: f64 = 0.05;

/// Whether a node's tags map a way into a building.
fn is_entrance(tags: &Tags) -> bool {
    tags.get("entrance").is_some_and(|v| v != "no") || tags.get("door").is_some_and(|v| v != "no")
}

/// Adds a door at each entrance node of a building's outline that lies in `rect`, in the wall
/// there and facing out of the building; an entrance on no building's outline has none.
fn collect_doors(
    set: &mut FeatureSet,
    selection: &Selection<'_>,
    projection: &Projection,
    rect: &Rect,
) {
    let entrances: std::collections::BTreeMap<i64, &crate::osm::Node> = selection
        .nodes
        .iter()
        .filter(|n| is_entrance(&n.tags) && rect.owns(projection.point(n.position)))
        .map(|n| (n.id, *n))
        .collect();
    if entrances.is_empty() {
        return;
    }
    let mut placed = std::collections::BTreeSet::new();
    for way in &selection.ways {
        let closed = way.nodes.len() >= 4 && way.nodes.first() == way.nodes.last();
        if !closed || !way.tags.is_set("building") || way.nodes.len() != way.positions.len() {
            continue;
        }
        let ring: Vec<Point> = way.positions[..way.positions.len() - 1]
            .iter()
            .map(|&p| projection.point(p))
            .collect();
        for (k, id) in way.nodes[..ring.len()].iter().enumerate() {
            let Some(node) = entrances.get(id) else {
                continue;
            };
            if placed.contains(id) {
                continue;
            }
            let metre = projection.metres(1.0, node.position.lat);
            let Some((at, rotation)) = door_in(&ring, k, metre) else {
                continue;
            };
            placed.insert(*id);
            let element = ElementRef {
                element_type: ElementType::Node,
                id: *id,
            };
            let feature = set.add_feature(Some(element), FeatureClass::Object, &node.tags);
            set.objects.push(PointObject {
                at,
                kind: ObjectKind::Door,
                rotation,
                feature,
            });
        }
    }
}

/// Where a door at corner `k` of a building's `ring` (global tile units, `metre` of them to
/// a metre) stands and how it turns: just outside the wall, facing out, square to the wall
/// from the corner before it to the one after.
fn door_in(ring: &[Point], k: usize, metre: f64) -> Option<(Point, f64)> {
    let n = ring.len();
    let (before, after) = (ring[(k + n - 1) % n], ring[(k + 1) % n]);
    let (du, dv) = (after[0] - before[0], after[1] - before[1]);
    let length = du.hypot(dv);
    if length <= 0.0 || metre <= 0.0 {
        return None;
    }
    let mut out = [dv / length, -du / length];
    let probe = |sign: f64| {
        let at = ring[k];
        [at[0] + sign * out[0] * metre, at[1] + sign * out[1] * metre]
    };
    if crate::geometry::ring_contains(ring, probe(0.5)) {
        out = [-out[0], -out[1]];
    } else if !crate::geometry::ring_contains(ring, probe(-0.5)) {
        // Neither side is inside: a corner too sharp to stand a door in.
        return None;
    }
    let at = ring[k];
    let foot = [
        at[0] + out[0] * DOOR_OUT_M * metre,
        at[1] + out[1] * DOOR_OUT_M * metre,
    ];
    // A model faces north (-z); turned by θ about the vertical it faces (-sin θ, -cos θ).
    Some((foot, (-out[0]).atan2(-out[1])))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tags_choose_the_object_and_its_direction() {
        let tags = |pairs: &[(&str, &str)]| Tags::from_pairs(pairs.to_vec());
        assert_eq!(
            ObjectKind::from_tags(&tags(&[("highway", "street_lamp")])),
            Some(ObjectKind::StreetLamp)
        );
        assert_eq!(
            ObjectKind::from_tags(&tags(&[
                ("power", "generator"),
                ("generator:source", "wind")
            ])),
            Some(ObjectKind::WindTurbine)
        );
        assert_eq!(
            ObjectKind::from_tags(&tags(&[
                ("power", "generator"),
                ("generator:source", "solar")
            ])),
            None
        );
        assert_eq!(
            direction(&tags(&[("direction", "E")])),
            Some(-90f64.to_radians())
        );
        assert_eq!(direction(&tags(&[("direction", "sideways")])), None);
        let kind = |pairs: &[(&str, &str)]| ObjectKind::from_tags(&tags(pairs));
        assert_eq!(
            kind(&[("highway", "bus_stop"), ("shelter", "yes")]),
            Some(ObjectKind::BusShelter)
        );
        assert_eq!(kind(&[("highway", "bus_stop")]), Some(ObjectKind::BusStop));
        assert_eq!(
            kind(&[("emergency", "fire_hydrant")]),
            Some(ObjectKind::FireHydrant)
        );
        assert_eq!(
            kind(&[
                ("emergency", "fire_hydrant"),
                ("fire_hydrant:type", "underground")
            ]),
            None
        );
        assert_eq!(
            kind(&[("historic", "memorial"), ("memorial", "plaque")]),
            None
        );
        assert_eq!(
            kind(&[("highway", "traffic_signals")]),
            Some(ObjectKind::TrafficSignals)
        );
        assert!(ObjectKind::StopSign.stands_beside_the_road());
        assert!(!ObjectKind::PostBox.stands_beside_the_road());
    }
}
