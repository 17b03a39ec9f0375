//! The tile's feature metadata: `EXT_structural_metadata`'s schema and its one property
//! table, a row for each feature the feature ids index.

use serde_json::{json as value, Value};

use super::BinaryBuilder;
use crate::features::FeatureInfo;

/// The schema and the one property table of `EXT_structural_metadata`.
pub(super) fn write_property_table(builder: &mut BinaryBuilder, features: &[FeatureInfo]) -> Value {
    let strings = |builder: &mut BinaryBuilder, values: Vec<String>| {
        let mut data = Vec::new();
        let mut offsets: Vec<u8> = Vec::with_capacity((values.len() + 1) * 4);
        offsets.extend_from_slice(&0u32.to_le_bytes());
        for v in &values {
            data.extend_from_slice(v.as_bytes());
            offsets.extend_from_slice(&(data.len() as u32).to_le_bytes());
        }
        // Property table buffer views start on 8-byte boundaries.
        let values_view = builder.view(&data, 8, None);
        let offsets_view = builder.view(&offsets, 8, None);
        value!({
            "values": values_view.value(),
            "stringOffsets": offsets_view.value(),
            "stringOffsetType": "UINT32"
        })
    };
    let osm_type = strings(
        builder,
        features
            .iter()
            .map(|f| {
                f.element
                    .map_or("none", |e| e.element_type.as_str())
                    .to_string()
            })
            .collect(),
    );
    let class = strings(
        builder,
        features
            .iter()
            .map(|f| f.class.as_str().to_string())
            .collect(),
    );
    let name = strings(
        builder,
        features
            .iter()
            .map(|f| f.name().unwrap_or("").to_string())
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
    value!({
        "schema": {
            "id": "terrastitch",
            "classes": {
                "osm_feature": {
                    "name": "OpenStreetMap feature",
                    "properties": {
                        "osm_type": {"type": "STRING", "description": "node, way, relation, or none for the default ground"},
                        "osm_id": {"type": "SCALAR", "componentType": "INT64", "description": "OSM element id (0 for the default ground)"},
                        "class": {"type": "STRING", "description": "terrain, road, railway, water, landcover, building, vegetation, barrier or object"},
                        "name": {"type": "STRING", "description": "the name tag, empty if none"},
                        "tags": {"type": "STRING", "description": "all OSM tags as a JSON object"},
                        "inferred": {"type": "STRING", "description": "values the tags leave unsaid that were inferred, as a JSON object of the tags they stand for (roof:shape, building:levels, roof:colour, building:colour); empty when nothing was"}
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
                "name": name,
                "tags": tags,
                "inferred": inferred
            }
        }]
    })
}
