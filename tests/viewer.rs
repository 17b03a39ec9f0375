//! The viewer at `/`, in a real browser: headless Chromium (software WebGL) driven by
//! playwright-core (`tests/js/viewer_check.mjs`). It must show the nine tiles around the start
//! without console errors, draw something, show a clicked building's OSM id, and load new tiles
//! when the camera moves. Screenshots and the report go to `tests/artifacts/viewer/`.

mod common;

use common::{browser_check, repo, TestServer};

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
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("cache.sqlite")).await;
    let artifacts = repo().join("tests/artifacts/viewer");
    let report = browser_check(
        "viewer_check.mjs",
        "viewer",
        vec![
            server.url("/"),
            artifacts.display().to_string(),
            KNOWN_BUILDING.to_string(),
        ],
    )
    .await;
    let text = serde_json::to_string_pretty(&report).unwrap();
    assert!(report["error"].is_null(), "{text}");
    assert_eq!(report["consoleErrors"], serde_json::json!([]), "{text}");
    assert_eq!(report["pageErrors"], serde_json::json!([]), "{text}");

    // The nine tiles around the start, loaded, none failed.
    let loaded = report["start"]["loaded"].as_array().unwrap();
    assert!(loaded.len() >= 9, "{text}");
    for x in 8528..=8530 {
        for y in 5972..=5974 {
            let key = serde_json::json!(format!("{x}/{y}"));
            assert!(loaded.contains(&key), "{x}/{y} not loaded: {text}");
        }
    }
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
    // The click on the known building shows it.
    assert_eq!(report["click"]["panelVisible"], true, "{text}");
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
    assert!(
        report["moved"]["hash"]
            .as_str()
            .unwrap()
            .starts_with("#43.7"),
        "{text}"
    );
    println!(
        "first full view {} ms, {:.2} frames/s while turning ({})",
        report["steps"]["firstFullViewMs"],
        report["steps"]["framesPerSecond"],
        report["glRenderer"]
    );
    server.stop().await;
}
