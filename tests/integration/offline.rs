//! `terrastitch seed` and `export`, run as the operator runs them, and `serve`'s logs and
//! shutdown as a process: a seed split into shards, resumed after it was killed, and exported
//! to MBTiles and to a directory.

use crate::common;

use std::path::Path;
use std::process::{Command, Stdio};

use common::process::{http_get, request, spawn_server};
use common::{bbox, terrastitch};
use terrastitch::cache::{etag_of, SqliteStore, TileFilter, TileReader, TileStore};
use terrastitch::tile::{LonLatBounds, TileId, TileRange};

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
        let stages = stage_seconds(&stderr).unwrap_or_else(|| panic!("no stages in:\n{stderr}"));
        assert_eq!(stages.len(), 9, "eight stages and compressing: {stages:?}");
        assert!(stages.iter().sum::<f64>() > 0.0, "{stages:?}");
        made += to_make;
    }
    assert_eq!(made, 4);
    assert_eq!(check_cache(&cache), 4, "the shards did not overlap");
    let (ok, stderr) = run(&["seed", "--bbox", &area, "--format", "glb"], &cache);
    assert!(ok, "{stderr}");
    assert_eq!(planned(&stderr), (0, 4));
    assert_eq!(
        stage_seconds(&stderr),
        None,
        "nothing made, no stages: {stderr}"
    );
    // A box outside the data is refused by the parser, not by the renderer.
    let (ok, stderr) = run(&["seed", "--bbox", "7.44,43.72,7.40,43.75"], &cache);
    assert!(!ok);
    assert!(stderr.contains("empty"), "{stderr}");
}

/// The seconds of each stage (and of compressing) the summary gives, summed over the tiles
/// made; `None` when it gives none.
fn stage_seconds(stderr: &str) -> Option<Vec<f64>> {
    let line = stderr
        .lines()
        .find(|l| l.starts_with("time in each stage"))?;
    let (_, figures) = line.split_once(": ")?;
    Some(
        figures
            .split([',', ';'])
            .map(|part| {
                let value = part.split_whitespace().last().unwrap_or_default();
                value.parse().unwrap_or_else(|_| panic!("{part} in {line}"))
            })
            .collect(),
    )
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
    common::wait_for("the seed to store a tile", || {
        let stored = rusqlite::Connection::open_with_flags(
            &cache,
            rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY,
        )
        .and_then(|c| c.query_row("SELECT count(*) FROM tiles", [], |r| r.get::<_, i64>(0)))
        .unwrap_or(0);
        assert!(
            child.try_wait().unwrap().is_none(),
            "the seed ended before it was killed"
        );
        (stored >= 1).then_some(())
    });
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

/// The tiles an export of `bounds` holds: at 14, and at the coarser zooms viewers ask for (the
/// far views' for glb, every zoom for terrain).
fn exported_tiles(bounds: &LonLatBounds, terrain: bool) -> Vec<TileId> {
    let zooms: Vec<u8> = match terrain {
        true => (0..=14).collect(),
        false => vec![8, 10, 12, 13, 14],
    };
    zooms
        .into_iter()
        .flat_map(|z| TileRange::covering(z, bounds).tiles().collect::<Vec<_>>())
        .collect()
}

#[test]
fn export_writes_mbtiles_and_a_directory_of_the_tiles() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache.sqlite");
    let area = bbox(8527, 8528, 5974, 5974);
    let bounds: LonLatBounds = area.parse().unwrap();
    let tiles = exported_tiles(&bounds, false);
    let file = dir.path().join("monaco.mbtiles");
    let (ok, stderr) = run(
        &["export", "--bbox", &area, "-o", file.to_str().unwrap()],
        &cache,
    );
    assert!(ok, "{stderr}");
    assert!(
        stderr.contains(&format!("exported {} tiles", tiles.len())),
        "{stderr}"
    );

    let store = SqliteStore::open(&cache, None).unwrap();
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
    assert_eq!(
        (meta("minzoom"), meta("maxzoom")),
        ("8".into(), "14".into())
    );
    assert_eq!(meta("bounds").split(',').count(), 4);
    let count: i64 = mbtiles
        .query_row("SELECT count(*) FROM tiles", [], |r| r.get(0))
        .unwrap();
    assert_eq!(count as usize, tiles.len());
    for &tile in &tiles {
        let key = terrastitch::format::TileKey {
            tile,
            format: terrastitch::format::Format::GLB,
        };
        let stored = store.get(&key).unwrap().unwrap();
        // MBTiles rows count from the south.
        let row = (1i64 << tile.z) - 1 - i64::from(tile.y);
        let data: Vec<u8> = mbtiles
            .query_row(
                "SELECT tile_data FROM tiles WHERE zoom_level = ?1 AND tile_column = ?2 AND tile_row = ?3",
                [i64::from(tile.z), i64::from(tile.x), row],
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
    assert_eq!(planned(&stderr), (0, tiles.len()));
    let file_of = |tile: TileId| out.join(format!("{}/{}/{}.glb", tile.z, tile.x, tile.y));
    for &tile in &tiles {
        let data = std::fs::read(file_of(tile)).unwrap();
        assert_eq!(&data[..4], b"glTF", "{tile}");
    }
    // Flat glb has no tileset to go with it.
    assert!(!out.join("tileset.json").exists());
    assert!(!dir.path().join("monaco.mbtiles.partial").exists());

    // Another terrastitch serves the file as it is, without any source data.
    let (mut child, address, _lines) = spawn_server(&["--archive", file.to_str().unwrap()], &[]);
    for &tile in &tiles {
        let path = format!("/tiles/{}/{}/{}.glb", tile.z, tile.x, tile.y);
        let (status, body) = http_get(&address, &path);
        assert_eq!(status, 200, "{tile}");
        assert_eq!(body, std::fs::read(file_of(tile)).unwrap(), "{tile}");
    }
    let (status, body) = http_get(&address, "/tiles/14/8529/5973.glb");
    assert_eq!(status, 404);
    assert!(
        String::from_utf8_lossy(&body).contains("is not in"),
        "{}",
        String::from_utf8_lossy(&body)
    );
    let (status, body) = http_get(&address, "/tiles/11/1066/746.glb");
    assert_eq!(status, 404);
    assert!(
        String::from_utf8_lossy(&body).contains("zooms 8, 10, 12, 13, 14"),
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
    // it), the far views it holds are offered, and there is no 3D Tiles tileset to serve from
    // it.
    assert_eq!(
        json["glb_compressions"],
        serde_json::json!(["none"]),
        "{json}"
    );
    assert_eq!(
        json["far_zooms"],
        serde_json::json!([13, 12, 10, 8]),
        "{json}"
    );
    let (status, body) = http_get(&address, "/tileset.json");
    assert_eq!(status, 404);
    assert!(
        String::from_utf8_lossy(&body).contains("glb-enu"),
        "{}",
        String::from_utf8_lossy(&body)
    );
    assert_eq!(http_get(&address, "/layer.json").0, 404);
    child.kill().unwrap();
    child.wait().unwrap();
}

/// What `scripts/pmtiles_dump.py` reads of a PMTiles file with the `pmtiles` package.
fn pmtiles_dump(file: &Path) -> serde_json::Value {
    let output = Command::new(common::python())
        .arg(common::repo().join("scripts/pmtiles_dump.py"))
        .arg(file)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).unwrap()
}

/// The tiles a dump lists, with their digests.
fn dumped_tiles(dump: &serde_json::Value) -> Vec<(TileId, String)> {
    let mut tiles: Vec<(TileId, String)> = dump["tiles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            let n = |k: &str| t[k].as_u64().unwrap();
            let tile = TileId::new(n("z") as u32, n("x"), n("y")).unwrap();
            (tile, t["sha256"].as_str().unwrap().to_string())
        })
        .collect();
    tiles.sort_by_key(|(t, _)| (t.z, t.x, t.y));
    tiles
}

/// The digests of the cache's tiles of `format` at `tiles`.
fn stored_tiles(
    store: &SqliteStore,
    tiles: &[TileId],
    format: terrastitch::format::Format,
) -> Vec<(TileId, String)> {
    use sha2::Digest;
    let mut digests: Vec<(TileId, String)> = tiles
        .iter()
        .map(|&tile| {
            let key = terrastitch::format::TileKey { tile, format };
            let stored = store.get(&key).unwrap().unwrap_or_else(|| panic!("{tile}"));
            let digest = sha2::Sha256::digest(&stored.bodies.identity);
            let hex: String = digest.iter().map(|b| format!("{b:02x}")).collect();
            (tile, hex)
        })
        .collect();
    digests.sort_by_key(|(t, _)| (t.z, t.x, t.y));
    digests
}

/// The status, the named headers and the body's digest of a response.
fn answer(address: &str, path: &str, headers: &[(&str, &str)]) -> (u16, Vec<String>, String) {
    use sha2::Digest;
    let (status, head, body) = request(address, path, headers);
    let digest: String = sha2::Sha256::digest(&body)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    let named = ["etag", "content-encoding", "content-type", "vary"]
        .iter()
        .map(|name| {
            head.lines()
                .find_map(|line| {
                    let (key, value) = line.split_once(':')?;
                    key.trim()
                        .eq_ignore_ascii_case(name)
                        .then(|| value.trim().to_string())
                })
                .unwrap_or_default()
        })
        .collect();
    (status, named, digest)
}

/// A PMTiles export holds the cache's bytes, as an independent reader finds them, with the
/// terrain at every zoom Cesium asks for; `serve --archive` answers with the same codings and
/// validators as the server that made the tiles, and its `layer.json` and `tileset.json`; a
/// directory export carries the same `layer.json` naming its files.
#[test]
fn a_pmtiles_export_holds_the_caches_bytes_and_is_served_as_the_cache_serves_them() {
    use terrastitch::format::{Format, Frame, Variant};
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache.sqlite");
    let area = bbox(8528, 8528, 5974, 5974);
    let bounds: LonLatBounds = area.parse().unwrap();
    let terrain = dir.path().join("terrain.pmtiles");
    let enu = dir.path().join("enu.pmtiles");
    for (format, file) in [("terrain", &terrain), ("glb-enu-meshopt", &enu)] {
        let args = ["export", "--bbox", &area, "--format", format, "-o"];
        let (ok, stderr) = run(&[&args[..], &[file.to_str().unwrap()]].concat(), &cache);
        assert!(ok, "{stderr}");
    }
    let store = SqliteStore::open(&cache, None).unwrap();
    let terrain_format = Format::Terrain(terrastitch::format::Extensions {
        normals: true,
        watermask: true,
    });
    let enu_format = Format::Glb(Variant {
        frame: Frame::EastNorthUp,
        meshopt: true,
    });
    for (file, format, is_terrain) in [(&terrain, terrain_format, true), (&enu, enu_format, false)]
    {
        let dump = pmtiles_dump(file);
        let expected = stored_tiles(&store, &exported_tiles(&bounds, is_terrain), format);
        assert_eq!(dumped_tiles(&dump), expected, "{}", file.display());
        assert_eq!(dump["header"]["tile_compression"], 1, "tiles as stored");
        assert_eq!(dump["header"]["clustered"], true);
        assert_eq!(dump["header"]["max_zoom"], 14);
        assert!(dump["metadata"]["attribution"]
            .as_str()
            .unwrap()
            .contains("OpenStreetMap"));
    }

    // The server that made the tiles, and one of the archive alone.
    let (mut live, live_address, _live_lines) =
        spawn_server(&["--cache", cache.to_str().unwrap()], &[]);
    let (mut archive, address, _lines) =
        spawn_server(&["--archive", terrain.to_str().unwrap()], &[]);
    common::wait_for("the sources to load", || {
        (http_get(&live_address, "/ready").0 == 200).then_some(())
    });
    let accept = "application/vnd.quantized-mesh;extensions=octvertexnormals-watermask";
    for path in ["/tiles/14/8528/5974.terrain", "/tiles/3/4/2.terrain"] {
        for coding in ["gzip", "br", "identity"] {
            let headers = [("Accept", accept), ("Accept-Encoding", coding)];
            let from_archive = answer(&address, path, &headers);
            assert_eq!(from_archive.0, 200, "{path} {coding}");
            assert_eq!(
                from_archive,
                answer(&live_address, path, &headers),
                "{path} {coding}"
            );
            let etag = from_archive.1[0].clone();
            assert!(!etag.is_empty(), "{path}");
            let again = [
                ("If-None-Match", etag.as_str()),
                ("Accept", accept),
                ("Accept-Encoding", coding),
            ];
            assert_eq!(request(&address, path, &again).0, 304, "{path}");
        }
    }
    let (status, layer) = http_get(&address, "/layer.json");
    assert_eq!(status, 200);
    let layer: serde_json::Value = serde_json::from_slice(&layer).unwrap();
    assert_eq!(layer["maxzoom"], 14, "{layer}");
    assert_eq!(layer["tiles"][0], "tiles/{z}/{x}/{y}.terrain");
    assert_eq!(layer["available"].as_array().unwrap().len(), 15, "{layer}");
    // A tile beside the box is not in the file, and not offered.
    assert_eq!(http_get(&address, "/tiles/14/8529/5974.terrain").0, 404);
    assert_eq!(layer["available"][14][0]["endX"], 8528, "{layer}");
    archive.kill().unwrap();
    archive.wait().unwrap();
    live.kill().unwrap();
    live.wait().unwrap();

    // The east-north-up archive is a 3D Tiles tileset with content in its parents.
    let (mut archive, address, _lines) = spawn_server(&["--archive", enu.to_str().unwrap()], &[]);
    let (status, root) = http_get(&address, "/tileset.json");
    assert_eq!(status, 200);
    let root: serde_json::Value = serde_json::from_slice(&root).unwrap();
    let file = root["root"]["children"][0]["content"]["uri"]
        .as_str()
        .unwrap();
    let (status, subtree) = http_get(&address, &format!("/{file}"));
    assert_eq!(status, 200, "{file}");
    let subtree: serde_json::Value = serde_json::from_slice(&subtree).unwrap();
    let parent = subtree["root"]["content"]["uri"].as_str().unwrap();
    let (status, body) = http_get(
        &address,
        &format!("/3dtiles/{}", parent.trim_start_matches("../../")),
    );
    assert_eq!(status, 200, "{parent}");
    assert_eq!(&body[..4], b"glTF");
    archive.kill().unwrap();
    archive.wait().unwrap();

    // A directory of the same: layer.json names files that are there.
    let out = dir.path().join("site");
    let target = format!("{}/", out.display());
    let args = [
        "export",
        "--bbox",
        &area,
        "--format",
        "terrain,glb-enu-meshopt",
        "-o",
        &target,
    ];
    let (ok, stderr) = run(&args, &cache);
    assert!(ok, "{stderr}");
    let written: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("layer.json")).unwrap()).unwrap();
    assert_eq!(written["available"], layer["available"]);
    let template = written["tiles"][0].as_str().unwrap();
    for (z, spans) in written["available"].as_array().unwrap().iter().enumerate() {
        for span in spans.as_array().unwrap() {
            let n = |k: &str| span[k].as_u64().unwrap();
            for x in n("startX")..=n("endX") {
                for y in n("startY")..=n("endY") {
                    let name = template
                        .replace("{z}", &z.to_string())
                        .replace("{x}", &x.to_string())
                        .replace("{y}", &y.to_string());
                    assert!(out.join(&name).exists(), "{name}");
                }
            }
        }
    }
    assert!(out.join("tileset.json").exists());
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
    let (mut child, address, _lines) = spawn_server(&["--archive", file.to_str().unwrap()], &[]);
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
    let leaf = content_uris(&subtree["root"])
        .into_iter()
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

/// The content URIs of a tileset's tile and of every tile under it.
fn content_uris(tile: &serde_json::Value) -> Vec<String> {
    let mut uris = Vec::new();
    let mut stack = vec![tile];
    while let Some(tile) = stack.pop() {
        if let Some(uri) = tile["content"]["uri"].as_str() {
            uris.push(uri.to_string());
        }
        stack.extend(tile["children"].as_array().into_iter().flatten());
    }
    uris
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
    let mut uris = content_uris(&tileset["root"]);
    for uri in &uris {
        assert!(out.join(uri).exists(), "{uri} is not in the folder");
    }
    uris.sort();
    // The tiles of 14, and their parents of 13 and 12 with content of their own (the root
    // lists the tiles of 12).
    let b: LonLatBounds = area.parse().unwrap();
    let listed: u64 = [12, 13, 14]
        .iter()
        .map(|&z| TileRange::covering(z, &b).len())
        .sum();
    assert_eq!(uris.len() as u64, listed, "{uris:?}");
    assert!(
        uris.iter().all(|u| u.ends_with(".enu-meshopt.glb")),
        "{uris:?}"
    );

    // A static file server, nothing of terrastitch.
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let address = listener.local_addr().unwrap();
    let site = axum::Router::new().fallback_service(tower_http::services::ServeDir::new(&out));
    let served = tokio::spawn(async move { axum::serve(listener, site).await });
    // The middle of the north-western tile (the box's centre is the corner of all four).
    let (lon, lat) = (
        b.west + (b.east - b.west) / 4.0,
        b.north - (b.north - b.south) / 4.0,
    );
    let artifacts = common::repo().join("tests/artifacts/export");
    let _turn = common::browser_turn().await;
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
    assert_eq!(report["consoleErrors"], serde_json::json!([]), "{text}");
    assert_eq!(report["failedRequests"], serde_json::json!([]), "{text}");
    assert_eq!(report["failedResponses"], serde_json::json!([]), "{text}");
    assert_eq!(report["state"]["errors"], serde_json::json!([]), "{text}");
    let loaded = report["state"]["loaded"].as_array().unwrap();
    assert!(loaded.len() >= 4, "{text}");
    // Straight down at the centre the ray meets the drawn ground or what stands on it.
    assert!(report["probe"].is_object(), "{text}");
}

/// A signal that comes the moment the server says it listens, before it has answered
/// anything, still stops it cleanly: the handlers are in place before the address is announced.
#[test]
fn a_signal_right_after_listening_stops_the_server_cleanly() {
    for signal in ["-TERM", "-INT"] {
        let dir = tempfile::tempdir().unwrap();
        let cache = dir.path().join("cache.sqlite");
        let (mut child, _address, _lines) =
            spawn_server(&["--cache", cache.to_str().unwrap()], &[]);
        let status = Command::new("kill")
            .args([signal, &child.id().to_string()])
            .status()
            .unwrap();
        assert!(status.success());
        let exit = child.wait().unwrap();
        assert!(exit.success(), "{signal}: {exit:?}");
    }
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
