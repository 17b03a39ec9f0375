//! A reader of compressed tiles (`EXT_meshopt_compression` over `KHR_mesh_quantization`),
//! written from the two specifications and apart from the writer: compressed views decoded by
//! meshoptimizer's decoders, accessors read by component type and stride, the node's
//! translation and scale applied to quantized positions.

use std::collections::{BTreeMap, BTreeSet};

use serde_json::Value;

use super::{read_features, DecodedTile, Primitive};

/// A compressed tile read back.
pub struct CompressedTile {
    /// The tile as the plain decoder gives it: positions in the tile's frame.
    pub tile: DecodedTile,
    /// Nodes whose positions are quantized: their grid step and, per primitive, each vertex as
    /// whole steps of the grid counted from the tile's corner.
    pub grids: BTreeMap<String, NodeGrid>,
    pub extensions_required: Vec<String>,
}

pub struct NodeGrid {
    pub step: f64,
    pub positions: Vec<Vec<[i64; 3]>>,
}

fn chunk(bytes: &[u8], at: usize, kind: &[u8; 4]) -> (Vec<u8>, usize) {
    let length = u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    assert_eq!(&bytes[at + 4..at + 8], kind, "chunk type");
    (bytes[at + 8..at + 8 + length].to_vec(), at + 8 + length)
}

fn number(value: &Value, key: &str) -> usize {
    value[key].as_u64().unwrap_or(0) as usize
}

/// Every buffer view's bytes, decoded where compressed.
fn views(root: &Value, bin: &[u8]) -> Vec<Vec<u8>> {
    let buffers = root["buffers"].as_array().expect("buffers");
    root["bufferViews"]
        .as_array()
        .expect("buffer views")
        .iter()
        .map(|view| {
            let Some(meshopt) = view["extensions"].get("EXT_meshopt_compression") else {
                assert_eq!(
                    number(view, "buffer"),
                    0,
                    "a plain view reads the binary chunk"
                );
                let offset = number(view, "byteOffset");
                return bin[offset..offset + number(view, "byteLength")].to_vec();
            };
            // The view itself points into a fallback buffer that holds nothing.
            let fallback = &buffers[number(view, "buffer")];
            assert_eq!(
                fallback["extensions"]["EXT_meshopt_compression"]["fallback"],
                true
            );
            assert!(fallback.get("uri").is_none());
            assert_eq!(number(meshopt, "buffer"), 0);
            let octahedral = match meshopt.get("filter").and_then(|f| f.as_str()) {
                None | Some("NONE") => false,
                Some("OCTAHEDRAL") => true,
                Some(other) => panic!("unexpected filter {other}"),
            };
            let offset = number(meshopt, "byteOffset");
            let source = &bin[offset..offset + number(meshopt, "byteLength")];
            let (count, stride) = (number(meshopt, "count"), number(meshopt, "byteStride"));
            if view.get("byteStride").is_some() {
                assert_eq!(
                    number(view, "byteStride"),
                    stride,
                    "the view's stride is the codec's"
                );
            }
            if meshopt["mode"] == "TRIANGLES" {
                // Index codec version 1, the one the extension reads.
                assert_eq!(source.first(), Some(&0xe1), "index codec header");
            }
            let decoded: Vec<u8> = match (meshopt["mode"].as_str(), stride) {
                (Some("ATTRIBUTES"), 4) => attributes::<4>(source, count),
                (Some("ATTRIBUTES"), 8) => attributes::<8>(source, count),
                (Some("ATTRIBUTES"), 12) => attributes::<12>(source, count),
                (Some("ATTRIBUTES"), 16) => attributes::<16>(source, count),
                (Some("TRIANGLES"), 2) => meshopt::decode_index_buffer::<u16>(source, count)
                    .expect("index data decodes")
                    .into_iter()
                    .flat_map(u16::to_le_bytes)
                    .collect(),
                (Some("TRIANGLES"), 4) => meshopt::decode_index_buffer::<u32>(source, count)
                    .expect("index data decodes")
                    .into_iter()
                    .flat_map(u32::to_le_bytes)
                    .collect(),
                other => panic!("unexpected meshopt view {other:?}"),
            };
            assert_eq!(decoded.len(), number(view, "byteLength"));
            if octahedral {
                assert_eq!(stride, 4, "octahedral bytes");
                let mut units: Vec<[i8; 4]> = decoded
                    .chunks_exact(4)
                    .map(|c| [c[0] as i8, c[1] as i8, c[2] as i8, c[3] as i8])
                    .collect();
                meshopt::decode_filter_oct(&mut units);
                return units.into_iter().flatten().map(|v| v as u8).collect();
            }
            decoded
        })
        .collect()
}

fn attributes<const N: usize>(source: &[u8], count: usize) -> Vec<u8>
where
    [u8; N]: Default,
{
    assert_eq!(
        meshopt::decode_vertex_version(source),
        Some(0),
        "vertex codec 0"
    );
    meshopt::decode_vertex_buffer::<[u8; N]>(source, count)
        .expect("vertex data decodes")
        .into_iter()
        .flatten()
        .collect()
}

/// An accessor's elements as numbers (normalized integers scaled as glTF says).
fn read(root: &Value, views: &[Vec<u8>], index: usize) -> Vec<Vec<f64>> {
    let accessor = &root["accessors"][index];
    let view = &root["bufferViews"][number(accessor, "bufferView")];
    let data = &views[number(accessor, "bufferView")];
    let components = match accessor["type"].as_str() {
        Some("SCALAR") => 1,
        Some("VEC3") => 3,
        Some("VEC4") => 4,
        other => panic!("accessor type {other:?}"),
    };
    let component_type = number(accessor, "componentType");
    let size = match component_type {
        5120 | 5121 => 1,
        5122 | 5123 => 2,
        5125 | 5126 => 4,
        other => panic!("component type {other}"),
    };
    let stride = match number(view, "byteStride") {
        0 => size * components,
        stride => stride,
    };
    let normalized = accessor["normalized"].as_bool().unwrap_or(false);
    let start = number(accessor, "byteOffset");
    (0..number(accessor, "count"))
        .map(|i| {
            (0..components)
                .map(|c| {
                    let at = start + i * stride + c * size;
                    let b = &data[at..at + size];
                    match (component_type, normalized) {
                        (5120, true) => (f64::from(b[0] as i8) / 127.0).max(-1.0),
                        (5121, true) => f64::from(b[0]) / 255.0,
                        (5121, false) => f64::from(b[0]),
                        (5123, false) => f64::from(u16::from_le_bytes([b[0], b[1]])),
                        (5125, false) => f64::from(u32::from_le_bytes(b.try_into().unwrap())),
                        (5126, false) => f64::from(f32::from_le_bytes(b.try_into().unwrap())),
                        other => panic!("unexpected component {other:?}"),
                    }
                })
                .collect()
        })
        .collect()
}

/// Reads a compressed glb.
pub fn decode_compressed(bytes: &[u8]) -> CompressedTile {
    assert_eq!(&bytes[0..4], b"glTF");
    let (json, next) = chunk(bytes, 12, b"JSON");
    let (bin, _) = chunk(bytes, next, b"BIN\0");
    let root: Value = serde_json::from_slice(&json).expect("JSON chunk");
    let views = views(&root, &bin);
    let mut nodes = BTreeMap::new();
    let mut instanced = BTreeSet::new();
    let mut grids = BTreeMap::new();
    for node in root["nodes"].as_array().expect("nodes") {
        let name = node["name"].as_str().unwrap_or_default().to_string();
        assert!(node.get("rotation").is_none() && node.get("matrix").is_none());
        if node["extensions"].get("EXT_mesh_gpu_instancing").is_some() {
            instanced.insert(name.clone());
        }
        let Some(mesh) = node["mesh"].as_u64() else {
            continue;
        };
        let vector = |key: &str, default: f64| -> [f64; 3] {
            match node[key].as_array() {
                Some(v) => std::array::from_fn(|i| v[i].as_f64().expect("number")),
                None => [default; 3],
            }
        };
        let (translation, scale) = (vector("translation", 0.0), vector("scale", 1.0));
        let mut primitives = Vec::new();
        let mut grid = None::<NodeGrid>;
        for primitive in root["meshes"][mesh as usize]["primitives"]
            .as_array()
            .expect("primitives")
        {
            let attributes = &primitive["attributes"];
            let position_accessor = number(attributes, "POSITION");
            let quantized = number(&root["accessors"][position_accessor], "componentType") != 5126;
            let raw = read(&root, &views, position_accessor);
            if quantized {
                // Whole steps: the node's translation is a whole number of its scale.
                assert!(
                    scale[0] == scale[1] && scale[1] == scale[2],
                    "uniform scale"
                );
                let base: [i64; 3] = std::array::from_fn(|i| {
                    let steps = translation[i] / scale[0];
                    assert!((steps - steps.round()).abs() < 0.01, "{steps}");
                    steps.round() as i64
                });
                let grid = grid.get_or_insert(NodeGrid {
                    step: scale[0],
                    positions: Vec::new(),
                });
                grid.positions.push(
                    raw.iter()
                        .map(|q| std::array::from_fn(|i| q[i] as i64 + base[i]))
                        .collect(),
                );
            }
            let positions = raw
                .iter()
                .map(|q| {
                    std::array::from_fn(|i| match quantized {
                        true => (q[i] * scale[i] + translation[i]) as f32,
                        // Float positions read as they are (a -0.0 stays -0.0).
                        false => q[i] as f32,
                    })
                })
                .collect();
            let triple = |v: &Vec<f64>| [v[0] as f32, v[1] as f32, v[2] as f32];
            let normals = read(&root, &views, number(attributes, "NORMAL"))
                .iter()
                .map(triple)
                .collect();
            let feature_ids = read(&root, &views, number(attributes, "_FEATURE_ID_0"))
                .iter()
                .map(|v| v[0] as u32)
                .collect();
            let indices = read(&root, &views, number(primitive, "indices"))
                .iter()
                .map(|v| v[0] as u32)
                .collect();
            let material = root["materials"][number(primitive, "material")]["name"]
                .as_str()
                .unwrap_or_default()
                .to_string();
            primitives.push(Primitive {
                material,
                positions,
                normals,
                feature_ids,
                indices,
                ..Primitive::default()
            });
        }
        if let Some(grid) = grid {
            grids.insert(name.clone(), grid);
        }
        nodes.insert(name, primitives);
    }
    let features = read_features(&root, &|i| views[i].as_slice());
    CompressedTile {
        tile: DecodedTile {
            nodes,
            instanced,
            features,
            asset_extras: root["asset"]["extras"].clone(),
        },
        grids,
        extensions_required: root["extensionsRequired"]
            .as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|v| v.as_str().map(String::from))
                    .collect()
            })
            .unwrap_or_default(),
    }
}
