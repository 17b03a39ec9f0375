//! The served tile, end to end, on the bundled Monaco sample: validity, frame, feature table,
//! stitching of roads and buildings into the ground, caching, and errors.

use crate::common;

use std::collections::BTreeMap;

use common::{corners, decode, validate, DecodedTile, GroundLocator, TestServer, GROUND_NODES};
use terrastitch::mesh::{dot, triangle_normal};
use terrastitch::osm::bounds_of;
use terrastitch::provider::Inputs;
use terrastitch::TileId;

/// Tiles with different characters: dense buildings on a 616 m slope; bridges and the
/// coastline; the steepest (Èze).
const TEST_TILES: [(u32, u32); 3] = [(8529, 5973), (8530, 5973), (8527, 5974)];

async fn fetch(server: &TestServer, path: &str) -> reqwest::Response {
    reqwest::get(server.url(path))
        .await
        .expect("request reaches the server")
}

fn ground_corners(tile: &DecodedTile, except: &str) -> Vec<[[f64; 3]; 3]> {
    GROUND_NODES
        .iter()
        .filter(|&&n| n != except)
        .flat_map(|n| corners(tile.primitives(n)))
        .collect()
}

/// Buildings of the extract whose centroid lies in the tile, and those whose box touches it.
fn extract_building_range(sources: &Inputs, tile: TileId) -> (usize, usize) {
    let b = tile.bounds();
    let mut centred = 0;
    let mut touching = 0;
    for way in &common::whole(sources).data().ways {
        if !way.tags.is_set("building") || !way.is_closed() {
            continue;
        }
        let Some(bounds) = bounds_of(&way.positions) else {
            continue;
        };
        let n = way.positions.len() as f64;
        let lon = way.positions.iter().map(|p| p.lon).sum::<f64>() / n;
        let lat = way.positions.iter().map(|p| p.lat).sum::<f64>() / n;
        if (b.west..b.east).contains(&lon) && (b.south..b.north).contains(&lat) {
            centred += 1;
        }
        if bounds.west <= b.east
            && b.west <= bounds.east
            && bounds.south <= b.north
            && b.south <= bounds.north
        {
            touching += 1;
        }
    }
    (centred, touching)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn monaco_tiles_are_valid_and_stitched() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("cache.sqlite")).await;
    let mut files = Vec::new();
    for (x, y) in TEST_TILES {
        let response = fetch(&server, &format!("/tiles/14/{x}/{y}.glb")).await;
        assert_eq!(response.status(), 200);
        assert_eq!(response.headers()["content-type"], "model/gltf-binary");
        let bytes = response.bytes().await.unwrap();
        let path = dir.path().join(format!("14_{x}_{y}.glb"));
        std::fs::write(&path, &bytes).unwrap();
        files.push((TileId { z: 14, x, y }, path, bytes));
    }

    let paths: Vec<&std::path::Path> = files.iter().map(|f| f.1.as_path()).collect();
    for report in validate(&paths) {
        report.assert_clean();
        // One draw call per material present: terrain, the road pavings (4), railway, water,
        // blank walls and roofs by finish (6), facades (4), lines and crossings (2), the land
        // covers (18), the barriers (5), power lines, a trunk and a crown per tree model (6)
        // and the object models (17).
        let draw_calls = report.draw_calls.expect("draw calls reported");
        assert!((4..=66).contains(&draw_calls), "{} draw calls", draw_calls);
    }

    for (tile, _, bytes) in &files {
        let decoded = decode(bytes);
        check_frame(&decoded, *tile);
        check_feature_table(&decoded, server.inputs(), *tile);
        check_roads_lie_on_the_ground(&decoded, *tile);
        check_walls_reach_the_ground(&decoded, *tile);
        check_ground_faces_up(&decoded);
    }
    server.stop().await;
}

fn check_frame(tile: &DecodedTile, id: TileId) {
    let size = tile.tile_size();
    assert!((size - id.size_m()).abs() < 1e-6);
    let extras = &tile.asset_extras["terrastitch"];
    assert_eq!(extras["tile"]["x"], id.x);
    assert_eq!(extras["tile"]["y"], id.y);
    assert!((extras["bounds"]["south"].as_f64().unwrap() - id.bounds().south).abs() < 1e-12);
    let ground = ground_corners(tile, "");
    let points = ground.iter().flatten();
    let min_x = points.clone().map(|p| p[0]).fold(f64::MAX, f64::min);
    let max_x = points.clone().map(|p| p[0]).fold(f64::MIN, f64::max);
    let min_z = points.clone().map(|p| p[2]).fold(f64::MAX, f64::min);
    let max_z = points.clone().map(|p| p[2]).fold(f64::MIN, f64::max);
    let s = f64::from(size as f32);
    assert_eq!(
        (min_x, min_z),
        (0.0, 0.0),
        "{id}: ground starts at the north-west corner"
    );
    assert_eq!(
        (max_x, max_z),
        (s, s),
        "{id}: ground ends at the south-east corner"
    );
    // Nothing of the tile's own geometry lies outside its square.
    for (_, primitives) in tile.placed_nodes() {
        for p in primitives.iter().flat_map(|p| &p.positions) {
            assert!(
                p[0] >= 0.0 && f64::from(p[0]) <= s && p[2] >= 0.0 && f64::from(p[2]) <= s,
                "{id}: {p:?}"
            );
        }
    }
    // The ground covers the square exactly once (areas in the x/z plane).
    let area: f64 = ground
        .iter()
        .map(|[a, b, c]| {
            ((b[0] - a[0]) * (c[2] - a[2]) - (c[0] - a[0]) * (b[2] - a[2])).abs() / 2.0
        })
        .sum();
    assert!(
        area < s * s * 1.0001,
        "{id}: ground area {area} exceeds the tile"
    );
    assert!(area > s * s * 0.5, "{id}: ground area {area} is too small");
}

fn check_feature_table(tile: &DecodedTile, sources: &Inputs, id: TileId) {
    let features = &tile.features;
    assert_eq!(features[0].class, "terrain");
    // (Instanced nodes carry their features per instance; `tests/features.rs` reads those.)
    for (node, primitives) in tile.placed_nodes() {
        // What stands along a road's sides is the road's.
        let class = if node == "roadside" {
            "road"
        } else {
            node.as_str()
        };
        for primitive in primitives {
            for &fid in &primitive.feature_ids {
                let feature = &features[fid as usize];
                assert_eq!(feature.class, class, "{id}: feature {fid} in node {node}");
            }
        }
    }
    let buildings: Vec<_> = features.iter().filter(|f| f.class == "building").collect();
    for b in &buildings {
        assert!(b.osm_type == "way" || b.osm_type == "relation");
        assert!(b.osm_id > 0);
        assert!(b.tags.contains_key("building"));
    }
    let (centred, touching) = extract_building_range(sources, id);
    let ways = buildings.iter().filter(|b| b.osm_type == "way").count();
    assert!(
        (centred..=touching).contains(&ways),
        "{id}: {ways} building ways in the table, extract has {centred} centred in the tile and {touching} touching it"
    );
    let roads = features.iter().filter(|f| f.class == "road").count();
    assert!(roads > 10, "{id}: only {roads} roads");
}

fn check_roads_lie_on_the_ground(tile: &DecodedTile, id: TileId) {
    let locator = GroundLocator::new(ground_corners(tile, "road"), tile.tile_size());
    let mut checked = 0;
    let mut total = 0;
    for primitive in tile.primitives("road") {
        for p in &primitive.positions {
            total += 1;
            let heights = locator.heights_at(f64::from(p[0]), f64::from(p[2]), 1e-6);
            if heights.is_empty() {
                continue;
            }
            checked += 1;
            for h in heights {
                assert!(
                    (f64::from(p[1]) - h).abs() <= 0.05,
                    "{id}: road vertex {p:?} is {h} above ground"
                );
            }
        }
    }
    assert!(
        checked * 3 > total,
        "{id}: only {checked} of {total} road vertices had ground beside them"
    );
}

fn check_walls_reach_the_ground(tile: &DecodedTile, id: TileId) {
    let locator = GroundLocator::new(ground_corners(tile, ""), tile.tile_size());
    // Blank walls (with the floors and gables) and walls with windows.
    let walls: Vec<_> = tile
        .primitives("building")
        .iter()
        .filter(|p| p.material == "building_walls" || p.material.starts_with("facade"))
        .collect();
    assert!(!walls.is_empty(), "a walls primitive");
    let mut by_building: BTreeMap<u32, Vec<[f32; 3]>> = BTreeMap::new();
    for walls in walls {
        for (p, &fid) in walls.positions.iter().zip(&walls.feature_ids) {
            by_building.entry(fid).or_default().push(*p);
        }
    }
    let mut checked = 0;
    for (fid, points) in &by_building {
        let bottom = points
            .iter()
            .map(|p| f64::from(p[1]))
            .fold(f64::MAX, f64::min);
        let mut touched = false;
        for p in points {
            for h in locator.heights_at(f64::from(p[0]), f64::from(p[2]), 1e-6) {
                touched = true;
                assert!(
                    bottom <= h + 1e-3,
                    "{id}: building {fid} wall bottom {bottom} above ground {h} at {p:?}"
                );
            }
        }
        checked += usize::from(touched);
    }
    assert!(
        checked * 10 >= by_building.len() * 9,
        "{id}: only {checked} of {} buildings touch the ground mesh",
        by_building.len()
    );
}

fn check_ground_faces_up(tile: &DecodedTile) {
    for node in GROUND_NODES {
        for primitive in tile.primitives(node) {
            for [a, b, c] in primitive.triangles() {
                let [a, b, c] = [a, b, c].map(|i| primitive.positions[i].map(f64::from));
                let normal = triangle_normal([a, b, c]);
                let length = dot(normal, normal).sqrt();
                // Where the ground steps between two points a hair apart, a triangle stands
                // upright and may lean either way at f32.
                assert!(
                    normal[1] >= 0.0 || -normal[1] <= 0.05 * length,
                    "{node} triangle faces down: {a:?} {b:?} {c:?} ({normal:?})"
                );
            }
            assert!(
                primitive.normals.iter().all(|n| n[1] > 0.0),
                "{node} normal points down"
            );
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_tile_is_identical_twice_and_after_a_restart_comes_from_sqlite() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache.sqlite");
    let server = TestServer::start(&cache).await;
    let path = "/tiles/14/8530/5974.glb";
    let first = fetch(&server, path).await;
    assert_eq!(first.headers()["x-cache"], "miss");
    let etag = first.headers()["etag"].clone();
    let first = first.bytes().await.unwrap();
    let second = fetch(&server, path).await;
    assert_eq!(second.headers()["x-cache"], "hit");
    assert_eq!(second.headers()["x-cache-layer"], "memory");
    assert_eq!(second.bytes().await.unwrap(), first);
    // HEAD gives the headers without the body.
    let head = reqwest::Client::new()
        .head(server.url(path))
        .send()
        .await
        .unwrap();
    assert_eq!(head.status(), 200);
    assert_eq!(head.headers()["etag"], etag);
    server.stop().await;

    let server = TestServer::start(&cache).await;
    let third = fetch(&server, path).await;
    assert_eq!(third.headers()["x-cache"], "hit");
    assert_eq!(third.headers()["x-cache-layer"], "store");
    assert_eq!(third.bytes().await.unwrap(), first);
    assert_eq!(server.metric("terrastitch_renders_total").await, 0.0);

    // A second render of the same tile (another cache) gives the same bytes.
    let other = tempfile::tempdir().unwrap();
    let fresh = TestServer::start(&other.path().join("cache.sqlite")).await;
    let again = fetch(&fresh, path).await;
    assert_eq!(again.headers()["x-cache"], "miss");
    assert_eq!(again.bytes().await.unwrap(), first);
    fresh.stop().await;
    server.stop().await;
}

/// A client that holds a tile asks with its `ETag` and gets a `304` without a body; another
/// tag gets the tile; every answer says how long it may be kept.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_tile_the_client_holds_is_not_sent_again() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("cache.sqlite")).await;
    let client = reqwest::Client::new();
    for path in ["/tiles/14/8529/5973.glb", "/tiles/14/8529/5973.terrain"] {
        let first = client.get(server.url(path)).send().await.unwrap();
        assert_eq!(first.status(), 200);
        assert_eq!(first.headers()["cache-control"], "public, max-age=86400");
        let etag = first.headers()["etag"].clone();
        assert!(!first.bytes().await.unwrap().is_empty());
        for asked in [
            etag.to_str().unwrap().to_string(),
            format!("\"other\", {}", etag.to_str().unwrap()),
            format!("W/{}", etag.to_str().unwrap()),
            "*".to_string(),
        ] {
            let again = client
                .get(server.url(path))
                .header("if-none-match", &asked)
                .send()
                .await
                .unwrap();
            assert_eq!(again.status(), 304, "{path} {asked}");
            assert_eq!(again.headers()["etag"], etag);
            assert_eq!(again.headers()["cache-control"], "public, max-age=86400");
            assert!(again.bytes().await.unwrap().is_empty());
        }
        let changed = client
            .get(server.url(path))
            .header("if-none-match", "\"something-else\"")
            .send()
            .await
            .unwrap();
        assert_eq!(changed.status(), 200, "{path}");
        assert!(!changed.bytes().await.unwrap().is_empty());
    }
    server.stop().await;
}

/// `/tiles.json` describes the tileset: the attribution, the area of the OSM data, the zoom,
/// and absolute URL templates that lead to tiles, which a page on another origin may read.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_tilejson_describes_the_tileset_and_leads_to_tiles() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("cache.sqlite")).await;
    let response = reqwest::get(server.url("/tiles.json")).await.unwrap();
    assert_eq!(response.status(), 200);
    let tilejson: serde_json::Value = response.json().await.unwrap();
    assert_eq!(
        tilejson["attribution"],
        "© OpenStreetMap contributors, SRTM: NASA/USGS"
    );
    assert_eq!(
        (tilejson["minzoom"].as_u64(), tilejson["maxzoom"].as_u64()),
        (Some(14), Some(14))
    );
    let bounds: Vec<f64> = tilejson["bounds"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|v| v.as_f64())
        .collect();
    // Monaco's extract: around the principality, not the world.
    assert_eq!(bounds.len(), 4);
    assert!(bounds[0] < 7.42 && bounds[2] > 7.42 && bounds[1] < 43.73 && bounds[3] > 43.73);
    assert!(
        bounds[2] - bounds[0] < 1.0 && bounds[3] - bounds[1] < 1.0,
        "{bounds:?}"
    );
    for (key, extension) in [("tiles", "glb"), ("terrain", "terrain")] {
        let template = tilejson[key][0].as_str().unwrap();
        assert_eq!(
            template,
            server.url(&format!("/tiles/{{z}}/{{x}}/{{y}}.{extension}")),
            "{key}"
        );
        let url = template
            .replace("{z}", "14")
            .replace("{x}", "8529")
            .replace("{y}", "5973");
        let response = reqwest::get(&url).await.unwrap();
        assert_eq!(response.status(), 200, "{url}");
        assert!(!response.bytes().await.unwrap().is_empty());
    }
    // A page on another origin may read the tiles (CORS on by default, for GET and HEAD).
    let client = reqwest::Client::new();
    let response = client
        .get(server.url("/tiles/14/8529/5973.glb"))
        .header("origin", "http://viewer.example")
        .send()
        .await
        .unwrap();
    assert_eq!(response.headers()["access-control-allow-origin"], "*");
    assert!(response.headers()["access-control-expose-headers"]
        .to_str()
        .unwrap()
        .contains("etag"));
    assert!(!response.bytes().await.unwrap().is_empty());
    let preflight = client
        .request(reqwest::Method::OPTIONS, server.url("/tiles.json"))
        .header("origin", "http://viewer.example")
        .header("access-control-request-method", "GET")
        .send()
        .await
        .unwrap();
    assert!(preflight.status().is_success(), "{}", preflight.status());
    assert!(preflight.headers()["access-control-allow-methods"]
        .to_str()
        .unwrap()
        .contains("GET"));
    // Behind a proxy that ends TLS, the templates say https.
    let response = reqwest::Client::new()
        .get(server.url("/tiles.json"))
        .header("x-forwarded-proto", "https")
        .send()
        .await
        .unwrap();
    let tilejson: serde_json::Value = response.json().await.unwrap();
    assert!(tilejson["tiles"][0]
        .as_str()
        .unwrap()
        .starts_with("https://"));
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_requests_get_a_status_and_a_json_error() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("cache.sqlite")).await;
    let atlantic = TileId::containing(14, -30.0, 40.0).unwrap();
    let cases = [
        ("/tiles/14/abc/1.glb".to_string(), 400, "x"),
        ("/tiles/14/99999/1.glb".to_string(), 400, "outside"),
        ("/tiles/14/8529/5973.png".to_string(), 400, "format"),
        ("/tiles/3/1/1.glb".to_string(), 404, "zoom 14"),
        (
            format!("/tiles/14/{}/{}.glb", atlantic.x, atlantic.y),
            404,
            "no OSM extract",
        ),
        ("/nothing/here".to_string(), 404, "no route"),
    ];
    for (path, status, needle) in cases {
        let response = fetch(&server, &path).await;
        assert_eq!(response.status().as_u16(), status, "{path}");
        assert!(response.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("application/json"));
        let body: serde_json::Value = response.json().await.expect("a JSON body");
        let message = body["error"].as_str().expect("an error message");
        assert!(
            message.contains(needle),
            "{path}: '{message}' does not mention '{needle}'"
        );
    }
    let atlantic_body: serde_json::Value = fetch(
        &server,
        &format!("/tiles/14/{}/{}.glb", atlantic.x, atlantic.y),
    )
    .await
    .json()
    .await
    .unwrap();
    assert!(
        atlantic_body["error"]
            .as_str()
            .unwrap()
            .contains("N40W030.hgt"),
        "{atlantic_body}"
    );
    let health = fetch(&server, "/health").await;
    assert_eq!(health.status(), 200);
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn concurrent_requests_for_a_cold_tile_render_it_once() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("cache.sqlite")).await;
    let client = reqwest::Client::new();
    let url = server.url("/tiles/14/8528/5974.glb");
    let requests = (0..50).map(|_| {
        let (client, url) = (client.clone(), url.clone());
        tokio::spawn(async move {
            let response = client.get(url).send().await.unwrap();
            assert_eq!(response.status(), 200);
            response.bytes().await.unwrap()
        })
    });
    let bodies: Vec<_> = futures_join(requests).await;
    assert_eq!(bodies.len(), 50);
    assert!(bodies.iter().all(|b| b == &bodies[0]), "responses differ");
    assert!(bodies[0].len() > 1000);
    assert_eq!(server.metric("terrastitch_renders_total").await, 1.0);
    server.stop().await;
}

async fn futures_join<T: Send + 'static>(
    handles: impl Iterator<Item = tokio::task::JoinHandle<T>>,
) -> Vec<T> {
    let mut out = Vec::new();
    for handle in handles.collect::<Vec<_>>() {
        out.push(handle.await.expect("request task"));
    }
    out
}

#[test]
#[should_panic(expected = "the validator reported on other files than asked")]
fn a_validator_that_stopped_before_its_reports_passes_nothing() {
    common::check_validator_run(Some(1), &[std::path::Path::new("a.glb")], &[]);
}

#[test]
#[should_panic(expected = "the validator exited with Some(1)")]
fn a_validator_that_crashed_after_its_reports_passes_nothing() {
    let clean = common::Validation {
        file: "a.glb".to_string(),
        errors: 0,
        warnings: 0,
        messages: Vec::new(),
        draw_calls: None,
    };
    common::check_validator_run(Some(1), &[std::path::Path::new("a.glb")], &[clean]);
}
