//! Objects of street level a simple model describes well enough (paper 001 §4.3): street lamps,
//! benches, bollards, power poles and towers, wind turbines. Mapped as nodes, drawn as instances
//! of one model per kind.

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
}

impl ObjectKind {
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

    pub fn as_str(self) -> &'static str {
        match self {
            ObjectKind::StreetLamp => "street_lamp",
            ObjectKind::Bench => "bench",
            ObjectKind::Bollard => "bollard",
            ObjectKind::PowerPole => "power_pole",
            ObjectKind::PowerTower => "power_tower",
            ObjectKind::WindTurbine => "wind_turbine",
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
        }
    }
}

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

pub(super) fn collect(
    set: &mut FeatureSet,
    selection: &Selection<'_>,
    projection: &Projection,
    rect: &Rect,
) {
    for node in &selection.nodes {
        let Some(kind) = ObjectKind::from_tags(&node.tags) else {
            continue;
        };
        let at = projection.point(node.position);
        if !rect.owns(at) {
            continue;
        }
        let element = ElementRef {
            element_type: ElementType::Node,
            id: node.id,
        };
        let feature = set.add_feature(Some(element), FeatureClass::Object, &node.tags);
        set.objects.push(PointObject {
            at,
            kind,
            rotation: direction(&node.tags).unwrap_or(0.0),
            feature,
        });
    }
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
    }
}
