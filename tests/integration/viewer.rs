//! The viewer at `/`, in a real browser: headless Chromium (software WebGL) driven by
//! playwright-core (`tests/js/viewer_check.mjs`). It must show the nine tiles around the start
//! without console errors, draw something, show a clicked building's OSM id, and load new tiles
//! when the camera moves. Screenshots and the report go to `tests/artifacts/viewer/`.

use crate::common;

use common::{browser_check, repo, write_extract, TestServer};
use terrastitch::config::Config;
use terrastitch::provider::Inputs;

/// Hôtel de Paris, next to the start view in Monte-Carlo.
const KNOWN_BUILDING: &str = "157719657";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_viewer_streams_tiles_and_shows_what_is_clicked() {
    assert!(
        repo()
            .join("static/vendor/three/build/three.module.js")
            .exists(),
        "three.js is not in static/vendor: run `make test` (it copies it from viewer/)"
    );
    let (server, _turn) = common::browser_server().await;
    let artifacts = repo().join("tests/artifacts/viewer");
    let report = browser_check(
        "viewer_check.mjs",
        "viewer",
        vec![
            // The start view this check knows its building from.
            server.url("/#43.7396,7.4255,1800,20,50"),
            artifacts.display().to_string(),
            KNOWN_BUILDING.to_string(),
        ],
    )
    .await;
    let text = serde_json::to_string_pretty(&report).unwrap();
    assert!(report["error"].is_null(), "{text}");
    assert_eq!(report["consoleErrors"], serde_json::json!([]), "{text}");
    assert_eq!(report["pageErrors"], serde_json::json!([]), "{text}");
    assert_eq!(report["failedRequests"], serde_json::json!([]), "{text}");

    // The nine tiles around the start, loaded, none failed.
    let loaded = report["start"]["loaded"].as_array().unwrap();
    assert!(loaded.len() >= 9, "{text}");
    for x in 8528..=8530 {
        for y in 5972..=5974 {
            let key = serde_json::json!(format!("14/{x}/{y}"));
            assert!(loaded.contains(&key), "{x}/{y} not loaded: {text}");
        }
    }
    // They are the first nine asked for, before any tile nearer the point looked at but
    // outside them.
    let mut asked: Vec<String> = report["start"]["requested"]
        .as_array()
        .unwrap()
        .iter()
        .take(9)
        .filter_map(|t| t.as_str().map(String::from))
        .collect();
    let mut expected: Vec<String> = (8528..=8530)
        .flat_map(|x| (5972..=5974).map(move |y| format!("14/{x}/{y}")))
        .collect();
    expected.sort();
    asked.sort();
    assert_eq!(asked, expected, "{text}");
    assert_eq!(report["end"]["failed"], serde_json::json!([]), "{text}");
    // Something is drawn: many colours, not a black canvas.
    assert!(
        report["pixels"]["distinctColours"].as_u64().unwrap() > 50,
        "{text}"
    );
    assert!(
        report["pixels"]["darkFraction"].as_f64().unwrap() < 0.5,
        "{text}"
    );
    // Shadows start off on software WebGL and, turned on, darken the view.
    assert_eq!(report["shadows"]["defaultOn"], false, "{text}");
    let without = report["shadows"]["brightnessWithout"].as_f64().unwrap();
    let with = report["shadows"]["brightnessWith"].as_f64().unwrap();
    assert!(with < without - 0.005, "{text}");
    // The mapped / inferred toggle paints the buildings whose shape was inferred, and gives
    // them back their colours.
    let orange = |key: &str| report["inferred"][key].as_f64().unwrap();
    assert!(orange("on") > orange("before") + 0.02, "{text}");
    assert!((orange("off") - orange("before")).abs() < 0.005, "{text}");
    // The click on the known building shows it, with what was inferred of it.
    assert_eq!(report["click"]["panelVisible"], true, "{text}");
    assert!(
        report["click"]["text"]
            .as_str()
            .unwrap_or_default()
            .contains("(inferred)"),
        "{text}"
    );
    assert_eq!(
        report["click"]["osmIds"],
        serde_json::json!([KNOWN_BUILDING]),
        "{text}"
    );
    // Moving the camera loads tiles not asked for before, and the view is in the URL.
    assert!(
        report["moved"]["newlyLoaded"].as_array().unwrap().len() >= 3,
        "{text}"
    );
    // The URL holds the moved view: 0.03° east of the start's 7.4255.
    let hash = report["moved"]["hash"].as_str().unwrap();
    let lon: f64 = hash.split(',').nth(1).unwrap().parse().unwrap();
    assert!(hash.starts_with("#43.7"), "{text}");
    assert!((lon - 7.4555).abs() < 1e-3, "{hash}");
    // Drawn back to 40 km, the view is made of the far-view tiles, with nothing failed.
    let shown: Vec<u8> = report["far"]["shownZooms"]
        .as_object()
        .unwrap()
        .keys()
        .map(|z| z.parse().unwrap())
        .collect();
    assert!(shown.iter().any(|&z| z <= 12), "{text}");
    assert!(!shown.contains(&14), "{text}");
    assert!(
        report["far"]["pixels"]["distinctColours"].as_u64().unwrap() > 50,
        "{text}"
    );
    println!(
        "first full view {} ms, {:.2} frames/s while turning ({}); from 40 km, zooms {:?} settled in {} ms",
        report["steps"]["firstFullViewMs"],
        report["steps"]["framesPerSecond"],
        report["glRenderer"],
        report["far"]["shownZooms"],
        report["far"]["settledMs"]
    );
    server.stop().await;
}

/// A server of another region (a few ways near Ulm, on the test SRTM files): the viewer and the
/// globe, their URLs naming no place, open on its data and ask for nothing it lacks.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn both_viewers_open_on_the_data_of_a_server_of_another_region() {
    let dir = tempfile::tempdir().unwrap();
    let extract = dir.path().join("ulm.osm.pbf");
    // Inside tile 14/8647/5668 (9.998–10.020 E, 48.385–48.400 N).
    write_extract(
        &serde_json::json!([
            {"tags": {"highway": "residential", "name": "Teststraße"},
             "nodes": [[10.001, 48.389], [10.009, 48.392], [10.016, 48.396]]},
            {"tags": {"building": "yes", "building:levels": "3"},
             "nodes": [[10.006, 48.393], [10.0066, 48.393], [10.0066, 48.3934],
                       [10.006, 48.3934], [10.006, 48.393]]},
        ]),
        &extract,
    );
    let zoom = Config::default().server.zoom;
    let sources = Inputs::open(&[extract], &repo().join("tests/data"), zoom).unwrap();
    let server_config = terrastitch::config::ServerConfig {
        render_threads: 2,
        ..Config::default().server
    };
    let _turn = common::browser_turn().await;
    let server =
        TestServer::start_with(&dir.path().join("cache.sqlite"), sources, &server_config).await;
    let report = browser_check(
        "open_check.mjs",
        "open",
        vec![
            server.url("/"),
            repo().join("tests/artifacts/open").display().to_string(),
        ],
    )
    .await;
    let text = serde_json::to_string_pretty(&report).unwrap();
    assert!(report["error"].is_null(), "{text}");
    assert_eq!(report["pageErrors"], serde_json::json!([]), "{text}");
    assert_eq!(report["consoleErrors"], serde_json::json!([]), "{text}");
    assert_eq!(report["failedRequests"], serde_json::json!([]), "{text}");
    let refused: Vec<&serde_json::Value> = report["answers"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|answer| answer[0].as_u64().unwrap() >= 400)
        .collect();
    assert!(refused.is_empty(), "answered with an error: {refused:?}");
    // The viewer loaded the data's tile, and keeps the place in its URL.
    let loaded = report["viewer"]["loaded"].as_array().unwrap();
    assert!(
        loaded.contains(&serde_json::json!("14/8647/5668")),
        "{text}"
    );
    assert_eq!(report["viewer"]["failed"], serde_json::json!([]), "{text}");
    assert!(
        report["viewer"]["hash"]
            .as_str()
            .unwrap()
            .starts_with("#48.3"),
        "{text}"
    );
    // The globe looks at the data and loaded content there.
    let looks_at = &report["globe"]["looksAt"];
    let (lon, lat) = (looks_at[0].as_f64().unwrap(), looks_at[1].as_f64().unwrap());
    assert!(
        (lon - 10.0085).abs() < 0.05 && (lat - 48.3925).abs() < 0.05,
        "{text}"
    );
    let content = report["globe"]["loaded"].as_array().unwrap();
    assert!(
        content
            .iter()
            .any(|u| u.as_str().unwrap().contains("14/8647/5668.glb")),
        "{text}"
    );
    assert_eq!(report["globe"]["failed"], serde_json::json!([]), "{text}");
    server.stop().await;
}
