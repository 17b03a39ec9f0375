//! Quantized-mesh terrain for Cesium: each tile checked by the spec-based checker in
//! `../shared/tools/qmesh_check.py` and decoded a second time by the `quantized-mesh-tile` reader;
//! the layer description; shared edges between neighbouring `.terrain` tiles.

use crate::common;

use std::collections::BTreeMap;
use std::io::Read;
use std::path::PathBuf;
use std::process::Command;

use common::{repo, TestServer};

const ALL_EXTENSIONS: &str = "application/vnd.quantized-mesh;extensions=octvertexnormals-watermask";

fn python() -> String {
    std::env::var("TERRASTITCH_PYTHON").unwrap_or_else(|_| "python3".to_string())
}

fn checker() -> PathBuf {
    let path = repo().join("../shared/tools/qmesh_check.py");
    assert!(path.exists(), "{} is missing", path.display());
    path
}

async fn fetch(server: &TestServer, path: &str, accept: &str) -> reqwest::Response {
    reqwest::Client::new()
        .get(server.url(path))
        .header("accept", accept)
        .header("accept-encoding", "gzip")
        .send()
        .await
        .expect("request reaches the server")
}

fn gunzip(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    flate2::read::GzDecoder::new(bytes)
        .read_to_end(&mut out)
        .expect("gzip");
    out
}

/// The checker's verdict on one file.
fn check(file: &std::path::Path, z: u32, x: u32, y: u32) -> serde_json::Value {
    let tms_y = (1u32 << z) - 1 - y;
    let output = Command::new(python())
        .arg(checker())
        .arg(file)
        .args([
            "--tile",
            &format!("{z}/{x}/{tms_y}"),
            "--scheme",
            "mercator",
            "--cross-check",
            "--json",
        ])
        .output()
        .expect("python runs");
    let stdout = String::from_utf8_lossy(&output.stdout);
    serde_json::from_str(stdout.trim()).unwrap_or_else(|_| {
        panic!(
            "checker output:\n{stdout}\n{}",
            String::from_utf8_lossy(&output.stderr)
        )
    })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn terrain_tiles_pass_the_spec_checker_and_a_second_reader() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("cache.sqlite")).await;
    let cases = [
        (8529, 5973, ALL_EXTENSIONS, vec![1, 2]),
        (
            8530,
            5973,
            "application/vnd.quantized-mesh;extensions=octvertexnormals",
            vec![1],
        ),
        (8530, 5974, "application/vnd.quantized-mesh", vec![]),
        (
            8527,
            5974,
            "application/vnd.quantized-mesh;extensions=watermask",
            vec![2],
        ),
    ];
    for (x, y, accept, extensions) in cases {
        let response = fetch(&server, &format!("/tiles/14/{x}/{y}.terrain"), accept).await;
        assert_eq!(response.status(), 200);
        assert_eq!(
            response.headers()["content-type"],
            "application/vnd.quantized-mesh"
        );
        assert_eq!(response.headers()["content-encoding"], "gzip");
        // Asked for gzip, and reqwest here has no gzip support: the body arrives as sent.
        let body = response.bytes().await.unwrap();
        assert_eq!(&body[..2], &[0x1f, 0x8b], "gzip magic");
        let file = dir.path().join(format!("{x}_{y}.terrain"));
        std::fs::write(&file, &body).unwrap();
        let report = check(&file, 14, x, y);
        assert_eq!(report["errors"], serde_json::json!([]), "{x}/{y}: {report}");
        let info = &report["info"];
        assert_eq!(
            info["quantized_mesh_tile_agrees"], true,
            "{x}/{y}: {report}"
        );
        assert_eq!(info["extensions"], serde_json::json!(extensions), "{x}/{y}");
        let coverage = info["uv_coverage"].as_f64().unwrap();
        assert!(
            (coverage - 1.0).abs() < 1e-4,
            "{x}/{y}: covers {coverage} of the tile"
        );
        assert!(info["triangleCount"].as_u64().unwrap() >= 2);
        if extensions.contains(&1) {
            assert!(info["normals_up_fraction"].as_f64().unwrap() > 0.99);
        }
    }
    server.stop().await;
}

/// The height quantization step of a tile, metres.
fn height_step(raw: &[u8]) -> f64 {
    let f32_at = |o: usize| f64::from(f32::from_le_bytes(raw[o..o + 4].try_into().unwrap()));
    (f32_at(28) - f32_at(24)) / 32767.0
}

/// Decoded vertices of a tile: (u, v, height in metres).
fn decode_vertices(raw: &[u8]) -> Vec<(u16, u16, f64)> {
    let f32_at = |o: usize| f32::from_le_bytes(raw[o..o + 4].try_into().unwrap());
    let (min, max) = (f64::from(f32_at(24)), f64::from(f32_at(28)));
    let n = u32::from_le_bytes(raw[88..92].try_into().unwrap()) as usize;
    let mut columns = [Vec::new(), Vec::new(), Vec::new()];
    for (k, column) in columns.iter_mut().enumerate() {
        let mut value = 0i32;
        for i in 0..n {
            let o = 92 + (k * n + i) * 2;
            let code = i32::from(u16::from_le_bytes([raw[o], raw[o + 1]]));
            value += (code >> 1) ^ -(code & 1);
            column.push(value);
        }
    }
    (0..n)
        .map(|i| {
            let h = min + f64::from(columns[2][i]) / 32767.0 * (max - min);
            (columns[0][i] as u16, columns[1][i] as u16, h)
        })
        .collect()
}

/// The vertices of a tile with `u` (`axis` 0) or `v` (`axis` 1) equal to `value`, as
/// (position along the edge, height), in order.
fn edge(tile: &[(u16, u16, f64)], axis: usize, value: u16) -> Vec<(u16, f64)> {
    let mut e: Vec<(u16, f64)> = tile
        .iter()
        .filter(|v| {
            if axis == 0 {
                v.0 == value
            } else {
                v.1 == value
            }
        })
        .map(|v| (if axis == 0 { v.1 } else { v.0 }, v.2))
        .collect();
    e.sort_by_key(|v| v.0);
    e
}

/// Fetches the tiles `(z, x, y)` and asserts that tile `west`'s east edge is tile `east`'s west
/// edge, and tile `north`'s south edge is tile `south`'s north edge.
async fn assert_shared_edges(
    server: &TestServer,
    z: u32,
    (west, east): ((u32, u32), (u32, u32)),
    (north, south): ((u32, u32), (u32, u32)),
) {
    let mut tiles = BTreeMap::new();
    for (x, y) in [west, east, north, south] {
        let response = fetch(server, &format!("/tiles/{z}/{x}/{y}.terrain"), "").await;
        assert_eq!(response.status(), 200, "{z}/{x}/{y}");
        let raw = gunzip(&response.bytes().await.unwrap());
        tiles.insert((x, y), (decode_vertices(&raw), height_step(&raw)));
    }
    let pairs = [(west, 0, 32767, east, 0, 0), (north, 1, 0, south, 1, 32767)];
    for (one, axis, value, other, other_axis, other_value) in pairs {
        let a = edge(&tiles[&one].0, axis, value);
        let b = edge(&tiles[&other].0, other_axis, other_value);
        // Heights are quantized against each tile's own range: equal to within the steps.
        let tolerance = tiles[&one].1 + tiles[&other].1;
        assert!(a.len() >= 2);
        assert_eq!(
            a.iter().map(|v| v.0).collect::<Vec<_>>(),
            b.iter().map(|v| v.0).collect::<Vec<_>>(),
            "zoom {z}"
        );
        for (va, vb) in a.iter().zip(&b) {
            assert!(
                (va.1 - vb.1).abs() <= tolerance,
                "zoom {z}: {va:?} vs {vb:?}"
            );
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn neighbouring_terrain_tiles_share_their_edges() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("cache.sqlite")).await;
    let monaco = ((8529, 5973), (8530, 5973));
    assert_shared_edges(&server, 14, monaco, ((8529, 5973), (8529, 5974))).await;
    // Coarser levels too: Monaco's zoom-13 tile and its neighbours.
    assert_shared_edges(
        &server,
        13,
        ((4264, 2986), (4265, 2986)),
        ((4264, 2986), (4264, 2987)),
    )
    .await;
    server.stop().await;
}

/// The tile of zoom `z` that holds Monaco's zoom-14 tile 8529/5973.
fn monaco_at(z: u32) -> (u32, u32) {
    (8529 >> (14 - z), 5973 >> (14 - z))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_coarser_level_is_served_as_terrain_alone() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("cache.sqlite")).await;
    let mut triangles = Vec::new();
    for z in [0, 4, 9, 12, 13] {
        let (x, y) = monaco_at(z);
        let response = fetch(
            &server,
            &format!("/tiles/{z}/{x}/{y}.terrain"),
            ALL_EXTENSIONS,
        )
        .await;
        assert_eq!(response.status(), 200, "zoom {z}");
        let body = response.bytes().await.unwrap();
        let file = dir.path().join(format!("{z}_{x}_{y}.terrain"));
        std::fs::write(&file, &body).unwrap();
        let report = check(&file, z, x, y);
        assert_eq!(
            report["errors"],
            serde_json::json!([]),
            "zoom {z}: {report}"
        );
        let info = &report["info"];
        assert_eq!(
            info["quantized_mesh_tile_agrees"], true,
            "zoom {z}: {report}"
        );
        let coverage = info["uv_coverage"].as_f64().unwrap();
        assert!((coverage - 1.0).abs() < 1e-4, "zoom {z}: covers {coverage}");
        let heights = decode_vertices(&gunzip(&body));
        let highest = heights.iter().map(|v| v.2).fold(f64::MIN, f64::max);
        if z >= 9 {
            // The Alps behind Monaco reach well above 1000 m; a level whose error bound (32 m at
            // zoom 9) is well below that shows them.
            assert!(highest > 300.0, "zoom {z}: highest vertex {highest} m");
        } else {
            // Coarser levels keep the corners and edges at least; nothing is below the sea.
            assert!(highest >= 0.0, "zoom {z}: highest vertex {highest} m");
        }
        triangles.push(info["triangleCount"].as_u64().unwrap());
    }
    // The error bound doubles with each coarser level: no level is the dense grid of samples
    // (131,072 triangles).
    assert!(triangles.iter().all(|&t| t < 50_000), "{triangles:?}");
    // Above zoom 14, glb only at the zooms of far views (not 11); finer terrain not at all.
    for path in ["/tiles/11/1066/746.glb", "/tiles/15/17058/11946.terrain"] {
        let response = fetch(&server, path, "").await;
        assert_eq!(response.status(), 404, "{path}");
        let body: serde_json::Value = response.json().await.unwrap();
        assert!(
            body["error"].as_str().unwrap().contains("not served"),
            "{body}"
        );
    }
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_layer_describes_slippy_map_tiles_in_web_mercator() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("cache.sqlite")).await;
    let layer: serde_json::Value = reqwest::get(server.url("/layer.json"))
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(layer["format"], "quantized-mesh-1.0");
    assert_eq!(layer["projection"], "EPSG:3857");
    assert_eq!(layer["scheme"], "slippyMap");
    assert_eq!(layer["tiles"][0], "tiles/{z}/{x}/{y}.terrain");
    assert_eq!(layer["minzoom"], 0);
    assert_eq!(layer["maxzoom"], 14);
    // Every coarser level is whole.
    for z in 0..14u64 {
        let last = (1u64 << z) - 1;
        assert_eq!(
            layer["available"][z as usize],
            serde_json::json!([{ "startX": 0, "startY": 0, "endX": last, "endY": last }]),
            "zoom {z}"
        );
    }
    let ranges = layer["available"][14].as_array().unwrap();
    let covers = |x: u64, y: u64| {
        ranges.iter().any(|r| {
            (r["startX"].as_u64().unwrap()..=r["endX"].as_u64().unwrap()).contains(&x)
                && (r["startY"].as_u64().unwrap()..=r["endY"].as_u64().unwrap()).contains(&y)
        })
    };
    // The Monaco tile, in the same (slippy) numbering as the URLs, is available.
    assert!(covers(8529, 5973));
    // Its TMS-numbered twin lies outside the data.
    assert!(!covers(8529, (1 << 14) - 1 - 5973));
    server.stop().await;
}
