//! glTF binary (`.glb`) writer.
//!
//! One node per feature class, named after it (and a `roadside` node for the sidewalks, kerbs
//! and verges over the road surfaces), each with one mesh whose primitives are the class's
//! [`Part`]s. Every primitive carries `POSITION`, `NORMAL` and `_FEATURE_ID_0`
//! (`EXT_mesh_features`), and painted ones (buildings) `COLOR_0` under a white material; the
//! feature ids index one property table (`EXT_structural_metadata`)
//! of class `osm_feature` with the OSM type, id, class, name and all tags (as a JSON object) of
//! each feature. The frame is described in `asset.extras.terrastitch`.
//!
//! A [`Variant`] chooses the frame (the flat Web Mercator frame, or east-north-up on the
//! ellipsoid for globe viewers, see [`super::enu`]) and whether the geometry is compressed:
//! `EXT_meshopt_compression` over `KHR_mesh_quantization`. Compressed positions of the flat
//! frame lie on a grid shared by every tile of the zoom (a step of 1/32768 of the tile's side,
//! counted from the tile's north-west corner; see [`Grid`]), so neighbours still share their
//! edge vertices exactly; normals become bytes; each primitive's triangles and vertices are
//! reordered for the vertex cache and fetch before meshoptimizer encodes them. The compressed
//! views decode into a fallback buffer that holds no bytes; the property table stays plain.
//!
//! The container is written here (gltf-json writes only the JSON): a 12-byte header, the JSON
//! chunk padded with spaces and the binary chunk padded with zeros, both to 4 bytes.

use std::collections::{BTreeMap, BTreeSet};

use gltf_json as json;
use json::validation::{Checked::Valid, USize64};
use serde_json::{json as value, Value};

use crate::features::facades::Glazing;
use crate::features::{FeatureClass, FeatureInfo};
use crate::format::{Frame, Variant};
use crate::geoid::VerticalDatum;
use crate::mesh::instances::Instances;
use crate::mesh::models::Model;
use crate::mesh::{MeshBuffers, Part};
use crate::output::enu::EastNorthUp;
use crate::tile::{LonLatBounds, TileId};
use materials::{material_of, metallic_of};
use metadata::write_property_table;

mod facades;
mod materials;
mod metadata;

pub use crate::format::ATTRIBUTION;

/// What the writer needs to describe the tile.
#[derive(Debug, Clone)]
pub struct TileDescription {
    pub tile: TileId,
    pub bounds: LonLatBounds,
    pub size_m: f64,
    pub generator: String,
    /// What east-north-up content's heights are measured from.
    pub vertical_datum: VerticalDatum,
}

/// Steps of the shared position grid along a tile's side.
pub const GRID_STEPS_PER_TILE: f64 = 32768.0;

/// Compressed positions of one node: whole steps of the shared grid, stored as offsets from
/// `base` (in steps from the tile's north-west corner and from zero height) in 16 bits; the
/// node's translation and scale turn them back into metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    pub step: f64,
    pub base: [i64; 3],
}

impl Grid {
    /// The grid for these positions, if they span at most 65,535 steps on every axis.
    fn over<'a>(size_m: f64, positions: impl Iterator<Item = &'a [f32; 3]>) -> Option<Grid> {
        let step = size_m / GRID_STEPS_PER_TILE;
        let mut min = [i64::MAX; 3];
        let mut max = [i64::MIN; 3];
        for p in positions {
            for axis in 0..3 {
                let q = (f64::from(p[axis]) / step).round() as i64;
                min[axis] = min[axis].min(q);
                max[axis] = max[axis].max(q);
            }
        }
        (0..3)
            .all(|axis| min[axis] <= max[axis] && max[axis] - min[axis] <= i64::from(u16::MAX))
            .then_some(Grid { step, base: min })
    }

    fn quantize(&self, p: [f32; 3]) -> [u16; 3] {
        std::array::from_fn(|axis| {
            let q = (f64::from(p[axis]) / self.step).round() as i64 - self.base[axis];
            q.clamp(0, i64::from(u16::MAX)) as u16
        })
    }
}

/// Accumulates the binary chunk and the buffer views that point into it.
struct BinaryBuilder {
    bytes: Vec<u8>,
    root: json::Root,
    /// With meshopt: the length of the fallback buffer the compressed views decode into.
    fallback: Option<usize>,
    /// The facade textures written so far, and the sampler they share.
    textures: BTreeMap<Glazing, json::Index<json::Texture>>,
    sampler: Option<json::Index<json::texture::Sampler>>,
}

impl BinaryBuilder {
    /// A view of vertex data, `stride` bytes an element: meshopt-compressed when the tile is.
    fn vertex_view(&mut self, data: &[u8], stride: usize) -> json::Index<json::buffer::View> {
        let target = Some(json::buffer::Target::ArrayBuffer);
        if self.fallback.is_none() {
            return self.view(data, 4, target);
        }
        let encoded = encode_vertices(data, stride);
        self.compressed(
            &encoded,
            (data.len(), stride, data.len() / stride),
            ("ATTRIBUTES", None),
            target,
        )
    }

    /// A compressed view of vertex data already put through a meshopt `filter` (its decoder
    /// undoes it after the codec).
    fn filtered_vertex_view(
        &mut self,
        data: &[u8],
        stride: usize,
        filter: &str,
    ) -> json::Index<json::buffer::View> {
        let encoded = encode_vertices(data, stride);
        self.compressed(
            &encoded,
            (data.len(), stride, data.len() / stride),
            ("ATTRIBUTES", Some(filter)),
            Some(json::buffer::Target::ArrayBuffer),
        )
    }

    /// A float `VEC3` attribute.
    fn float_vec3(
        &mut self,
        values: &[[f32; 3]],
        min_max: Option<(Value, Value)>,
    ) -> json::Index<json::Accessor> {
        let bytes = floats_to_bytes(values.iter().flatten().copied());
        let view = self.vertex_view(&bytes, 12);
        self.accessor(
            view,
            values.len(),
            json::accessor::ComponentType::F32,
            json::accessor::Type::Vec3,
            min_max,
        )
    }

    /// A normalized attribute of one byte per component, each element padded to 4 bytes.
    fn byte_attribute(
        &mut self,
        padded: &[u8],
        count: usize,
        component_type: json::accessor::ComponentType,
        type_: json::accessor::Type,
    ) -> json::Index<json::Accessor> {
        let view = self.vertex_view(padded, 4);
        self.root.buffer_views[view.value()].byte_stride = Some(json::buffer::Stride(4));
        let accessor = self.accessor(view, count, component_type, type_, None);
        self.root.accessors[accessor.value()].normalized = true;
        accessor
    }

    /// A view of triangle indices, 16 or 32 bits each.
    fn index_view(
        &mut self,
        indices: &[u32],
        vertex_count: usize,
        wide: bool,
    ) -> json::Index<json::buffer::View> {
        let bytes: Vec<u8> = if wide {
            indices.iter().flat_map(|&i| i.to_le_bytes()).collect()
        } else {
            indices
                .iter()
                .flat_map(|&i| (i as u16).to_le_bytes())
                .collect()
        };
        let target = Some(json::buffer::Target::ElementArrayBuffer);
        if self.fallback.is_none() {
            return self.view(&bytes, 4, target);
        }
        let encoded = meshopt::encode_index_buffer(indices, vertex_count)
            .expect("meshoptimizer encodes any triangle list");
        let stride = if wide { 4 } else { 2 };
        self.compressed(
            &encoded,
            (bytes.len(), stride, indices.len()),
            ("TRIANGLES", None),
            target,
        )
    }

    /// Appends meshoptimizer's bytes to the binary chunk and a view of the fallback buffer
    /// that they decode into (`decoded_length` bytes of `count` elements of `stride`), by a
    /// codec `mode` and a filter, if any.
    fn compressed(
        &mut self,
        encoded: &[u8],
        (decoded_length, stride, count): (usize, usize, usize),
        (mode, filter): (&str, Option<&str>),
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::buffer::View> {
        while self.bytes.len() % 4 != 0 {
            self.bytes.push(0);
        }
        let offset = self.bytes.len();
        self.bytes.extend_from_slice(encoded);
        let fallback = self.fallback.get_or_insert(0);
        *fallback = fallback.next_multiple_of(4);
        let decoded_offset = *fallback;
        *fallback += decoded_length;
        let mut extension = value!({
            "buffer": 0,
            "byteOffset": offset,
            "byteLength": encoded.len(),
            "byteStride": stride,
            "count": count,
            "mode": mode,
        });
        if let Some(filter) = filter {
            extension["filter"] = value!(filter);
        }
        self.root.push(json::buffer::View {
            buffer: json::Index::new(1),
            byte_length: USize64::from(decoded_length),
            byte_offset: Some(USize64::from(decoded_offset)),
            byte_stride: None,
            name: None,
            target: target.map(Valid),
            extensions: Some(json::extensions::buffer::View {
                others: [("EXT_meshopt_compression".to_string(), extension)]
                    .into_iter()
                    .collect(),
            }),
            extras: Default::default(),
        })
    }

    /// Appends `data` as a buffer view aligned to `align` bytes.
    fn view(
        &mut self,
        data: &[u8],
        align: usize,
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::buffer::View> {
        while self.bytes.len() % align != 0 {
            self.bytes.push(0);
        }
        let offset = self.bytes.len();
        self.bytes.extend_from_slice(data);
        self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(data.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            name: None,
            target: target.map(Valid),
            extensions: None,
            extras: Default::default(),
        })
    }

    fn accessor(
        &mut self,
        view: json::Index<json::buffer::View>,
        count: usize,
        component_type: json::accessor::ComponentType,
        type_: json::accessor::Type,
        min_max: Option<(Value, Value)>,
    ) -> json::Index<json::Accessor> {
        let (min, max) = match min_max {
            Some((min, max)) => (Some(min), Some(max)),
            None => (None, None),
        };
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(component_type)),
            extensions: None,
            extras: Default::default(),
            type_: Valid(type_),
            min,
            max,
            name: None,
            normalized: false,
            sparse: None,
        })
    }
}

fn floats_to_bytes(values: impl Iterator<Item = f32>) -> Vec<u8> {
    values.flat_map(f32::to_le_bytes).collect()
}

/// meshoptimizer's vertex codec (version 0, the one `EXT_meshopt_compression` reads) over
/// elements of `stride` bytes.
fn encode_vertices(data: &[u8], stride: usize) -> Vec<u8> {
    fn typed<const N: usize>(data: &[u8]) -> Vec<u8> {
        let elements: Vec<[u8; N]> = data
            .chunks_exact(N)
            .map(|c| {
                let mut element = [0; N];
                element.copy_from_slice(c);
                element
            })
            .collect();
        meshopt::encode_vertex_buffer_level(&elements, 2, Some(0))
            .expect("meshoptimizer encodes any vertex data")
    }
    match stride {
        4 => typed::<4>(data),
        8 => typed::<8>(data),
        12 => typed::<12>(data),
        16 => typed::<16>(data),
        other => unreachable!("no vertex stream of {other} bytes is written"),
    }
}

/// The buffers with their triangles ordered for the vertex cache and their vertices in the
/// order the triangles first use them (what meshoptimizer's codecs compress best); vertices no
/// triangle uses are dropped.
fn reordered(buffers: &MeshBuffers) -> MeshBuffers {
    let count = buffers.positions.len();
    let mut indices = meshopt::optimize_vertex_cache(&buffers.indices, count);
    let mut remap = vec![u32::MAX; count];
    let mut order: Vec<usize> = Vec::with_capacity(count);
    for index in &mut indices {
        let old = *index as usize;
        if remap[old] == u32::MAX {
            remap[old] = order.len() as u32;
            order.push(old);
        }
        *index = remap[old];
    }
    let mut out = MeshBuffers::default();
    out.positions = order.iter().map(|&i| buffers.positions[i]).collect();
    out.normals = order.iter().map(|&i| buffers.normals[i]).collect();
    out.feature_ids = order.iter().map(|&i| buffers.feature_ids[i]).collect();
    out.indices = indices;
    if buffers.colours.len() == count {
        out.colours = order.iter().map(|&i| buffers.colours[i]).collect();
    }
    if buffers.uvs.len() == count {
        out.uvs = order.iter().map(|&i| buffers.uvs[i]).collect();
    }
    out
}

/// Writes a tile's parts and feature table as glb bytes, in the frame and with the
/// compression `variant` asks for.
pub fn write(
    description: &TileDescription,
    parts: &BTreeMap<Part, MeshBuffers>,
    instanced: &BTreeMap<Model, Instances>,
    features: &[FeatureInfo],
    variant: Variant,
) -> Vec<u8> {
    let enu = (variant.frame == Frame::EastNorthUp)
        .then(|| EastNorthUp::in_datum(description.tile, description.vertical_datum));
    let carried;
    let (parts, instanced) = match &enu {
        Some(enu) => {
            let mut moved = (parts.clone(), instanced.clone());
            enu.carry(&mut moved.0, &mut moved.1);
            carried = moved;
            (&carried.0, &carried.1)
        }
        None => (parts, instanced),
    };
    // Room for the plain buffers at once, rather than growing through copies of many MB.
    let room = if variant.meshopt {
        0
    } else {
        parts.values().map(MeshBuffers::byte_len).sum()
    };
    let mut builder = BinaryBuilder {
        bytes: Vec::with_capacity(room),
        root: json::Root::default(),
        fallback: variant.meshopt.then_some(0),
        textures: BTreeMap::new(),
        sampler: None,
    };

    let mut nodes = Vec::new();
    for ((_, name), class_parts) in parts_by_node(parts) {
        nodes.push(write_class(
            &mut builder,
            description,
            variant,
            name,
            &class_parts,
        ));
    }
    for (&model, instances) in instanced {
        if !instances.is_empty() {
            nodes.push(write_instanced(
                &mut builder,
                model,
                instances,
                features.len(),
            ));
        }
    }
    let scene = builder.root.push(json::Scene {
        extensions: None,
        extras: Default::default(),
        name: Some(description.tile.to_string()),
        nodes,
    });
    builder.root.scene = Some(scene);

    let metadata = write_property_table(&mut builder, features);
    builder.root.extensions = Some(json::extensions::root::Root {
        others: [("EXT_structural_metadata".to_string(), metadata)]
            .into_iter()
            .collect(),
    });
    declare_extensions(&mut builder, instanced.values().any(|i| !i.is_empty()));
    write_buffers(&mut builder);
    builder.root.asset = asset(description, enu.as_ref());

    let json_bytes = serde_json::to_vec(&builder.root).expect("glTF JSON serializes");
    container(&json_bytes, &builder.bytes)
}

/// The parts a node draws, by the feature class it draws for and its name.
type NodeParts<'a> = BTreeMap<(FeatureClass, &'static str), Vec<(Part, &'a MeshBuffers)>>;

/// The non-empty parts grouped by the node that draws them, in the order of their classes.
fn parts_by_node(parts: &BTreeMap<Part, MeshBuffers>) -> NodeParts<'_> {
    let mut node_parts = NodeParts::new();
    for (&part, buffers) in parts {
        if !buffers.is_empty() {
            node_parts
                .entry((part.class(), part.node()))
                .or_default()
                .push((part, buffers));
        }
    }
    node_parts
}

/// A node named `name`: one mesh with a primitive per part, and with compressed positions of
/// the flat frame, the translation and scale that carry the shared grid back to metres.
fn write_class(
    builder: &mut BinaryBuilder,
    description: &TileDescription,
    variant: Variant,
    name: &str,
    class_parts: &[(Part, &MeshBuffers)],
) -> json::Index<json::Node> {
    // Positions on the shared grid where the node's extent allows it.
    let grid = if variant.meshopt && variant.frame == Frame::WebMercator {
        Grid::over(
            description.size_m,
            class_parts.iter().flat_map(|(_, b)| b.positions.iter()),
        )
    } else {
        None
    };
    let primitives = class_parts
        .iter()
        .map(|&(part, buffers)| write_primitive(builder, part, buffers, grid.as_ref()))
        .collect();
    let mesh = builder.root.push(json::Mesh {
        extensions: None,
        extras: Default::default(),
        name: Some(name.to_string()),
        primitives,
        weights: None,
    });
    let (translation, scale) = match grid {
        Some(grid) => (
            Some(grid.base.map(|b| (b as f64 * grid.step) as f32)),
            Some([grid.step as f32; 3]),
        ),
        None => (None, None),
    };
    builder.root.push(json::Node {
        mesh: Some(mesh),
        name: Some(name.to_string()),
        translation,
        scale,
        ..Default::default()
    })
}

/// The extensions the tile uses, and of them those a reader needs to decode it.
fn declare_extensions(builder: &mut BinaryBuilder, has_instances: bool) {
    builder.root.extensions_used = vec![
        "EXT_mesh_features".to_string(),
        "EXT_structural_metadata".to_string(),
    ];
    if has_instances {
        builder.root.extensions_used.extend([
            "EXT_mesh_gpu_instancing".to_string(),
            "EXT_instance_features".to_string(),
        ]);
    }
    if builder.fallback.is_some_and(|length| length > 0) {
        // Normals are bytes in every compressed tile, positions too where a grid fits.
        for extension in ["KHR_mesh_quantization", "EXT_meshopt_compression"] {
            builder.root.extensions_used.push(extension.to_string());
            builder.root.extensions_required.push(extension.to_string());
        }
        // Facade texture coordinates are whole texels, scaled back by the texture's transform.
        if !builder.textures.is_empty() {
            let extension = facades::TEXTURE_TRANSFORM.to_string();
            builder.root.extensions_used.push(extension.clone());
            builder.root.extensions_required.push(extension);
        }
    }
}

/// Pads the binary chunk and declares the buffer that holds it, and with meshopt the fallback
/// buffer the compressed views decode into.
fn write_buffers(builder: &mut BinaryBuilder) {
    while builder.bytes.len() % 4 != 0 {
        builder.bytes.push(0);
    }
    builder.root.buffers = vec![json::Buffer {
        byte_length: USize64::from(builder.bytes.len()),
        name: None,
        uri: None,
        extensions: None,
        extras: Default::default(),
    }];
    if let Some(fallback) = builder.fallback.filter(|&length| length > 0) {
        // What the compressed views decode into: no bytes of its own.
        builder.root.buffers.push(json::Buffer {
            byte_length: USize64::from(fallback.next_multiple_of(4)),
            name: None,
            uri: None,
            extensions: Some(json::extensions::buffer::Buffer {
                others: [(
                    "EXT_meshopt_compression".to_string(),
                    value!({ "fallback": true }),
                )]
                .into_iter()
                .collect(),
            }),
            extras: Default::default(),
        });
    }
}

/// A node drawing one model at every instance: `EXT_mesh_gpu_instancing` with translation,
/// rotation and scale per instance, and the instance's feature id (`EXT_instance_features`).
fn write_instanced(
    builder: &mut BinaryBuilder,
    model: Model,
    instances: &Instances,
    feature_count: usize,
) -> json::Index<json::Node> {
    let primitives = model
        .parts()
        .iter()
        .map(|(part, buffers)| write_primitive(builder, *part, buffers, None))
        .collect();
    let mesh = builder.root.push(json::Mesh {
        extensions: None,
        extras: Default::default(),
        name: Some(model.name().to_string()),
        primitives,
        weights: None,
    });
    let count = instances.len();
    let mut vector = |values: Vec<f32>, type_: json::accessor::Type| {
        let stride = 4 * type_.multiplicity();
        let view = builder.vertex_view(&floats_to_bytes(values.into_iter()), stride);
        // Instance attributes are not vertex attributes: no target on their views.
        builder.root.buffer_views[view.value()].target = None;
        builder.accessor(view, count, json::accessor::ComponentType::F32, type_, None)
    };
    let translation = vector(
        instances.translations.iter().flatten().copied().collect(),
        json::accessor::Type::Vec3,
    );
    let rotation = vector(
        instances.rotations.iter().flatten().copied().collect(),
        json::accessor::Type::Vec4,
    );
    let scale = vector(
        instances.scales.iter().flatten().copied().collect(),
        json::accessor::Type::Vec3,
    );
    let ids = vector(
        instances.feature_ids.iter().map(|&id| id as f32).collect(),
        json::accessor::Type::Scalar,
    );
    let mut others = serde_json::Map::new();
    others.insert(
        "EXT_mesh_gpu_instancing".to_string(),
        value!({ "attributes": {
            "TRANSLATION": translation.value(),
            "ROTATION": rotation.value(),
            "SCALE": scale.value(),
            "_FEATURE_ID_0": ids.value(),
        }}),
    );
    let distinct: BTreeSet<u32> = instances.feature_ids.iter().copied().collect();
    others.insert(
        "EXT_instance_features".to_string(),
        value!({ "featureIds": [{
            "featureCount": distinct.len(),
            "attribute": 0,
            "propertyTable": 0,
        }]}),
    );
    debug_assert!(distinct.iter().all(|&id| (id as usize) < feature_count));
    builder.root.push(json::Node {
        mesh: Some(mesh),
        name: Some(model.name().to_string()),
        extensions: Some(json::extensions::scene::Node { others }),
        ..Default::default()
    })
}

/// One part as a primitive: its attributes, indices and material, with the feature ids that
/// index the property table.
fn write_primitive(
    builder: &mut BinaryBuilder,
    part: Part,
    buffers: &MeshBuffers,
    grid: Option<&Grid>,
) -> json::mesh::Primitive {
    let compressed = builder.fallback.is_some();
    let reordered_buffers;
    let buffers = if compressed {
        reordered_buffers = reordered(buffers);
        &reordered_buffers
    } else {
        buffers
    };
    let count = buffers.positions.len();
    let positions = match grid {
        Some(grid) => write_grid_positions(builder, &buffers.positions, grid),
        None => write_float_positions(builder, &buffers.positions),
    };
    let normals = write_normals(builder, &buffers.normals, count, compressed);
    let feature_ids = write_feature_ids(builder, &buffers.feature_ids, count);
    let indices = write_indices(builder, &buffers.indices, count);

    let painted = !buffers.colours.is_empty() && buffers.colours.len() == count;
    let colours = painted.then(|| {
        let bytes: Vec<u8> = buffers.colours.iter().flatten().copied().collect();
        builder.byte_attribute(
            &bytes,
            count,
            json::accessor::ComponentType::U8,
            json::accessor::Type::Vec4,
        )
    });
    let uvs = (!buffers.uvs.is_empty() && buffers.uvs.len() == count)
        .then(|| facades::write_uvs(builder, &buffers.uvs, compressed));
    let material = write_material(builder, part, painted);

    let distinct: BTreeSet<u32> = buffers.feature_ids.iter().copied().collect();
    let mut attributes = BTreeMap::new();
    attributes.insert(Valid(json::mesh::Semantic::Positions), positions);
    attributes.insert(Valid(json::mesh::Semantic::Normals), normals);
    if let Some(colours) = colours {
        attributes.insert(Valid(json::mesh::Semantic::Colors(0)), colours);
    }
    if let Some(uvs) = uvs {
        attributes.insert(Valid(json::mesh::Semantic::TexCoords(0)), uvs);
    }
    attributes.insert(
        Valid(json::mesh::Semantic::Extras("FEATURE_ID_0".to_string())),
        feature_ids,
    );
    json::mesh::Primitive {
        attributes,
        extensions: Some(json::extensions::mesh::Primitive {
            others: [(
                "EXT_mesh_features".to_string(),
                value!({
                    "featureIds": [{
                        "featureCount": distinct.len(),
                        "attribute": 0,
                        "propertyTable": 0,
                        "label": "osm"
                    }]
                }),
            )]
            .into_iter()
            .collect(),
        }),
        extras: Default::default(),
        indices: Some(indices),
        material: Some(material),
        mode: Valid(json::mesh::Mode::Triangles),
        targets: None,
    }
}

/// Positions as whole steps of the shared grid, 16 bits each, padded to 8 bytes a vertex.
fn write_grid_positions(
    builder: &mut BinaryBuilder,
    positions: &[[f32; 3]],
    grid: &Grid,
) -> json::Index<json::Accessor> {
    let quantized: Vec<[u16; 3]> = positions.iter().map(|&p| grid.quantize(p)).collect();
    let mut min = [u16::MAX; 3];
    let mut max = [0u16; 3];
    for q in &quantized {
        for axis in 0..3 {
            min[axis] = min[axis].min(q[axis]);
            max[axis] = max[axis].max(q[axis]);
        }
    }
    let bytes: Vec<u8> = quantized
        .iter()
        .flat_map(|q| {
            let [a, b, c] = q.map(u16::to_le_bytes);
            [a[0], a[1], b[0], b[1], c[0], c[1], 0, 0]
        })
        .collect();
    let view = builder.vertex_view(&bytes, 8);
    builder.root.buffer_views[view.value()].byte_stride = Some(json::buffer::Stride(8));
    builder.accessor(
        view,
        positions.len(),
        json::accessor::ComponentType::U16,
        json::accessor::Type::Vec3,
        Some((value!(min), value!(max))),
    )
}

/// Positions as floats, with the bounds glTF requires of them.
fn write_float_positions(
    builder: &mut BinaryBuilder,
    positions: &[[f32; 3]],
) -> json::Index<json::Accessor> {
    let mut min = [f32::INFINITY; 3];
    let mut max = [f32::NEG_INFINITY; 3];
    for p in positions {
        for axis in 0..3 {
            min[axis] = min[axis].min(p[axis]);
            max[axis] = max[axis].max(p[axis]);
        }
    }
    builder.float_vec3(positions, Some((value!(min), value!(max))))
}

/// Normals as floats, or in a compressed tile as signed normalized bytes, padded to 4 a vertex,
/// stored octahedrally (meshopt's `OCTAHEDRAL` filter: two components that vary instead of
/// three, which its codec packs tighter; the decoder gives back the bytes of the unit vector).
fn write_normals(
    builder: &mut BinaryBuilder,
    normals: &[[f32; 3]],
    count: usize,
    compressed: bool,
) -> json::Index<json::Accessor> {
    if !compressed {
        return builder.float_vec3(normals, None);
    }
    let units: Vec<[f32; 4]> = normals.iter().map(|n| [n[0], n[1], n[2], 0.0]).collect();
    let bytes: Vec<u8> = meshopt::encode_filter_oct::<i8>(&units, 7)
        .into_iter()
        .flatten()
        .map(|v| v as u8)
        .collect();
    let view = builder.filtered_vertex_view(&bytes, 4, "OCTAHEDRAL");
    builder.root.buffer_views[view.value()].byte_stride = Some(json::buffer::Stride(4));
    let accessor = builder.accessor(
        view,
        count,
        json::accessor::ComponentType::I8,
        json::accessor::Type::Vec3,
        None,
    );
    builder.root.accessors[accessor.value()].normalized = true;
    accessor
}

/// Feature ids: 16-bit where they fit (vertex attributes may not be 32-bit integers), each
/// element padded to the 4-byte alignment vertex attributes need; floats beyond.
fn write_feature_ids(
    builder: &mut BinaryBuilder,
    feature_ids: &[u32],
    count: usize,
) -> json::Index<json::Accessor> {
    let max_id = feature_ids.iter().copied().max().unwrap_or(0);
    let (id_view, id_type) = if max_id < u32::from(u16::MAX) {
        let padded: Vec<u8> = feature_ids
            .iter()
            .flat_map(|&id| {
                let [a, b] = (id as u16).to_le_bytes();
                [a, b, 0, 0]
            })
            .collect();
        let view = builder.vertex_view(&padded, 4);
        builder.root.buffer_views[view.value()].byte_stride = Some(json::buffer::Stride(4));
        (view, json::accessor::ComponentType::U16)
    } else {
        let bytes = floats_to_bytes(feature_ids.iter().map(|&id| id as f32));
        (
            builder.vertex_view(&bytes, 4),
            json::accessor::ComponentType::F32,
        )
    };
    builder.accessor(id_view, count, id_type, json::accessor::Type::Scalar, None)
}

/// Triangle indices, 16 bits each unless the primitive has more vertices than 16 bits number.
fn write_indices(
    builder: &mut BinaryBuilder,
    indices: &[u32],
    vertex_count: usize,
) -> json::Index<json::Accessor> {
    let wide = vertex_count > usize::from(u16::MAX);
    let view = builder.index_view(indices, vertex_count, wide);
    builder.accessor(
        view,
        indices.len(),
        if wide {
            json::accessor::ComponentType::U32
        } else {
            json::accessor::ComponentType::U16
        },
        json::accessor::Type::Scalar,
        None,
    )
}

/// The part's material; painted parts carry their colour in their vertices, under white.
fn write_material(
    builder: &mut BinaryBuilder,
    part: Part,
    painted: bool,
) -> json::Index<json::Material> {
    let (mut colour, roughness) = material_of(part);
    if painted {
        colour = [1.0, 1.0, 1.0, 1.0];
    }
    let base_color_texture = match part {
        Part::Facade(glazing) => Some(facades::texture_info(builder, glazing)),
        _ => None,
    };
    builder.root.push(json::Material {
        name: Some(part.name().to_string()),
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_factor: json::material::PbrBaseColorFactor(colour),
            base_color_texture,
            metallic_factor: json::material::StrengthFactor(metallic_of(part)),
            roughness_factor: json::material::StrengthFactor(roughness),
            ..Default::default()
        },
        // A tunnel's lining is seen from inside (through a portal) and from outside (with the
        // ground hidden).
        double_sided: part == Part::TunnelLining,
        ..Default::default()
    })
}

fn asset(description: &TileDescription, enu: Option<&EastNorthUp>) -> json::Asset {
    let b = description.bounds;
    let mut extras = value!({
        "terrastitch": {
            "tile": {"z": description.tile.z, "x": description.tile.x, "y": description.tile.y},
            "bounds": {"west": b.west, "south": b.south, "east": b.east, "north": b.north},
            "tile_size_m": description.size_m,
            "frame": "glTF Y-up. x: Web Mercator metres east of the tile's north-west corner; z: Web Mercator metres south of it; y: elevation in metres times the Web Mercator scale factor 1/cos(latitude) at the vertex. Tiles line up when translated by tile_size_m per step in x or y.",
            "vertical_scale": "mercator_scale_factor_per_vertex",
            "attribution": ATTRIBUTION
        }
    });
    if let Some(enu) = enu {
        extras["terrastitch"]["frame"] = value!("glTF Y-up in metres, east-north-up at the centre of the tile on the WGS 84 ellipsoid: x east, y up, z south. Heights are SRTM heights (above the EGM96 geoid) taken as heights above the ellipsoid. Turned Z-up (x, -z, y), `transform` (column-major) carries a point to Earth-centred, Earth-fixed metres, as a 3D Tiles tile transform does.");
        extras["terrastitch"]["vertical_scale"] = value!("none");
        extras["terrastitch"]["transform"] = value!(enu.transform());
    }
    json::Asset {
        copyright: Some(ATTRIBUTION.to_string()),
        extensions: None,
        extras: Some(serde_json::value::to_raw_value(&extras).expect("asset extras serialize")),
        generator: Some(description.generator.clone()),
        min_version: None,
        version: "2.0".to_string(),
    }
}

/// Wraps JSON and binary chunks in the glb container.
pub fn container(json_bytes: &[u8], binary: &[u8]) -> Vec<u8> {
    // Each chunk padded to four bytes: the JSON with spaces, the binary with zeros.
    let padded = |len: usize| len.div_ceil(4) * 4;
    let (json_len, binary_len) = (padded(json_bytes.len()), padded(binary.len()));
    let total = 12 + 8 + json_len + if binary.is_empty() { 0 } else { 8 + binary_len };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_len as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(json_bytes);
    out.resize(out.len() + json_len - json_bytes.len(), b' ');
    if !binary.is_empty() {
        out.extend_from_slice(&(binary_len as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(binary);
        out.resize(out.len() + binary_len - binary.len(), 0);
    }
    out
}

#[cfg(test)]
mod tests;
