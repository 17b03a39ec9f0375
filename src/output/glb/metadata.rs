//! The tile's feature metadata: `EXT_structural_metadata`'s schema and its one property
//! table, a row for each feature the feature ids index.

use serde_json::{json as value, Value};

use super::BinaryBuilder;
use crate::features::{FeatureClass, FeatureInfo};
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

/// An enum column: one byte a row.
fn enums(builder: &mut BinaryBuilder, values: Vec<u8>) -> Value {
    let view = builder.view(&values, 8, None);
    value!({ "values": view.value() })
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
    let osm_type = enums(
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
    let class = enums(
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
    let inferred = strings(
        builder,
        features
            .iter()
            .map(|f| {
                if f.inferred.is_empty() {
                    return String::new();
                }
                let object: serde_json::Map<String, Value> = f
                    .inferred
                    .iter()
                    .map(|(k, v)| (k.to_string(), Value::String(v.clone())))
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
    value!({
        "schema": {
            "id": "terrastitch",
            "enums": {
                "osm_type": enum_of(&OSM_TYPES, "the type of an OSM element"),
                "feature_class": enum_of(&class_names, "what a feature is drawn as"),
            },
            "classes": {
                "osm_feature": {
                    "name": "OpenStreetMap feature",
                    "properties": {
                        "osm_type": {"type": "ENUM", "enumType": "osm_type", "description": "node, way, relation, or none for the default ground"},
                        "osm_id": {"type": "SCALAR", "componentType": "INT64", "description": "OSM element id (0 for the default ground)"},
                        "class": {"type": "ENUM", "enumType": "feature_class", "description": "terrain, road, railway, water, landcover, building, vegetation, barrier, object, bridge, tunnel or marking"},
                        "tags": {"type": "STRING", "description": "all OSM tags as a JSON object (its name among them)"},
                        "inferred": {"type": "STRING", "description": "values the tags leave unsaid that were inferred, as a JSON object of the tags they stand for (roof:shape, roof:direction, building:levels, roof:colour, building:colour); empty when nothing was"}
                    }
                }
            }
        },
        "propertyTables": [{
            "name": "osm_features",
            "class": "osm_feature",
            "count": features.len(),
            "properties": {
                "osm_type": osm_type,
                "osm_id": {"values": ids_view.value()},
                "class": class,
                "tags": tags,
                "inferred": inferred
            }
        }]
    })
}
