//! Quantized-mesh terrain for Cesium: each tile checked by the spec-based checker in
//! `../shared/tools/qmesh_check.py` and decoded a second time by the `quantized-mesh-tile` reader;
//! the layer description; shared edges between neighbouring `.terrain` tiles.

mod common;

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
        // reqwest here has no gzip support: the body arrives as sent.
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

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn neighbouring_terrain_tiles_share_their_edges() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("cache.sqlite")).await;
    let mut tiles = BTreeMap::new();
    for (x, y) in [(8529, 5973), (8530, 5973), (8529, 5974)] {
        let body = fetch(&server, &format!("/tiles/14/{x}/{y}.terrain"), "")
            .await
            .bytes()
            .await
            .unwrap();
        tiles.insert((x, y), decode_vertices(&gunzip(&body)));
    }
    let edge = |tile: &[(u16, u16, f64)], u_or_v: usize, value: u16| -> Vec<(u16, f64)> {
        let mut e: Vec<(u16, f64)> = tile
            .iter()
            .filter(|v| {
                if u_or_v == 0 {
                    v.0 == value
                } else {
                    v.1 == value
                }
            })
            .map(|v| (if u_or_v == 0 { v.1 } else { v.0 }, v.2))
            .collect();
        e.sort_by_key(|v| v.0);
        e
    };
    let pairs = [
        (
            edge(&tiles[&(8529, 5973)], 0, 32767),
            edge(&tiles[&(8530, 5973)], 0, 0),
        ),
        (
            edge(&tiles[&(8529, 5973)], 1, 0),
            edge(&tiles[&(8529, 5974)], 1, 32767),
        ),
    ];
    for (a, b) in pairs {
        assert!(a.len() >= 2);
        assert_eq!(
            a.iter().map(|v| v.0).collect::<Vec<_>>(),
            b.iter().map(|v| v.0).collect::<Vec<_>>()
        );
        for (va, vb) in a.iter().zip(&b) {
            // Heights are quantized against each tile's own range: equal to within a step.
            assert!((va.1 - vb.1).abs() < 0.02, "{va:?} vs {vb:?}");
        }
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
