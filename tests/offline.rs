//! `terrastitch seed` and `export`, run as the operator runs them, and `serve`'s logs and
//! shutdown as a process: a seed split into shards, resumed after it was killed, and exported
//! to MBTiles and to a directory.

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::process::{http_get, request, spawn_server};
use common::{bbox, terrastitch};
use terrastitch::cache::{etag_of, SqliteStore, TileFilter, TileStore};
use terrastitch::tile::{LonLatBounds, TileRange};

fn run(args: &[&str], cache: &Path) -> (bool, String) {
    let output = terrastitch()
        .args(args)
        .arg("--cache")
        .arg(cache)
        .output()
        .unwrap();
    (
        output.status.success(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

/// The plan line's numbers: to make, already cached.
fn planned(stderr: &str) -> (usize, usize) {
    let line = stderr
        .lines()
        .find(|l| l.contains("to make"))
        .unwrap_or_else(|| panic!("no plan line in:\n{stderr}"));
    let number = |before: &str| -> usize {
        let head = &line[..line.find(before).unwrap()];
        head.split_whitespace().last().unwrap().parse().unwrap()
    };
    (number(" to make"), number(" already"))
}

/// Every stored tile is whole: its bytes have the digest stored with them and are a glb of the
/// length its header gives.
fn check_cache(cache: &Path) -> usize {
    let store = SqliteStore::open(cache, None).unwrap();
    store.check_integrity().unwrap();
    let entries = store.list(&TileFilter::All).unwrap();
    for entry in &entries {
        let tile = store.get(&entry.key).unwrap().unwrap();
        let data = &tile.bodies.identity;
        assert_eq!(tile.etag, etag_of(data), "{}", entry.key.tile);
        assert_eq!(&data[..4], b"glTF");
        let length = u32::from_le_bytes(data[8..12].try_into().unwrap()) as usize;
        assert_eq!(length, data.len(), "{}", entry.key.tile);
    }
    entries.len()
}

#[test]
fn shards_split_a_seed_and_a_second_run_makes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache.sqlite");
    let area = bbox(8527, 8528, 5974, 5975);
    let mut made = 0;
    for shard in ["1/2", "2/2"] {
        let (ok, stderr) = run(
            &[
                "seed",
                "--bbox",
                &area,
                "--format",
                "glb",
                "--shard",
                shard,
                "--threads",
                "2",
            ],
            &cache,
        );
        assert!(ok, "{stderr}");
        assert!(stderr.contains("4 tiles in the box"), "{stderr}");
        let (to_make, already) = planned(&stderr);
        assert_eq!((to_make, already), (2, 0), "{stderr}");
        assert!(stderr.contains("tiles/s"), "{stderr}");
        made += to_make;
    }
    assert_eq!(made, 4);
    assert_eq!(check_cache(&cache), 4, "the shards did not overlap");
    let (ok, stderr) = run(&["seed", "--bbox", &area, "--format", "glb"], &cache);
    assert!(ok, "{stderr}");
    assert_eq!(planned(&stderr), (0, 4));
    // A box outside the data is refused by the parser, not by the renderer.
    let (ok, stderr) = run(&["seed", "--bbox", "7.44,43.72,7.40,43.75"], &cache);
    assert!(!ok);
    assert!(stderr.contains("empty"), "{stderr}");
}

/// The summary's counts of elevation LP components: solved, and found solved.
fn components(stderr: &str) -> (u64, u64) {
    let line = stderr
        .lines()
        .find(|l| l.contains("components solved"))
        .unwrap_or_else(|| panic!("no summary in:\n{stderr}"));
    let tail = &line[line.find("elevation LP: ").unwrap() + "elevation LP: ".len()..];
    let numbers: Vec<u64> = tail
        .split(|c: char| !c.is_ascii_digit())
        .filter(|w| !w.is_empty())
        .map(|w| w.parse().unwrap())
        .collect();
    (numbers[0], numbers[1])
}

/// Each stored tile with its ETag, in tile order.
fn etags(store: &SqliteStore) -> Vec<(String, String)> {
    let mut tiles: Vec<(String, String)> = store
        .list(&TileFilter::All)
        .unwrap()
        .iter()
        .map(|e| {
            let tile = store.get(&e.key).unwrap().unwrap();
            (e.key.tile.to_string(), tile.etag)
        })
        .collect();
    tiles.sort();
    tiles
}

#[test]
fn a_seed_finds_the_elevation_components_an_earlier_seed_solved_and_makes_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache.sqlite");
    let area = bbox(8528, 8529, 5974, 5974);
    let (ok, stderr) = run(&["seed", "--bbox", &area, "--format", "glb"], &cache);
    assert!(ok, "{stderr}");
    let (solved, found) = components(&stderr);
    assert!(solved > 0, "{stderr}");
    let store = SqliteStore::open(&cache, None).unwrap();
    let first = etags(&store);
    assert_eq!(first.len(), 2);
    assert!(!store.solutions(usize::MAX).unwrap().is_empty());
    store.remove(&TileFilter::All).unwrap();
    drop(store);

    // A new process makes the tiles again from the components the first one kept.
    let (ok, stderr) = run(&["seed", "--bbox", &area, "--format", "glb"], &cache);
    assert!(ok, "{stderr}");
    // Every component the first run met, solved there or found from its other tile.
    assert_eq!(components(&stderr), (0, solved + found), "{stderr}");
    let store = SqliteStore::open(&cache, None).unwrap();
    assert_eq!(etags(&store), first);
}

#[test]
fn a_seed_killed_midway_leaves_a_sound_cache_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache.sqlite");
    let area = bbox(8528, 8530, 5973, 5974);
    let mut child = terrastitch()
        .args(["seed", "--bbox", &area, "--format", "glb", "--threads", "1"])
        .arg("--cache")
        .arg(&cache)
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Kill it once it has stored a tile or two.
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        let stored = rusqlite::Connection::open_with_flags(
            &cache,
            rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY,
        )
        .and_then(|c| c.query_row("SELECT count(*) FROM tiles", [], |r| r.get::<_, i64>(0)))
        .unwrap_or(0);
        if stored >= 1 {
            break;
        }
        assert!(Instant::now() < deadline, "the seed stored nothing");
        assert!(
            child.try_wait().unwrap().is_none(),
            "the seed ended before it was killed"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let before = check_cache(&cache);
    assert!((1..6).contains(&before), "{before}");

    let (ok, stderr) = run(&["seed", "--bbox", &area, "--format", "glb"], &cache);
    assert!(ok, "{stderr}");
    let (to_make, already) = planned(&stderr);
    assert_eq!(already, before, "{stderr}");
    assert_eq!(to_make + already, 6, "{stderr}");
    assert_eq!(check_cache(&cache), 6);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_seed_without_formats_makes_what_the_viewer_and_the_globe_ask_for() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache.sqlite");
    let area = bbox(8528, 8528, 5974, 5974);
    let (ok, stderr) = run(&["seed", "--bbox", &area], &cache);
    assert!(ok, "{stderr}");
    let store = SqliteStore::open(&cache, None).unwrap();
    let mut formats: Vec<&str> = store
        .list(&TileFilter::All)
        .unwrap()
        .iter()
        .map(|e| e.key.format.as_str())
        .collect();
    formats.sort();
    assert_eq!(formats, ["glb-enu-meshopt", "glb-meshopt"]);
    drop(store);
    // The viewer's and the globe's first requests are hits.
    let server = common::TestServer::start(&cache).await;
    for path in [
        "/tiles/14/8528/5974.glb?compress=meshopt",
        "/3dtiles/14/8528/5974.glb?compress=meshopt",
    ] {
        let response = server.get(path, &[]).await;
        assert_eq!(response.status(), 200, "{path}");
        assert_eq!(response.headers()["x-cache"], "hit", "{path}");
    }
    server.stop().await;
}

#[test]
fn export_writes_mbtiles_and_a_directory_of_the_tiles() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache.sqlite");
    let area = bbox(8527, 8528, 5974, 5974);
    let file = dir.path().join("monaco.mbtiles");
    let (ok, stderr) = run(
        &["export", "--bbox", &area, "-o", file.to_str().unwrap()],
        &cache,
    );
    assert!(ok, "{stderr}");
    assert!(stderr.contains("exported 2 tiles"), "{stderr}");

    let store = SqliteStore::open(&cache, None).unwrap();
    let bounds: LonLatBounds = area.parse().unwrap();
    let range = TileRange::covering(14, &bounds);
    let mbtiles = rusqlite::Connection::open(&file).unwrap();
    let meta = |name: &str| -> String {
        mbtiles
            .query_row("SELECT value FROM metadata WHERE name = ?1", [name], |r| {
                r.get(0)
            })
            .unwrap()
    };
    assert_eq!(meta("format"), "glb");
    assert!(meta("attribution").contains("© OpenStreetMap contributors"));
    assert_eq!(meta("minzoom"), "14");
    assert_eq!(meta("bounds").split(',').count(), 4);
    let count: i64 = mbtiles
        .query_row("SELECT count(*) FROM tiles", [], |r| r.get(0))
        .unwrap();
    assert_eq!(count, 2);
    for tile in range.tiles() {
        let key = terrastitch::format::TileKey {
            tile,
            format: terrastitch::format::Format::GLB,
        };
        let stored = store.get(&key).unwrap().unwrap();
        // MBTiles rows count from the south.
        let row = (1i64 << 14) - 1 - i64::from(tile.y);
        let data: Vec<u8> = mbtiles
            .query_row(
                "SELECT tile_data FROM tiles WHERE zoom_level = 14 AND tile_column = ?1 AND tile_row = ?2",
                [i64::from(tile.x), row],
                |r| r.get(0),
            )
            .unwrap();
        assert_eq!(data, stored.bodies.identity.to_vec(), "{tile}");
    }

    let out = dir.path().join("tiles");
    let target = format!("{}/", out.display());
    let (ok, stderr) = run(&["export", "--bbox", &area, "-o", &target], &cache);
    assert!(ok, "{stderr}");
    // Everything was in the cache already.
    assert_eq!(planned(&stderr), (0, 2));
    for tile in range.tiles() {
        let path = out.join(format!("14/{}/{}.glb", tile.x, tile.y));
        let data = std::fs::read(&path).unwrap();
        assert_eq!(&data[..4], b"glTF", "{}", path.display());
    }
    assert!(!dir.path().join("monaco.mbtiles.partial").exists());

    // Another terrastitch serves the file as it is, without any source data.
    let (mut child, address, _lines) = spawn_server(&["--mbtiles", file.to_str().unwrap()], &[]);
    for tile in range.tiles() {
        let (status, body) = http_get(&address, &format!("/tiles/14/{}/{}.glb", tile.x, tile.y));
        assert_eq!(status, 200, "{tile}");
        let exported = std::fs::read(out.join(format!("14/{}/{}.glb", tile.x, tile.y))).unwrap();
        assert_eq!(body, exported, "{tile}");
    }
    let (status, body) = http_get(&address, "/tiles/14/8529/5973.glb");
    assert_eq!(status, 404);
    assert!(
        String::from_utf8_lossy(&body).contains("is not in"),
        "{}",
        String::from_utf8_lossy(&body)
    );
    assert_eq!(http_get(&address, "/ready").0, 200);
    let (status, body) = http_get(&address, "/tiles.json");
    assert_eq!(status, 200);
    let json: serde_json::Value = serde_json::from_slice(&body).unwrap();
    let west = json["bounds"][0].as_f64().unwrap();
    assert!((west - bounds.west).abs() < 1e-9, "{json}");
    // The archive holds plain flat glb: that is the compression offered (the viewer follows
    // it), and there is no 3D Tiles tileset to serve from it.
    assert_eq!(
        json["glb_compressions"],
        serde_json::json!(["none"]),
        "{json}"
    );
    let (status, body) = http_get(&address, "/tileset.json");
    assert_eq!(status, 404);
    assert!(
        String::from_utf8_lossy(&body).contains("glb-enu"),
        "{}",
        String::from_utf8_lossy(&body)
    );
    child.kill().unwrap();
    child.wait().unwrap();
}

#[test]
fn an_archive_of_east_north_up_tiles_is_served_as_a_3d_tileset() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache.sqlite");
    let area = bbox(8527, 8527, 5975, 5975);
    let file = dir.path().join("enu.mbtiles");
    let (ok, stderr) = run(
        &[
            "export",
            "--bbox",
            &area,
            "--format",
            "glb-enu-meshopt",
            "-o",
            file.to_str().unwrap(),
        ],
        &cache,
    );
    assert!(ok, "{stderr}");
    let (mut child, address, _lines) = spawn_server(&["--mbtiles", file.to_str().unwrap()], &[]);
    let get_json = |path: &str| {
        let (status, body) = http_get(&address, path);
        assert_eq!(status, 200, "{path}: {}", String::from_utf8_lossy(&body));
        serde_json::from_slice::<serde_json::Value>(&body).unwrap()
    };
    // The tileset names the archive's compression; its files lead to the tile, which comes.
    let root = get_json("/tileset.json");
    let child_uri = root["root"]["children"][0]["content"]["uri"]
        .as_str()
        .unwrap();
    assert!(child_uri.ends_with(".json?compress=meshopt"), "{root}");
    let subtree = get_json(&format!("/{child_uri}"));
    let leaf = subtree["root"]["children"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["content"]["uri"].as_str().unwrap().to_string())
        .find(|u| u.contains("14/8527/5975.glb"))
        .expect("the exported tile is listed");
    let (status, body) = http_get(
        &address,
        &format!("/3dtiles/{}", leaf.trim_start_matches("../../")),
    );
    assert_eq!(status, 200);
    assert_eq!(&body[0..4], b"glTF");
    child.kill().unwrap();
    child.wait().unwrap();
}

/// An exported directory of east-north-up tiles carries its `tileset.json`: served by a plain
/// static file server, 3DTilesRendererJS loads it and draws the tiles.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_directory_export_is_a_3d_tileset_on_a_static_host() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache.sqlite");
    let area = bbox(8528, 8529, 5973, 5974);
    let out = dir.path().join("site");
    let target = format!("{}/", out.display());
    let args = [
        "export",
        "--bbox",
        &area,
        "--format",
        "glb-enu-meshopt",
        "-o",
        &target,
    ];
    let (ok, stderr) = tokio::task::spawn_blocking({
        let cache = cache.clone();
        let args: Vec<String> = args.iter().map(|a| a.to_string()).collect();
        move || run(&args.iter().map(String::as_str).collect::<Vec<_>>(), &cache)
    })
    .await
    .unwrap();
    assert!(ok, "{stderr}");
    // The document names every exported file, and only those.
    let tileset: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("tileset.json")).unwrap()).unwrap();
    let mut uris = Vec::new();
    let mut stack = vec![&tileset["root"]];
    while let Some(tile) = stack.pop() {
        if let Some(uri) = tile["content"]["uri"].as_str() {
            assert!(out.join(uri).exists(), "{uri} is not in the folder");
            uris.push(uri.to_string());
        }
        stack.extend(tile["children"].as_array().into_iter().flatten());
    }
    uris.sort();
    assert_eq!(uris.len(), 4, "{uris:?}");
    assert!(
        uris.iter().all(|u| u.ends_with(".enu-meshopt.glb")),
        "{uris:?}"
    );

    // A static file server, nothing of terrastitch.
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let address = listener.local_addr().unwrap();
    let site = axum::Router::new().fallback_service(tower_http::services::ServeDir::new(&out));
    let served = tokio::spawn(async move { axum::serve(listener, site).await });
    let b: LonLatBounds = area.parse().unwrap();
    // The middle of the north-western tile (the box's centre is the corner of all four).
    let (lon, lat) = (
        b.west + (b.east - b.west) / 4.0,
        b.north - (b.north - b.south) / 4.0,
    );
    let artifacts = common::repo().join("tests/artifacts/export");
    let report = common::browser_check(
        "tiles3d_check.mjs",
        "export",
        vec![
            format!("http://{address}/"),
            artifacts.display().to_string(),
            lat.to_string(),
            lon.to_string(),
            "tileset.json".to_string(),
        ],
    )
    .await;
    served.abort();
    let text = serde_json::to_string_pretty(&report).unwrap();
    assert!(report["error"].is_null(), "{text}");
    assert_eq!(report["pageErrors"], serde_json::json!([]), "{text}");
    assert_eq!(report["failedResponses"], serde_json::json!([]), "{text}");
    assert_eq!(report["state"]["errors"], serde_json::json!([]), "{text}");
    let loaded = report["state"]["loaded"].as_array().unwrap();
    assert!(loaded.len() >= 4, "{text}");
    // Straight down at the centre the ray meets the drawn ground or what stands on it.
    assert!(report["probe"].is_object(), "{text}");
}

/// With JSON logs, every line is one JSON object, and a request's lines carry its id; SIGTERM
/// stops the server cleanly.
#[test]
fn json_logs_carry_the_request_id_and_sigterm_stops_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache.sqlite");
    let (mut child, address, lines_rx) = spawn_server(
        &["--cache", cache.to_str().unwrap()],
        &[("TERRASTITCH_LOG__FORMAT", "json"), ("RUST_LOG", "info")],
    );
    let (status, head, _) = request(&address, "/health", &[("X-Request-Id", "json-log-test-7")]);
    assert_eq!(status, 200);
    assert!(
        head.to_lowercase()
            .contains("x-request-id: json-log-test-7"),
        "{head}"
    );

    let status = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let exit = child.wait().unwrap();
    assert!(exit.success(), "{exit:?}");
    // The reader ends with the process's stderr.
    let lines: Vec<String> = lines_rx.iter().collect();
    let mut with_id = 0;
    for line in &lines {
        let json: serde_json::Value =
            serde_json::from_str(line).unwrap_or_else(|_| panic!("not JSON: {line}"));
        assert!(json["level"].is_string(), "{line}");
        if line.contains("json-log-test-7") {
            assert_eq!(json["span"]["id"], "json-log-test-7", "{line}");
            with_id += 1;
        }
    }
    assert!(
        with_id >= 1,
        "no line carries the request id:\n{}",
        lines.join("\n")
    );
    assert!(lines.iter().any(|l| l.contains("shutting down")));
}
