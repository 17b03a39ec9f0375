//! Power lines (`power=line`, `power=minor_line`): the conductors between the towers and poles
//! of a way, hung at the height of their supports (paper 001 §4.3: the supports themselves are
//! point objects).

use super::{FeatureClass, FeatureSet, Projection};
use crate::geometry::Point;
use crate::osm::index::Selection;
use crate::osm::units::parse_length_m;
use crate::osm::{ElementRef, ElementType, Way};

/// A power line to hang.
#[derive(Debug, Clone, PartialEq)]
pub struct PowerLine {
    /// The way in global tile units.
    pub line: Vec<Point>,
    /// Height of the conductors above the ground at each node, metres.
    pub heights_m: Vec<f64>,
    /// Sideways offsets of the conductors from the way, metres.
    pub offsets_m: Vec<f64>,
    pub feature: u32,
}

/// Conductor height at a support, by `power` value of the support node.
fn support_height_m(power: Option<&str>, minor: bool) -> f64 {
    match power {
        Some("tower") => 24.0,
        Some("pole") => 9.4,
        _ if minor => 9.4,
        _ => 24.0,
    }
}

pub(super) fn add_way(
    set: &mut FeatureSet,
    way: &Way,
    selection: &Selection<'_>,
    projection: &Projection,
) {
    let minor = match way.tags.get("power") {
        Some("line") => false,
        Some("minor_line") => true,
        _ => return,
    };
    if way.tags.get("location") == Some("underground") || way.tags.get("line") == Some("busbar") {
        return;
    }
    let tagged_height = way
        .tags
        .get("height")
        .and_then(parse_length_m)
        .filter(|h| (2.0..=150.0).contains(h));
    let heights_m = way
        .nodes
        .iter()
        .map(|&id| {
            let support = selection
                .nodes
                .binary_search_by_key(&id, |n| n.id)
                .ok()
                .and_then(|i| selection.nodes[i].tags.get("power"));
            tagged_height.unwrap_or_else(|| support_height_m(support, minor))
        })
        .collect();
    let offsets_m = if minor {
        vec![-0.8, 0.0, 0.8]
    } else {
        vec![-6.0, 0.0, 6.0]
    };
    let element = ElementRef {
        element_type: ElementType::Way,
        id: way.id,
    };
    let feature = set.add_feature(Some(element), FeatureClass::Object, &way.tags);
    set.power_lines.push(PowerLine {
        line: projection.points(&way.positions),
        heights_m,
        offsets_m,
        feature,
    });
}
