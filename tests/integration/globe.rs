//! The 3D Tiles tileset in CesiumJS, in a real browser: the globe page (`static/globe.html`)
//! loads `/tileset.json` in headless Chromium (software WebGL), driven by playwright-core
//! (`tests/js/globe_check.mjs`), one session through several views. Tiles must load without
//! errors and draw; from 15 km the parents alone cover the data, from 2 km the zoom-14 tiles,
//! both on the server's own terrain; then, looking
//! straight down from 400 m on a building's centre (worked out here from the flat glb), the
//! feature CesiumJS picks at the centre of the view must be that building: the content sits on
//! the globe where its longitude and latitude say, and its metadata is readable. The same
//! tileset also loads in NASA-AMMOS 3DTilesRendererJS (`tests/js/tiles3d_check.mjs`), where a
//! ray straight down on the building's centre must hit a building. Screenshots and the reports
//! go to `tests/artifacts/globe/`.

use crate::common;

use common::{browser_check, decode, repo, TestServer};
use terrastitch::TileId;

/// Hôtel de Paris, in Monte-Carlo.
const KNOWN_BUILDING: i64 = 157_719_657;

/// The building's centre (longitude, latitude) from its walls and roofs in the flat tile that
/// draws it (one of the tiles around it; the others may list it in their table without drawing
/// it, as the foundations over a tunnel).
async fn building_centre(server: &TestServer) -> (f64, f64) {
    for (x, y) in [(8530, 5973), (8529, 5974), (8529, 5973)] {
        if let Some(centre) = centre_in(server, TileId::new(14, x, y).unwrap()).await {
            return centre;
        }
    }
    panic!("no tile around it draws the building");
}

/// A checker script's report, run with the server's URL, the artefacts folder, the
/// building's centre (latitude, longitude) and `views`; kept as
/// `tests/artifacts/globe/{report}`.
async fn check(
    script: &str,
    report: &str,
    server: &TestServer,
    views: Vec<String>,
) -> (serde_json::Value, String) {
    let (lon, lat) = building_centre(server).await;
    let artifacts = repo().join("tests/artifacts/globe");
    let mut args = vec![
        server.url("/"),
        artifacts.display().to_string(),
        lat.to_string(),
        lon.to_string(),
    ];
    args.extend(views);
    let value = browser_check(script, "globe", args).await;
    let text = serde_json::to_string_pretty(&value).unwrap();
    std::fs::write(artifacts.join(report), &text).unwrap();
    (value, text)
}

async fn centre_in(server: &TestServer, tile: TileId) -> Option<(f64, f64)> {
    let url = server.url(&format!("/tiles/{}/{}/{}.glb", tile.z, tile.x, tile.y));
    let bytes = reqwest::get(&url).await.unwrap().bytes().await.unwrap();
    let decoded = decode(&bytes);
    let feature = decoded
        .features
        .iter()
        .position(|f| f.osm_id == KNOWN_BUILDING)? as u32;
    let (mut x, mut z, mut n) = (0.0, 0.0, 0.0);
    for primitive in decoded.primitives("building") {
        for (p, &id) in primitive.positions.iter().zip(&primitive.feature_ids) {
            if id == feature {
                x += f64::from(p[0]);
                z += f64::from(p[2]);
                n += 1.0;
            }
        }
    }
    (n > 0.0).then(|| tile.frame().to_lon_lat(x / n, z / n))
}

/// One session of the globe page: its start view, the data from far and near, and a pick.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cesium_shows_the_data_from_far_and_near_on_its_own_terrain_and_picks_a_building_where_it_stands(
) {
    assert!(
        repo().join("static/vendor/cesium/Cesium.js").exists(),
        "CesiumJS is not in static/vendor: run `make test` (it copies it from viewer/)"
    );
    let (server, _turn) = common::browser_server().await;
    let views = far_and_near(&server).await;
    let (report, text) = check("globe_check.mjs", "report.json", &server, views).await;
    assert!(report["error"].is_null(), "{text}");
    assert_eq!(report["consoleErrors"], serde_json::json!([]), "{text}");
    assert_eq!(report["pageErrors"], serde_json::json!([]), "{text}");
    assert_eq!(report["failedRequests"], serde_json::json!([]), "{text}");
    assert_eq!(report["end"]["failed"], serde_json::json!([]), "{text}");
    starts_drawn(&report, &text);
    far_and_near_drawn(&report, &text);
    // Straight down on the building's centre, CesiumJS picks the building.
    assert_eq!(
        report["picked"]["osmId"],
        serde_json::json!(KNOWN_BUILDING.to_string()),
        "{text}"
    );
    assert_eq!(report["picked"]["osmType"], "way", "{text}");
    assert_eq!(report["panel"]["visible"], true, "{text}");
    server.stop().await;
}

/// The start view: the tileset files and compressed content tiles came, and something was
/// drawn over the ground in view.
fn starts_drawn(report: &serde_json::Value, text: &str) {
    assert!(
        report["requests"]["tilesets"].as_u64().unwrap() >= 2,
        "{text}"
    );
    let content = report["requests"]["content"].as_array().unwrap();
    assert!(content.len() >= 4, "{text}");
    assert!(
        content
            .iter()
            .all(|u| u.as_str().unwrap().ends_with(".glb?compress=meshopt")),
        "{text}"
    );
    assert!(
        report["pixels"]["distinctColours"].as_u64().unwrap() > 50,
        "{text}"
    );
    // The tiles cover the ground in view: most of the lower half changes without them.
    assert!(
        report["pixels"]["contentFraction"].as_f64().unwrap() > 0.5,
        "{text}"
    );
    println!(
        "globe: first settled view {} ms, {} content tiles",
        report["steps"]["firstAllLoadedMs"],
        content.len()
    );
}

/// The data's box from 15 km, straight down on the middle of its northern half (the lower half
/// of the view then lies on the data, a strip 7 km deep); and from 2 km, at 45° on Monaco.
async fn far_and_near(server: &TestServer) -> Vec<String> {
    let description: serde_json::Value = reqwest::get(server.url("/tiles.json"))
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let b: Vec<f64> = description["bounds"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let (lon, lat) = building_centre(server).await;
    let far = format!(
        "{},{},15000,-90",
        (b[1] + b[3]) / 2.0 + (b[3] - b[1]) / 4.0,
        (b[0] + b[2]) / 2.0
    );
    vec![far, format!("{lat},{lon},2000,-45")]
}

/// From far, content over the data drawn from the parents alone; near, from zoom-14 tiles;
/// both on the server's terrain.
fn far_and_near_drawn(report: &serde_json::Value, text: &str) {
    let views = report["views"].as_array().unwrap();
    assert_eq!(views.len(), 2, "{text}");
    for view in views {
        let height = view["height"].as_u64().unwrap();
        assert_eq!(view["terrain"], "server", "{text}");
        // Content over at least half of the lower half of the view.
        let covered = view["pixels"]["contentFraction"].as_f64().unwrap();
        assert!(covered >= 0.5, "{height} m: {covered}\n{text}");
        let zooms: Vec<u64> = view["drawnZooms"]
            .as_object()
            .unwrap()
            .keys()
            .map(|z| z.parse().unwrap())
            .collect();
        match height {
            15000 => assert!(
                !zooms.is_empty() && zooms.iter().all(|&z| z < 14),
                "{zooms:?}\n{text}"
            ),
            _ => assert!(zooms.contains(&14), "{zooms:?}\n{text}"),
        }
        println!(
            "globe from {height} m: settled in {} ms, content over {:.0} % of the lower half, zooms {zooms:?}",
            view["settledMs"],
            covered * 100.0
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn three_d_tiles_renderer_js_loads_the_tileset_and_finds_the_building_in_place() {
    assert!(
        repo()
            .join("tests/js/node_modules/3d-tiles-renderer")
            .exists(),
        "3d-tiles-renderer is not installed: run `make test` (it runs npm ci in tests/js)"
    );
    let (server, _turn) = common::browser_server().await;
    let (report, text) = check("tiles3d_check.mjs", "tiles3d-report.json", &server, vec![]).await;
    assert!(report["error"].is_null(), "{text}");
    assert_eq!(report["consoleErrors"], serde_json::json!([]), "{text}");
    assert_eq!(report["pageErrors"], serde_json::json!([]), "{text}");
    assert_eq!(report["state"]["errors"], serde_json::json!([]), "{text}");
    assert_eq!(report["failedResponses"], serde_json::json!([]), "{text}");
    assert_eq!(report["failedRequests"], serde_json::json!([]), "{text}");
    let loaded = report["state"]["loaded"].as_array().unwrap();
    assert!(
        loaded
            .iter()
            .filter(|u| u.as_str().unwrap().contains(".glb?compress=meshopt"))
            .count()
            >= 4,
        "{text}"
    );
    // Straight down on the building's centre: a building, standing on Monte-Carlo's ground.
    let names = report["probe"]["names"].as_array().expect("a hit");
    assert!(names.iter().any(|n| n == "building"), "{text}");
    let height = report["probe"]["height"].as_f64().unwrap();
    assert!((20.0..150.0).contains(&height), "{text}");
    println!(
        "3DTilesRendererJS: settled in {} ms, {} content tiles; the ray hit at {height:.1} m",
        report["settledMs"],
        loaded.len()
    );
    server.stop().await;
}
