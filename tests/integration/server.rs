//! How the server behaves as an HTTP service on real renders: content codings, the time limit,
//! stale tiles, the admin routes, readiness, metrics and request ids, shutdown. The routes'
//! rules on a provider that renders nothing (the queue, single flight, validators) are in
//! `tests/router.rs`.

use crate::common;

use std::io::Read;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use common::{sample_osm, sample_srtm, wait_until, TestServer};
use terrastitch::cache::encoding::Bodies;
use terrastitch::cache::{etag_of, Provenance, SqliteStore, StoredTile, TileFilter, TileStore};
use terrastitch::config::{Config, ServerConfig};
use terrastitch::format::{Format, TileKey};
use terrastitch::provider::{Inputs, Renderer};
use terrastitch::TileId;

fn sources() -> Inputs {
    Inputs::open(&[sample_osm()], &sample_srtm(), 14).expect("sample data loads")
}

async fn start(dir: &std::path::Path, config: ServerConfig) -> TestServer {
    TestServer::start_with(&dir.join("cache.sqlite"), sources(), &config).await
}

fn two_threads() -> ServerConfig {
    ServerConfig {
        render_threads: 2,
        ..ServerConfig::default()
    }
}

async fn wait_for_metric(server: &TestServer, name: &str, at_least: f64) {
    let deadline = Instant::now() + common::HUNG;
    while server.metric(name).await < at_least {
        assert!(Instant::now() < deadline, "{name} never reached {at_least}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// Every client gets the smallest coding it accepts, each coding with its own strong validator,
/// all decoding to the same tile; the validator of the coding a request would get makes a `304`,
/// another coding's does not.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn codings_are_negotiated_and_each_has_its_own_validator() {
    let dir = tempfile::tempdir().unwrap();
    let server = start(dir.path(), two_threads()).await;
    let path = "/tiles/14/8527/5974.glb";
    let mut bodies = Vec::new();
    let mut etags = Vec::new();
    for accept in ["", "gzip", "br", "gzip, deflate, br", "br;q=0, gzip"] {
        let response = server.get(path, &[("accept-encoding", accept)]).await;
        assert_eq!(response.status(), 200);
        let headers = response.headers().clone();
        let vary = headers["vary"].to_str().unwrap().to_lowercase();
        assert!(vary.contains("accept-encoding"), "{vary}");
        let coding = headers
            .get("content-encoding")
            .map(|v| v.to_str().unwrap().to_string());
        let expected = match accept {
            "" => None,
            "gzip" | "br;q=0, gzip" => Some("gzip"),
            _ => Some("br"),
        };
        assert_eq!(coding.as_deref(), expected, "Accept-Encoding: {accept}");
        let raw = response.bytes().await.unwrap().to_vec();
        let decoded = match coding.as_deref() {
            Some("gzip") => {
                let mut out = Vec::new();
                flate2::read::GzDecoder::new(&raw[..])
                    .read_to_end(&mut out)
                    .unwrap();
                out
            }
            Some("br") => {
                let mut out = Vec::new();
                brotli::Decompressor::new(&raw[..], 4096)
                    .read_to_end(&mut out)
                    .unwrap();
                out
            }
            _ => raw.clone(),
        };
        assert_eq!(&decoded[..4], b"glTF");
        bodies.push((coding, raw.len(), decoded));
        etags.push(headers["etag"].to_str().unwrap().to_string());
    }
    let identity = &bodies[0].2;
    assert!(bodies.iter().all(|(_, _, decoded)| decoded == identity));
    let (gzip_len, br_len) = (bodies[1].1, bodies[2].1);
    assert!(
        br_len < gzip_len && gzip_len < identity.len() / 2,
        "{br_len} {gzip_len} {}",
        identity.len()
    );
    assert_eq!(
        etags[0],
        etag_of(identity),
        "the identity validator is the content's digest"
    );
    let distinct: std::collections::BTreeSet<&String> = etags[..3].iter().collect();
    assert_eq!(distinct.len(), 3, "{etags:?}");
    for (held, etag) in etags[..3].iter().enumerate() {
        for (asked, accept) in ["", "gzip", "br"].iter().enumerate() {
            let response = server
                .get(
                    path,
                    &[("if-none-match", etag), ("accept-encoding", accept)],
                )
                .await;
            let expected = if held == asked { 304 } else { 200 };
            assert_eq!(response.status(), expected, "{etag} / {accept}");
            if expected == 304 {
                assert_eq!(response.headers()["etag"], etag.as_str());
            }
            let _ = response.bytes().await;
        }
    }
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_render_past_its_time_limit_is_stopped_with_a_503() {
    let dir = tempfile::tempdir().unwrap();
    let config = ServerConfig {
        render_threads: 1,
        render_timeout_ms: 1,
        ..ServerConfig::default()
    };
    let server = start(dir.path(), config).await;
    let response = server.get("/tiles/14/8529/5973.glb", &[]).await;
    assert_eq!(response.status(), 503);
    assert!(response.headers().contains_key("retry-after"));
    let body = response.text().await.unwrap();
    assert!(body.contains("longer than its limit"), "{body}");
    assert_eq!(
        server.metric("terrastitch_render_timeouts_total").await,
        1.0
    );
    assert_eq!(server.state.cache.reader().usage().unwrap().tiles, 0);
    // Asked again, the tile is not tried again: the same error, at once.
    let again = server.get("/tiles/14/8529/5973.glb", &[]).await;
    assert_eq!(again.status(), 503);
    let body = again.text().await.unwrap();
    assert!(
        body.contains("longer than its limit") && body.contains("not tried again"),
        "{body}"
    );
    assert_eq!(server.metric("terrastitch_renders_total").await, 1.0);
    server.stop().await;
}

/// A stored tile made by another pipeline is served at once, marked stale, and replaced in
/// the background by a tile made now.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stale_tile_is_served_while_it_is_made_again() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache.sqlite");
    let key = TileKey {
        tile: TileId {
            z: 14,
            x: 8527,
            y: 5974,
        },
        format: Format::GLB,
    };
    {
        let store = SqliteStore::open(&cache, None).unwrap();
        let old = b"a tile from an older pipeline".to_vec();
        store
            .put(
                &key,
                &StoredTile {
                    etag: etag_of(&old),
                    bodies: Bodies::compress(old).unwrap(),
                    made_by: Provenance {
                        pipeline: "0.0.0+old".to_string(),
                        sources: "old".to_string(),
                    },
                    created_at: 1,
                },
            )
            .unwrap();
    }
    let server = TestServer::start_with(&cache, sources(), &two_threads()).await;
    let stale = server.get("/tiles/14/8527/5974.glb", &[]).await;
    assert_eq!(stale.status(), 200);
    assert_eq!(stale.headers()["x-cache"], "stale");
    assert_eq!(
        stale.bytes().await.unwrap().as_ref(),
        b"a tile from an older pipeline"
    );
    wait_for_metric(&server, "terrastitch_regenerations_total", 1.0).await;
    let fresh = server.get("/tiles/14/8527/5974.glb", &[]).await;
    assert_eq!(fresh.headers()["x-cache"], "hit");
    assert_eq!(&fresh.bytes().await.unwrap()[..4], b"glTF");
    let stored = server.state.cache.reader().list(&TileFilter::All).unwrap();
    assert_eq!(stored.len(), 1);
    let renderer = server.renderer.as_ref().unwrap();
    assert_eq!(stored[0].made_by.pipeline, renderer.pipeline());
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn admin_routes_need_the_token_then_purge_and_regenerate() {
    let dir = tempfile::tempdir().unwrap();
    // Without a token configured the routes are off.
    let off = start(dir.path(), two_threads()).await;
    let response = reqwest::Client::new()
        .post(off.url("/admin/purge"))
        .body(r#"{"all": true}"#)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 404);
    let _ = response.bytes().await;
    off.stop().await;

    let dir = tempfile::tempdir().unwrap();
    let config = ServerConfig {
        admin_token: "s3cret-token".to_string(),
        ..two_threads()
    };
    let server = start(dir.path(), config).await;
    let client = reqwest::Client::new();
    let admin = |route: &str, token: Option<&str>, body: &str| {
        let mut request = client.post(server.url(route)).body(body.to_string());
        if let Some(token) = token {
            request = request.header("authorization", format!("Bearer {token}"));
        }
        request.send()
    };
    for token in [None, Some("wrong")] {
        let response = admin("/admin/purge", token, r#"{"all": true}"#)
            .await
            .unwrap();
        assert_eq!(response.status(), 401);
        assert!(response.headers().contains_key("www-authenticate"));
        let json: serde_json::Value = response.json().await.unwrap();
        assert!(json["error"].is_string());
    }
    let response = admin("/admin/purge", Some("s3cret-token"), r#"{"everything": 1}"#)
        .await
        .unwrap();
    assert_eq!(response.status(), 400);
    let _ = response.bytes().await;

    for tile in ["8527/5974", "8528/5974"] {
        let response = server.get(&format!("/tiles/14/{tile}.glb"), &[]).await;
        assert_eq!(response.headers()["x-cache"], "miss");
        let _ = response.bytes().await;
    }
    // Regeneration makes the tile again in the background.
    let response = admin(
        "/admin/regenerate",
        Some("s3cret-token"),
        r#"{"tiles": ["14/8527/5974"]}"#,
    )
    .await
    .unwrap();
    assert_eq!(response.status(), 202);
    let json: serde_json::Value = response.json().await.unwrap();
    assert_eq!(json["queued"], 1);
    wait_for_metric(&server, "terrastitch_regenerations_total", 1.0).await;
    assert_eq!(server.metric("terrastitch_renders_total").await, 3.0);

    // Purging a box removes its tiles from the store and from memory.
    let bounds = TileId {
        z: 14,
        x: 8527,
        y: 5974,
    }
    .bounds();
    let inner = format!(
        r#"{{"bbox": [{}, {}, {}, {}]}}"#,
        bounds.west + 1e-4,
        bounds.south + 1e-4,
        bounds.east - 1e-4,
        bounds.north - 1e-4
    );
    let response = admin("/admin/purge", Some("s3cret-token"), &inner)
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    let json: serde_json::Value = response.json().await.unwrap();
    assert_eq!(json["removed"], 1);
    let again = server.get("/tiles/14/8527/5974.glb", &[]).await;
    assert_eq!(again.headers()["x-cache"], "miss");
    let kept = server.get("/tiles/14/8528/5974.glb", &[]).await;
    assert_eq!(kept.headers()["x-cache"], "hit");
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn not_ready_until_the_sources_are_loaded() {
    let dir = tempfile::tempdir().unwrap();
    let state = TestServer::state(&dir.path().join("cache.sqlite"), &two_threads());
    let server = TestServer::start_state(state).await;
    assert_eq!(server.get("/health", &[]).await.status(), 200);
    let ready = server.get("/ready", &[]).await;
    assert_eq!(ready.status(), 503);
    let json: serde_json::Value = ready.json().await.unwrap();
    assert_eq!(json["status"], "not ready");
    let tile = server.get("/tiles/14/8527/5974.glb", &[]).await;
    assert_eq!(tile.status(), 503);
    assert!(tile.headers().contains_key("retry-after"));
    let _ = tile.bytes().await;
    let renderer = Renderer::new(sources(), Config::default().render, 14);
    server.state.provide(std::sync::Arc::new(renderer));
    let ready = server.get("/ready", &[]).await;
    assert_eq!(ready.status(), 200);
    let json: serde_json::Value = ready.json().await.unwrap();
    assert_eq!(json["srtm_files"], 1);
    server.stop().await;
}

/// `/metrics` counts responses by route and status and times renders by stage; every response
/// carries a request id, the client's own when it sent one.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn metrics_count_routes_and_stages_and_responses_carry_request_ids() {
    let dir = tempfile::tempdir().unwrap();
    let server = start(dir.path(), two_threads()).await;
    let tile = server.get("/tiles/14/8527/5974.glb", &[]).await;
    let generated = tile.headers()["x-request-id"].to_str().unwrap().to_string();
    assert!(!generated.is_empty());
    let _ = tile.bytes().await;
    let wrong_method = reqwest::Client::new()
        .delete(server.url("/tiles/14/8527/5974.glb"))
        .send()
        .await
        .unwrap();
    assert_eq!(wrong_method.status(), 405);
    let json: serde_json::Value = wrong_method.json().await.unwrap();
    assert!(json["error"].as_str().unwrap().contains("DELETE"), "{json}");
    let echoed = server
        .get("/nowhere", &[("x-request-id", "client-chosen-42")])
        .await;
    assert_eq!(echoed.status(), 404);
    assert_eq!(echoed.headers()["x-request-id"], "client-chosen-42");
    let other = server.get("/health", &[]).await;
    assert_ne!(other.headers()["x-request-id"].to_str().unwrap(), generated);

    let text = server.get("/metrics", &[]).await.text().await.unwrap();
    for line in [
        "terrastitch_http_requests_total{route=\"/tiles/{z}/{x}/{file}\",status=\"200\"} 1",
        "terrastitch_http_requests_total{route=\"unmatched\",status=\"404\"} 1",
        "terrastitch_render_stage_seconds_count{stage=\"total\"} 1",
        "terrastitch_render_stage_seconds_count{stage=\"structures\"} 1",
        "terrastitch_render_stage_seconds_bucket{stage=\"total\",le=\"+Inf\"} 1",
        "terrastitch_cache_misses_total 1",
        "terrastitch_render_queue{state=\"waiting\"} 0",
        "terrastitch_downloads_total 0",
    ] {
        assert!(text.contains(line), "missing {line} in\n{text}");
    }
    server.stop().await;
}

/// Shutting down lets a render in flight finish and its client get the tile.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shutdown_finishes_the_renders_in_flight() {
    let dir = tempfile::tempdir().unwrap();
    let server = start(dir.path(), two_threads()).await;
    let url = server.url("/tiles/14/8529/5973.glb");
    let request = tokio::spawn(async move {
        let response = reqwest::get(url).await.unwrap();
        (
            response.status().as_u16(),
            response.bytes().await.unwrap().len(),
        )
    });
    // Stopped once the render is under way.
    let state = server.state.clone();
    wait_until("the render to begin", || {
        state.pool_gauges().running > 0 || state.metrics.renders.load(Ordering::Relaxed) > 0
    })
    .await;
    let store = server.state.cache.reader();
    server.stop().await;
    let (status, len) = request.await.unwrap();
    assert_eq!(status, 200);
    assert!(len > 1000);
    assert_eq!(store.usage().unwrap().tiles, 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_3d_tiles_routes_walk_down_to_content_and_refuse_what_is_not_there() {
    let dir = tempfile::tempdir().unwrap();
    let server = start(dir.path(), two_threads()).await;
    let json = |response: reqwest::Response| async move {
        let status = response.status().as_u16();
        let body: serde_json::Value = response.json().await.expect("a JSON body");
        (status, body)
    };

    // The root, then a child tileset, then a content tile it names, all as the URIs say.
    let (status, root) = json(server.get("/tileset.json?compress=meshopt", &[]).await).await;
    assert_eq!(status, 200, "{root}");
    assert_eq!(root["asset"]["version"], "1.1");
    let child = root["root"]["children"][0]["content"]["uri"]
        .as_str()
        .expect("a child tileset")
        .to_string();
    assert!(child.starts_with("3dtiles/") && child.ends_with(".json?compress=meshopt"));
    // The same root in the folder of the files it names: its URIs start there.
    let (status, in_folder) = json(server.get("/3dtiles/tileset.json", &[]).await).await;
    assert_eq!(status, 200, "{in_folder}");
    assert_eq!(
        format!(
            "3dtiles/{}",
            in_folder["root"]["children"][0]["content"]["uri"]
                .as_str()
                .unwrap()
        ),
        child.trim_end_matches("?compress=meshopt"),
    );
    let (status, subtree) = json(server.get(&format!("/{child}"), &[]).await).await;
    assert_eq!(status, 200, "{subtree}");
    let leaves = subtree["root"]["children"].as_array().unwrap();
    assert!(!leaves.is_empty());
    // Every leaf is a tile the server can make: its SRTM file is there.
    let sources = sources();
    let outer = subtree["root"]["boundingVolume"]["region"]
        .as_array()
        .unwrap();
    for leaf in leaves {
        let uri = leaf["content"]["uri"].as_str().unwrap();
        let path = uri.trim_start_matches("../../").split('?').next().unwrap();
        let parts: Vec<u64> = path
            .trim_end_matches(".glb")
            .split('/')
            .map(|p| p.parse().unwrap())
            .collect();
        let tile = TileId::new(parts[0] as u32, parts[1], parts[2]).unwrap();
        assert!(sources.check_coverage(tile).is_ok(), "{tile} listed");
        let region = leaf["boundingVolume"]["region"].as_array().unwrap();
        let v = |r: &Vec<serde_json::Value>, i: usize| r[i].as_f64().unwrap();
        assert!(
            v(region, 4) >= v(outer, 4) && v(region, 5) <= v(outer, 5),
            "{leaf}"
        );
    }
    let uri = leaves[0]["content"]["uri"].as_str().unwrap();
    let content = format!("/3dtiles/{}", uri.trim_start_matches("../../"));
    let response = server.get(&content, &[]).await;
    assert_eq!(response.status(), 200);
    assert_eq!(
        response.headers()["content-type"].to_str().unwrap(),
        "model/gltf-binary"
    );
    let body = response.bytes().await.unwrap();
    assert_eq!(&body[0..4], b"glTF");

    // What is not there is a JSON error.
    for (path, expected) in [
        ("/3dtiles/13/4265/2986.json", 404),
        ("/3dtiles/12/0/0.json", 404),
        ("/3dtiles/14/8529/5973.terrain", 400),
        ("/3dtiles/14/abc/5973.glb", 400),
        ("/tileset.json?compress=draco", 400),
        ("/3dtiles/14/8529/5973.glb?compress=zstd", 400),
    ] {
        let (status, body) = json(server.get(path, &[]).await).await;
        assert_eq!(status, expected, "{path}: {body}");
        assert!(body["error"].is_string(), "{path}: {body}");
    }
    server.stop().await;
}

/// The server's renders share one memo of solved LP components: a road or bridge that reaches
/// two neighbouring tiles is solved for the first and found for the second, and `/metrics`
/// says so.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_component_one_tile_solved_is_found_by_its_neighbour() {
    let dir = tempfile::tempdir().unwrap();
    let server = start(dir.path(), two_threads()).await;
    let found = |text: &str| common::metric_in(text, "terrastitch_lp_components_found_total");
    let metrics = || async { server.get("/metrics", &[]).await.text().await.unwrap() };
    let first = server.get("/tiles/14/8529/5973.glb", &[]).await;
    assert_eq!(first.status(), 200);
    let _ = first.bytes().await;
    let after_one = found(&metrics().await).expect("the metric is written");
    let second = server.get("/tiles/14/8530/5973.glb", &[]).await;
    assert_eq!(second.status(), 200);
    let _ = second.bytes().await;
    let after_two = found(&metrics().await).expect("the metric is written");
    assert!(
        after_two > after_one,
        "components found: {after_one} after one tile, {after_two} after its neighbour"
    );
    server.stop().await;
}
