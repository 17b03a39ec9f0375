//! The tile's feature metadata: `EXT_structural_metadata`'s schema and its one property
//! table, a row for each feature the feature ids index.

use serde_json::{json as value, Value};

use super::BinaryBuilder;
use crate::features::roof_shape::RoofShape;
use crate::features::{FeatureClass, FeatureInfo, InferredTags};
use crate::osm::ElementType;

/// The element types of `osm_type`, by their enum values.
const OSM_TYPES: [&str; 4] = ["none", "node", "way", "relation"];

/// A string column: its bytes and their offsets, 16 bits each where the bytes fit (as most
/// columns of a tile do), else 32.
fn strings(builder: &mut BinaryBuilder, values: Vec<String>) -> Value {
    let total: usize = values.iter().map(String::len).sum();
    let narrow = total <= usize::from(u16::MAX);
    let mut data = Vec::with_capacity(total);
    let mut offsets: Vec<u8> = Vec::with_capacity((values.len() + 1) * 4);
    let push = |offset: usize, offsets: &mut Vec<u8>| {
        if narrow {
            offsets.extend_from_slice(&(offset as u16).to_le_bytes());
        } else {
            offsets.extend_from_slice(&(offset as u32).to_le_bytes());
        }
    };
    push(0, &mut offsets);
    for v in &values {
        data.extend_from_slice(v.as_bytes());
        push(data.len(), &mut offsets);
    }
    // Property table buffer views start on 8-byte boundaries.
    let values_view = builder.view(&data, 8, None);
    let offsets_view = builder.view(&offsets, 8, None);
    value!({
        "values": values_view.value(),
        "stringOffsets": offsets_view.value(),
        "stringOffsetType": if narrow { "UINT16" } else { "UINT32" }
    })
}

/// A column of fixed-size values (an enum's bytes, numbers, vectors), laid row after row.
fn fixed(builder: &mut BinaryBuilder, values: Vec<u8>) -> Value {
    let view = builder.view(&values, 8, None);
    value!({ "values": view.value() })
}

/// What no inferred value is written as, in each of the inferred columns.
const NOT_INFERRED_DIRECTION: u16 = u16::MAX;
const NOT_INFERRED_LEVELS: u8 = 0;
const NOT_INFERRED_COLOUR: [u8; 3] = [0, 0, 0];

/// The columns of the values inferred where a building's tags are silent (named after the
/// columns, with what a row that inferred nothing holds as their `noData`).
fn inferred_columns(builder: &mut BinaryBuilder, features: &[FeatureInfo]) -> Value {
    let inferred = || features.iter().map(|f| &f.inferred);
    let shape = inferred()
        .map(|i| {
            i.roof_shape.map_or(0, |s| {
                RoofShape::ALL.iter().position(|a| *a == s).unwrap_or(0) as u8 + 1
            })
        })
        .collect();
    let direction = inferred()
        .flat_map(|i| {
            i.roof_direction_deg
                .map_or(NOT_INFERRED_DIRECTION, |d| {
                    d.rem_euclid(360.0).round() as u16 % 360
                })
                .to_le_bytes()
        })
        .collect();
    let levels = inferred()
        .map(|i| {
            i.levels.map_or(NOT_INFERRED_LEVELS, |l| {
                l.clamp(1, u32::from(u8::MAX)) as u8
            })
        })
        .collect();
    let colour = |pick: fn(&InferredTags) -> Option<[u8; 3]>| -> Vec<u8> {
        // A colour that happens to be the no-data black is written one step off it.
        inferred()
            .flat_map(|i| {
                pick(i).map_or(NOT_INFERRED_COLOUR, |c| {
                    if c == NOT_INFERRED_COLOUR {
                        [0, 0, 1]
                    } else {
                        c
                    }
                })
            })
            .collect()
    };
    value!({
        "inferred_roof_shape": fixed(builder, shape),
        "inferred_roof_direction": fixed(builder, direction),
        "inferred_building_levels": fixed(builder, levels),
        "inferred_building_colour": fixed(builder, colour(|i| i.building_colour)),
        "inferred_roof_colour": fixed(builder, colour(|i| i.roof_colour)),
    })
}

/// The schema of the inferred columns.
fn inferred_schema() -> Value {
    let colour = |tag: &str| {
        value!({"type": "VEC3", "componentType": "UINT8", "noData": NOT_INFERRED_COLOUR,
            "description": format!("{tag} inferred (sRGB), where neither it nor a material is tagged")})
    };
    value!({
        "inferred_roof_shape": {"type": "ENUM", "enumType": "roof_shape", "noData": "none",
            "description": "roof:shape inferred, where it is not tagged"},
        "inferred_roof_direction": {"type": "SCALAR", "componentType": "UINT16", "noData": NOT_INFERRED_DIRECTION,
            "description": "roof:direction inferred (degrees, the compass direction the roof's faces look towards), where it is not tagged and the roof follows a row"},
        "inferred_building_levels": {"type": "SCALAR", "componentType": "UINT8", "noData": NOT_INFERRED_LEVELS,
            "description": "building:levels inferred, where neither it nor a height is tagged"},
        "inferred_building_colour": colour("building:colour"),
        "inferred_roof_colour": colour("roof:colour"),
    })
}

/// An enum's definition: its names, valued by their order.
fn enum_of(names: &[&str], description: &str) -> Value {
    let values: Vec<Value> = names
        .iter()
        .enumerate()
        .map(|(value, name)| value!({ "name": name, "value": value }))
        .collect();
    value!({ "valueType": "UINT8", "description": description, "values": values })
}

/// The schema and the one property table of `EXT_structural_metadata`.
pub(super) fn write_property_table(builder: &mut BinaryBuilder, features: &[FeatureInfo]) -> Value {
    let osm_type = fixed(
        builder,
        features
            .iter()
            .map(|f| {
                f.element.map_or(0, |e| match e.element_type {
                    ElementType::Node => 1,
                    ElementType::Way => 2,
                    ElementType::Relation => 3,
                })
            })
            .collect(),
    );
    let class = fixed(
        builder,
        features
            .iter()
            .map(|f| {
                FeatureClass::ALL
                    .iter()
                    .position(|c| *c == f.class)
                    .unwrap_or(0) as u8
            })
            .collect(),
    );
    let tags = strings(
        builder,
        features
            .iter()
            .map(|f| {
                let object: serde_json::Map<String, Value> = f
                    .tags
                    .iter()
                    .map(|(k, v)| (k.to_string(), Value::String(v.to_string())))
                    .collect();
                Value::Object(object).to_string()
            })
            .collect(),
    );
    let ids: Vec<u8> = features
        .iter()
        .flat_map(|f| f.element.map_or(0i64, |e| e.id).to_le_bytes())
        .collect();
    let ids_view = builder.view(&ids, 8, None);
    let class_names: Vec<&str> = FeatureClass::ALL.iter().map(|c| c.as_str()).collect();
    let shape_names: Vec<&str> = std::iter::once("none")
        .chain(RoofShape::ALL.iter().map(|s| s.tag()))
        .collect();
    let mut declared = value!({
        "osm_type": {"type": "ENUM", "enumType": "osm_type", "description": "node, way, relation, or none for the default ground"},
        "osm_id": {"type": "SCALAR", "componentType": "INT64", "description": "OSM element id (0 for the default ground)"},
        "class": {"type": "ENUM", "enumType": "feature_class", "description": "terrain, road, railway, water, landcover, building, vegetation, barrier, object, bridge, tunnel or marking"},
        "tags": {"type": "STRING", "description": "all OSM tags as a JSON object (its name among them)"}
    });
    let mut columns = value!({
        "osm_type": osm_type,
        "osm_id": {"values": ids_view.value()},
        "class": class,
        "tags": tags
    });
    merge(&mut declared, inferred_schema());
    merge(&mut columns, inferred_columns(builder, features));
    value!({
        "schema": {
            "id": "terrastitch",
            "enums": {
                "osm_type": enum_of(&OSM_TYPES, "the type of an OSM element"),
                "feature_class": enum_of(&class_names, "what a feature is drawn as"),
                "roof_shape": enum_of(&shape_names, "a roof:shape value, or none"),
            },
            "classes": {
                "osm_feature": {
                    "name": "OpenStreetMap feature",
                    "properties": declared
                }
            }
        },
        "propertyTables": [{
            "name": "osm_features",
            "class": "osm_feature",
            "count": features.len(),
            "properties": columns
        }]
    })
}

/// Adds the members of the object `more` to the object `into`.
fn merge(into: &mut Value, more: Value) {
    if let (Value::Object(into), Value::Object(more)) = (into, more) {
        into.extend(more);
    }
}
