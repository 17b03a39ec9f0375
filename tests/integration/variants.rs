//! The glb variants: compressed tiles (`EXT_meshopt_compression` over `KHR_mesh_quantization`)
//! carry the plain tile's geometry on the grid neighbours share, so their edges still meet
//! exactly; east-north-up tiles put every vertex where its longitude, latitude and height say
//! on the WGS 84 globe.

use crate::common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use common::compressed::{decode_compressed, CompressedTile};
use common::{decode, render_in_process, validate, DecodedTile, GROUND_NODES};
use terrastitch::geodesy::ecef;
use terrastitch::output::glb::GRID_STEPS_PER_TILE;
use terrastitch::TileId;

/// The Khronos validator finds neither errors nor warnings in the files a variant wrote. It
/// does not know `EXT_meshopt_compression`: in a compressed file it checks the JSON (accessor
/// types, normalized flags, strides, the quantized position accessors' declarations), not the
/// data, which the reader in `common::compressed` decodes and the tests compare.
fn assert_valid(out: &Path, variant: &str) {
    let files: Vec<std::path::PathBuf> = std::fs::read_dir(out.join(variant))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    let paths: Vec<&Path> = files.iter().map(|p| p.as_path()).collect();
    assert!(!paths.is_empty());
    for report in validate(&paths) {
        report.assert_clean();
    }
}

fn render(tile: (u32, u32), variant: &str, out: &Path) -> Vec<u8> {
    let dir = out.join(variant);
    std::fs::create_dir_all(&dir).unwrap();
    render_in_process(
        &format!("14/{}/{}", tile.0, tile.1),
        &["--variant".as_ref(), variant.as_ref()],
        &dir,
    )
}

/// Ground vertices of a compressed tile on one side, as grid steps (along the side, height).
fn grid_edge(tile: &CompressedTile, side: &str) -> BTreeSet<(i64, i64)> {
    let full = GRID_STEPS_PER_TILE as i64;
    let mut vertices = BTreeSet::new();
    for node in GROUND_NODES {
        let Some(grid) = tile.grids.get(node) else {
            assert!(
                tile.tile.primitives(node).is_empty(),
                "{node} not quantized"
            );
            continue;
        };
        for q in grid.positions.iter().flatten() {
            let hit = match side {
                "west" => (q[0] == 0).then_some(q[2]),
                "east" => (q[0] == full).then_some(q[2]),
                "north" => (q[2] == 0).then_some(q[0]),
                "south" => (q[2] == full).then_some(q[0]),
                _ => unreachable!(),
            };
            if let Some(along) = hit {
                vertices.insert((along, q[1]));
            }
        }
    }
    vertices
}

#[test]
fn compressed_tiles_keep_the_geometry_and_share_their_edges() {
    let out = tempfile::tempdir().unwrap();
    let tiles = [(8529, 5973), (8530, 5973), (8529, 5974)];
    let mut compressed = BTreeMap::new();
    let mut plains = BTreeMap::new();
    for tile in tiles {
        let plain_bytes = render(tile, "glb", out.path());
        let meshopt_bytes = render(tile, "glb-meshopt", out.path());
        let plain = decode(&plain_bytes);
        let packed = decode_compressed(&meshopt_bytes);
        println!(
            "14/{}/{}: plain {} bytes, meshopt {} bytes ({:.1} %)",
            tile.0,
            tile.1,
            plain_bytes.len(),
            meshopt_bytes.len(),
            100.0 * meshopt_bytes.len() as f64 / plain_bytes.len() as f64
        );
        assert!(meshopt_bytes.len() * 2 < plain_bytes.len());
        for extension in ["EXT_meshopt_compression", "KHR_mesh_quantization"] {
            assert!(packed.extensions_required.iter().any(|e| e == extension));
        }
        compare(&plain, &packed);
        compressed.insert(tile, packed);
        plains.insert(tile, plain);
    }

    assert_valid(out.path(), "glb-meshopt");

    // Every ground class lies on the shared grid, and the edge vertices neighbours share
    // (exactly, in the plain tiles) are the same grid points in both compressed tiles. A vertex
    // a few centimetres inside an edge may round onto it: such a vertex is counted, not shared.
    let pairs = [
        ((8529, 5973), "east", (8530, 5973), "west"),
        ((8529, 5973), "south", (8529, 5974), "north"),
    ];
    for (a, side_a, b, side_b) in pairs {
        let shared_a = plain_edge(&plains[&a], side_a);
        let shared_b = plain_edge(&plains[&b], side_b);
        assert!(
            shared_a.len() > 50,
            "{a:?} {side_a}: {} vertices",
            shared_a.len()
        );
        assert_eq!(shared_a, shared_b, "{a:?} {side_a} against {b:?} {side_b}");
        let (edge_a, edge_b) = (
            grid_edge(&compressed[&a], side_a),
            grid_edge(&compressed[&b], side_b),
        );
        assert!(shared_a.is_subset(&edge_a), "{a:?} {side_a}");
        assert!(shared_b.is_subset(&edge_b), "{b:?} {side_b}");
        println!(
            "{a:?} {side_a}: {} shared edge vertices on the grid in both tiles; rounded onto the edge: {} and {}",
            shared_a.len(),
            edge_a.len() - shared_a.len(),
            edge_b.len() - shared_b.len()
        );
    }
}

/// Ground vertices of a plain tile exactly on one side, rounded to the grid.
fn plain_edge(tile: &DecodedTile, side: &str) -> BTreeSet<(i64, i64)> {
    let size = tile.tile_size() as f32;
    let step = tile.tile_size() / GRID_STEPS_PER_TILE;
    let steps = |c: f32| (f64::from(c) / step).round() as i64;
    let mut vertices = BTreeSet::new();
    for node in GROUND_NODES {
        for primitive in tile.primitives(node) {
            for p in &primitive.positions {
                let along = match side {
                    "west" => (p[0] == 0.0).then_some(p[2]),
                    "east" => (p[0] == size).then_some(p[2]),
                    "north" => (p[2] == 0.0).then_some(p[0]),
                    "south" => (p[2] == size).then_some(p[0]),
                    _ => unreachable!(),
                };
                if let Some(along) = along {
                    vertices.insert((steps(along), steps(p[1])));
                }
            }
        }
    }
    vertices
}

/// The compressed tile holds the plain one: the same features, nodes, materials and triangles,
/// each vertex within half a grid step, each normal within a byte's precision.
fn compare(plain: &DecodedTile, packed: &CompressedTile) {
    let tile = &packed.tile;
    assert_eq!(plain.features, tile.features);
    assert_eq!(plain.instanced, tile.instanced);
    assert_eq!(
        plain.nodes.keys().collect::<Vec<_>>(),
        tile.nodes.keys().collect::<Vec<_>>()
    );
    let step = plain.tile_size() / GRID_STEPS_PER_TILE;
    for (name, primitives) in &plain.nodes {
        let packed_primitives = tile.primitives(name);
        assert_eq!(primitives.len(), packed_primitives.len(), "{name}");
        let grid = packed.grids.get(name.as_str());
        assert_eq!(
            grid.is_some(),
            !plain.instanced.contains(name),
            "{name}: placed nodes are quantized, instanced models are not"
        );
        for (i, (p, q)) in primitives.iter().zip(packed_primitives).enumerate() {
            assert_eq!(p.material, q.material);
            assert_eq!(p.indices.len(), q.indices.len(), "{name} {}", p.material);
            // The same triangles (as corner positions on the grid with their feature), in any
            // order and starting at any corner.
            let key = |prim: &common::Primitive, t: [usize; 3]| {
                let corners = t.map(|v| {
                    let at = prim.positions[v].map(|c| (f64::from(c) / step).round() as i64);
                    (at, prim.feature_ids[v])
                });
                // The smallest rotation (two corners may share a grid point).
                (0..3)
                    .map(|k| {
                        let mut rotated = corners;
                        rotated.rotate_left(k);
                        rotated
                    })
                    .min()
                    .unwrap()
            };
            if let Some(grid) = grid {
                let mut a: Vec<_> = p.triangles().map(|t| key(p, t)).collect();
                let mut b: Vec<_> = q.triangles().map(|t| key(q, t)).collect();
                a.sort();
                b.sort();
                if a != b {
                    let only_a: Vec<_> = a.iter().filter(|t| !b.contains(t)).take(3).collect();
                    let only_b: Vec<_> = b.iter().filter(|t| !a.contains(t)).take(3).collect();
                    panic!(
                        "{name} {}: triangles differ: plain only {only_a:?}, compressed only {only_b:?}",
                        p.material
                    );
                }
                // The grid steps are the plain positions rounded.
                let grid_positions: BTreeSet<[i64; 3]> =
                    grid.positions[i].iter().copied().collect();
                let rounded: BTreeSet<[i64; 3]> = p
                    .positions
                    .iter()
                    .map(|v| v.map(|c| (f64::from(c) / step).round() as i64))
                    .collect();
                assert_eq!(grid_positions, rounded, "{name} {}", p.material);
            }
            // Each vertex has a vertex of the plain primitive at its grid point (at its very
            // position where not quantized) with the same feature and a normal within a
            // byte's precision.
            let at = |v: &[f32; 3]| match grid {
                Some(_) => v.map(|c| (f64::from(c) / step).round() as i64),
                None => v.map(|c| i64::from(c.to_bits())),
            };
            let mut plain_normals: BTreeMap<([i64; 3], u32), Vec<[f32; 3]>> = BTreeMap::new();
            for ((v, n), f) in p.positions.iter().zip(&p.normals).zip(&p.feature_ids) {
                plain_normals.entry((at(v), *f)).or_default().push(*n);
            }
            for ((v, n), f) in q.positions.iter().zip(&q.normals).zip(&q.feature_ids) {
                if grid.is_some() {
                    let off = (0..3)
                        .map(|k| (f64::from(v[k]) / step - (f64::from(v[k]) / step).round()).abs())
                        .fold(0.0, f64::max);
                    assert!(
                        off < 0.01,
                        "{name}: a dequantized vertex off the grid by {off}"
                    );
                }
                let normals = plain_normals
                    .get(&(at(v), *f))
                    .unwrap_or_else(|| panic!("{name}: no plain vertex at {v:?}"));
                assert!(
                    normals
                        .iter()
                        .any(|m| (0..3).map(|k| n[k] * m[k]).sum::<f32>() > 0.99),
                    "{name}: normal {n:?} against {normals:?}"
                );
            }
        }
    }
}

#[test]
fn east_north_up_tiles_sit_where_their_coordinates_say() {
    let out = tempfile::tempdir().unwrap();
    let tile_xy = (8529, 5973);
    let tile = TileId::new(14, 8529, 5973).unwrap();
    let plain_bytes = render(tile_xy, "glb", out.path());
    let plain = decode(&plain_bytes);
    let enu_bytes = render(tile_xy, "glb-enu", out.path());
    let enu = decode(&enu_bytes);
    let packed = decode_compressed(&render(tile_xy, "glb-enu-meshopt", out.path()));
    let transform: Vec<f64> = enu.asset_extras["terrastitch"]["transform"]
        .as_array()
        .expect("the transform in the asset's extras")
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(transform.len(), 16);
    let place = |p: [f32; 3]| -> [f64; 3] {
        // Y-up turned Z-up as a 3D Tiles runtime does, then the tile transform.
        let q = [f64::from(p[0]), -f64::from(p[2]), f64::from(p[1])];
        std::array::from_fn(|i| {
            transform[i] * q[0]
                + transform[4 + i] * q[1]
                + transform[8 + i] * q[2]
                + transform[12 + i]
        })
    };
    let frame = tile.frame();
    let mut checked = 0;
    let mut worst = 0.0f64;
    for (name, primitives) in plain.placed_nodes() {
        for (p, e) in primitives.iter().zip(enu.primitives(name)) {
            assert_eq!(p.positions.len(), e.positions.len());
            for (a, b) in p.positions.iter().zip(&e.positions).step_by(7) {
                let (x, z) = (f64::from(a[0]), f64::from(a[2]));
                let (lon, lat) = frame.to_lon_lat(x, z);
                let height = f64::from(a[1]) / frame.scale_at(z);
                let expected = ecef(lon, lat, height);
                let placed = place(*b);
                let error = (0..3)
                    .map(|i| (placed[i] - expected[i]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                worst = worst.max(error);
                checked += 1;
            }
        }
    }
    println!("{checked} vertices placed on the globe, worst {worst:.4} m off");
    assert_valid(out.path(), "glb-enu");
    assert_valid(out.path(), "glb-enu-meshopt");
    assert!(checked > 10_000, "{checked}");
    assert!(worst < 0.01, "{worst} m");
    // Up is up: the terrain's normals point away from the Earth's centre.
    let terrain = &enu.primitives("terrain")[0];
    let upward = terrain.normals.iter().filter(|n| n[1] > 0.0).count();
    assert!(upward * 100 > terrain.normals.len() * 99);
    // The compressed form keeps float positions (no shared grid in a frame of its own).
    assert!(packed.grids.is_empty());
    assert_eq!(packed.tile.features, enu.features);
    let mut compared = 0;
    for (name, primitives) in enu.placed_nodes() {
        assert_eq!(
            primitives.len(),
            packed.tile.primitives(name).len(),
            "{name}"
        );
        for (e, c) in primitives.iter().zip(packed.tile.primitives(name)) {
            compared += 1;
            assert_eq!(e.indices.len(), c.indices.len());
            let before: BTreeSet<[u32; 3]> =
                e.positions.iter().map(|p| p.map(f32::to_bits)).collect();
            let after: BTreeSet<[u32; 3]> =
                c.positions.iter().map(|p| p.map(f32::to_bits)).collect();
            assert_eq!(before, after, "{name}");
        }
    }
    assert!(compared > 10, "{compared} primitives compared");

    // Instances (trees, objects): placed like vertices, scaled in true metres.
    let (plain_instances, enu_instances) = (instances(&plain_bytes), instances(&enu_bytes));
    assert!(!plain_instances.is_empty());
    assert_eq!(
        plain_instances.keys().collect::<Vec<_>>(),
        enu_instances.keys().collect::<Vec<_>>()
    );
    let mut placed = 0;
    for (name, (translations, scales)) in &plain_instances {
        let (enu_translations, enu_scales) = &enu_instances[name];
        assert_eq!(translations.len(), enu_translations.len(), "{name}");
        for i in 0..translations.len() {
            let (t, s) = (translations[i], scales[i]);
            let (x, z) = (f64::from(t[0]), f64::from(t[2]));
            let (lon, lat) = frame.to_lon_lat(x, z);
            let expected = ecef(lon, lat, f64::from(t[1]) / frame.scale_at(z));
            let at = place(enu_translations[i]);
            let error = (0..3).map(|k| (at[k] - expected[k]).powi(2)).sum::<f64>();
            assert!(error.sqrt() < 0.01, "{name} {i}: {} m", error.sqrt());
            for k in 0..3 {
                let true_metres = f64::from(s[k]) / frame.scale_at(z);
                assert!((f64::from(enu_scales[i][k]) - true_metres).abs() < 1e-3 * true_metres);
            }
            placed += 1;
        }
    }
    println!("{placed} instances placed on the globe");
}

/// Each instance's translation and scale, in order.
type Placements = (Vec<[f32; 3]>, Vec<[f32; 3]>);

/// Translations and scales of each instanced node (`EXT_mesh_gpu_instancing`) of a plain glb.
fn instances(bytes: &[u8]) -> BTreeMap<String, Placements> {
    let gltf = gltf::Gltf::from_slice(bytes).expect("valid glb");
    let blob = gltf.blob.clone().expect("binary chunk");
    let mut out = BTreeMap::new();
    for node in gltf.document.nodes() {
        let Some(extension) = node.extension_value("EXT_mesh_gpu_instancing") else {
            continue;
        };
        let read = |attribute: &str| -> Vec<[f32; 3]> {
            let index = extension["attributes"][attribute].as_u64().unwrap() as usize;
            let accessor = gltf.document.accessors().nth(index).unwrap();
            gltf::accessor::Iter::<[f32; 3]>::new(accessor, |_| Some(&blob[..]))
                .unwrap()
                .collect()
        };
        out.insert(
            node.name().unwrap_or_default().to_string(),
            (read("TRANSLATION"), read("SCALE")),
        );
    }
    out
}
