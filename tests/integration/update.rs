//! OSM diffs applied to the store: the tiles whose bytes change are all in the expire list, the
//! list holds no tile far from the change, the updated store makes the same tiles as a store
//! imported from the extract with the change applied, and a bad or out-of-order diff leaves the
//! store as it was.
//!
//! The diffs are written by `scripts/osm_diff.py` (pyosmium), with the changed extract.

use crate::common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Output;

use common::{sample_osm, terrastitch};
use sha2::{Digest, Sha256};
use terrastitch::cache::{SqliteStore, TileFilter, TileReader, TileStore};

/// Monaco's tiles: every tile the bundled extract reaches.
const AREA: &str = "7.37,43.72,7.45,43.76";

fn python() -> String {
    std::env::var("TERRASTITCH_PYTHON").unwrap_or_else(|_| "python3".to_string())
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

fn run(command: &mut std::process::Command) -> Output {
    let output = command.output().unwrap();
    assert!(output.status.success(), "{}", stderr(&output));
    output
}

/// Writes the diff `edit` of the bundled extract and the extract it makes; returns the
/// elements it chose (`way 123`). The extract is read once for every diff, by the first, and
/// kept in `tests/artifacts/osm-diff` for the others (and the next runs, while it is the same
/// file).
fn write_diff(edit: &str, osc: &Path, changed: &Path) -> Vec<String> {
    let output = run(std::process::Command::new(python())
        .env(
            "OSM_DIFF_CACHE",
            common::repo().join("tests/artifacts/osm-diff"),
        )
        .arg(common::repo().join("scripts/osm_diff.py"))
        .arg(sample_osm())
        .arg(edit)
        .arg(osc)
        .arg(changed));
    stderr(&output).lines().map(str::to_string).collect()
}

fn import(store: &Path, extract: &Path) {
    run(terrastitch()
        .arg("import")
        .arg("--store")
        .arg(store)
        .arg("--osm")
        .arg(extract));
}

fn update(store: &Path, osc: &Path) -> Output {
    terrastitch()
        .arg("update")
        .arg("--store")
        .arg(store)
        .arg("--osc")
        .arg(osc)
        .arg("--expired")
        .arg("-")
        .output()
        .unwrap()
}

/// The digest of each of the area's tiles made from `store` (imported from `extract`), by
/// `seed` into a cache of its own in `dir`. The cache starts with the elevation components the
/// sample's seed solved and no tile: a component is found by what it holds, so a seed reuses
/// those its store still has and solves the rest, as a seed after an update does.
fn tiles(store: &Path, extract: &Path, dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::create_dir_all(dir).unwrap();
    let cache = dir.join("cache.sqlite");
    std::fs::write(&cache, &the_sample().1).unwrap();
    seed(store, extract, &cache)
}

/// Seeds the area into `cache` and returns the digest of each tile in it.
fn seed(store: &Path, extract: &Path, cache: &Path) -> BTreeMap<String, Vec<u8>> {
    run(terrastitch()
        .args(["seed", "--bbox", AREA, "--format", "glb", "--store"])
        .arg(store)
        .arg("--osm")
        .arg(extract)
        .arg("--cache")
        .arg(cache));
    let made = SqliteStore::open(cache, None).unwrap();
    let entries = made.list(&TileFilter::All).unwrap();
    assert!(!entries.is_empty(), "the area has tiles");
    entries
        .into_iter()
        .map(|entry| {
            let tile = made
                .get(&entry.key)
                .unwrap()
                .expect("a listed tile is stored");
            // The stored tile's strong validator is the digest of its bytes.
            (entry.key.tile.to_string(), tile.etag.into_bytes())
        })
        .collect()
}

/// Each tile's digest, by its name.
type Digests = BTreeMap<String, Vec<u8>>;

/// The area's tiles from a store imported from the bundled extract, and the bytes of a cache
/// file holding only the elevation components they solved: made once a run, as every diff of
/// it starts from them.
fn the_sample() -> &'static (Digests, Vec<u8>) {
    static MADE: std::sync::OnceLock<(Digests, Vec<u8>)> = std::sync::OnceLock::new();
    MADE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let store = dir.path().join("osm.sqlite");
        import(&store, &sample_osm());
        let cache = dir.path().join("cache.sqlite");
        let tiles = seed(&store, &sample_osm(), &cache);
        let made = SqliteStore::open(&cache, None).unwrap();
        made.remove(&TileFilter::All).unwrap();
        drop(made);
        // Closed, the store has folded its write-ahead log into the file: its bytes are whole.
        let log = dir.path().join("cache.sqlite-wal");
        assert!(std::fs::metadata(&log).map_or(true, |m| m.len() == 0));
        (tiles, std::fs::read(&cache).unwrap())
    })
}

fn tiles_of_the_sample() -> BTreeMap<String, Vec<u8>> {
    the_sample().0.clone()
}

fn file_digest(path: &Path) -> Vec<u8> {
    Sha256::digest(std::fs::read(path).unwrap()).to_vec()
}

/// What a diff did to the area's tiles.
struct Outcome {
    expired: BTreeSet<String>,
    changed: BTreeSet<String>,
    all: usize,
}

/// Imports the bundled extract, applies the diff `edit`, and checks that the updated store
/// holds what a store imported from the changed extract holds.
fn apply(edit: &str) -> Outcome {
    let dir = tempfile::tempdir().unwrap();
    let osc = dir.path().join("change.osc.gz");
    let changed_extract = dir.path().join("changed.osm.pbf");
    write_diff(edit, &osc, &changed_extract);
    check(dir.path(), &sample_osm(), &osc, &changed_extract)
}

/// Imports the bundled extract cut by the diff `cut` (elements deleted that others still name,
/// as at an extract's border), applies `bring` (which creates them again), and checks that the
/// updated store holds what a store imported from the whole extract holds.
fn restore(cut: &str, bring: &str) -> Outcome {
    let dir = tempfile::tempdir().unwrap();
    let cut_extract = dir.path().join("cut.osm.pbf");
    write_diff(cut, &dir.path().join("cut.osc"), &cut_extract);
    let osc = dir.path().join("bring.osc.gz");
    write_diff(bring, &osc, &dir.path().join("unused.osm.pbf"));
    check(dir.path(), &cut_extract, &osc, &sample_osm())
}

/// Imports `base`, applies `osc`, and checks that the updated store holds what a store imported
/// from `changed` holds (so makes every tile as it does); returns what the diff did to the
/// area's tiles.
fn check(dir: &Path, base: &Path, osc: &Path, changed: &Path) -> Outcome {
    let store = dir.join("osm.sqlite");
    import(&store, base);
    let before = match base == sample_osm() {
        true => tiles_of_the_sample(),
        false => tiles(&store, base, &dir.join("before")),
    };

    let output = update(&store, osc);
    assert!(output.status.success(), "{}", stderr(&output));
    let expired: BTreeSet<String> = String::from_utf8_lossy(&output.stdout)
        .lines()
        .map(str::to_string)
        .collect();
    let after = tiles(&store, base, &dir.join("after"));

    // Tiles are made from the store alone: one that holds, row for row, what a store imported
    // from the changed extract holds makes every tile as that store does.
    let fresh = dir.join("fresh.sqlite");
    import(&fresh, changed);
    let tables = |store: &Path| common::table_rows(store, &common::STORE_TABLES);
    assert!(
        tables(&store) == tables(&fresh),
        "the updated store holds what a store imported from the changed extract holds"
    );
    let changed = before
        .iter()
        .filter(|(tile, digest)| after.get(*tile) != Some(*digest))
        .map(|(tile, _)| tile.clone())
        .collect();
    Outcome {
        expired,
        changed,
        all: before.len(),
    }
}

/// The tiles within one of `tiles` (a 3 × 3 block around each).
fn around(tiles: &BTreeSet<String>) -> BTreeSet<String> {
    let mut near = BTreeSet::new();
    for tile in tiles {
        let parts: Vec<i64> = tile.split('/').map(|p| p.parse().unwrap()).collect();
        for dx in -1..=1 {
            for dy in -1..=1 {
                near.insert(format!("14/{}/{}", parts[1] + dx, parts[2] + dy));
            }
        }
    }
    near
}

impl Outcome {
    /// Checks that the diff changed some tile, that every tile it changed is expired, and that
    /// no tile beyond those around the changed ones is.
    fn assert_exact(&self, what: &str) {
        let (changed, expired) = (&self.changed, &self.expired);
        assert!(!changed.is_empty(), "{what} changes a tile");
        assert!(
            changed.is_subset(expired),
            "every changed tile is expired: changed {changed:?}, expired {expired:?}"
        );
        assert!(
            expired.is_subset(&around(changed)),
            "no tile far from the change is expired: changed {changed:?}, expired {expired:?}"
        );
    }
}

#[test]
fn a_moved_bridge_node_expires_the_tiles_around_its_group_and_no_far_tile() {
    let outcome = apply("move-bridge-node");
    outcome.assert_exact("moving a bridge");
    assert!(
        outcome.expired.len() * 4 < outcome.all,
        "{} of {} tiles expired",
        outcome.expired.len(),
        outcome.all
    );
}

#[test]
fn a_deleted_building_changes_its_tiles_only() {
    apply("delete-building").assert_exact("deleting a building");
}

#[test]
fn a_multipolygon_turned_into_a_lake_changes_its_tiles_only() {
    apply("water-multipolygon").assert_exact("a new lake");
}

#[test]
fn a_node_a_way_missed_at_import_is_found_when_a_diff_brings_it() {
    restore("cut-node", "bring-node").assert_exact("a road's node brought back");
}

#[test]
fn a_relation_whose_ways_were_missing_is_found_when_a_diff_brings_them() {
    restore("cut-ways", "bring-ways").assert_exact("a multipolygon's ways brought back");
}

#[test]
fn many_changes_expire_every_tile_they_change() {
    let outcome = apply("many:300");
    assert!(
        outcome.changed.len() > 1,
        "300 changes changed {:?}",
        outcome.changed
    );
    assert!(
        outcome.changed.is_subset(&outcome.expired),
        "changed {:?}, expired {:?}",
        outcome.changed,
        outcome.expired
    );
}

#[test]
fn a_truncated_or_out_of_order_diff_is_refused_by_name_and_the_store_is_unchanged() {
    let dir = tempfile::tempdir().unwrap();
    let osc = dir.path().join("bridge.osc.gz");
    write_diff(
        "move-bridge-node",
        &osc,
        &dir.path().join("changed.osm.pbf"),
    );
    let store = dir.path().join("osm.sqlite");
    import(&store, &sample_osm());
    let pristine = file_digest(&store);

    let bytes = std::fs::read(&osc).unwrap();
    let cut = dir.path().join("cut.osc.gz");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let refused = update(&store, &cut);
    assert!(!refused.status.success());
    let message = stderr(&refused);
    assert!(message.contains("cut.osc.gz"), "{message}");
    assert_eq!(file_digest(&store), pristine, "the store is unchanged");

    let applied = update(&store, &osc);
    assert!(applied.status.success(), "{}", stderr(&applied));
    let updated = file_digest(&store);
    // The same change a year older: out of order once the newer one is in.
    let older = dir.path().join("older.osc");
    let text = String::from_utf8(
        std::io::Read::bytes(flate2::read::GzDecoder::new(bytes.as_slice()))
            .collect::<Result<Vec<u8>, _>>()
            .unwrap(),
    )
    .unwrap()
    .replace("2030-01-01", "2029-01-01");
    std::fs::write(&older, text).unwrap();
    let refused = update(&store, &older);
    assert!(!refused.status.success());
    let message = stderr(&refused);
    assert!(
        message.contains("older.osc") && message.contains("out of order"),
        "{message}"
    );
    assert_eq!(file_digest(&store), updated, "the store is unchanged");
}

/// A replication directory with `count` diffs of the bundled extract (sequences 1 to
/// `count`) and its `state.txt` at sequence 0.
fn replication_source(dir: &Path, count: u64) -> PathBuf {
    let source = dir.join("replication");
    for sequence in 1..=count {
        let file = source.join(format!("000/000/{sequence:03}.osc.gz"));
        std::fs::create_dir_all(file.parent().unwrap()).unwrap();
        let changed = dir.join(format!("changed-{sequence}.osm.pbf"));
        write_diff(&format!("many:100:{sequence}"), &file, &changed);
    }
    set_state(&source, 0);
    source
}

fn set_state(source: &Path, sequence: u64) {
    std::fs::write(
        source.join("state.txt"),
        format!("sequenceNumber={sequence}\ntimestamp=2030-01-01T00\\:00\\:00Z\n"),
    )
    .unwrap();
}

fn catch_up(store: &Path, source: &Path) -> std::process::Child {
    terrastitch()
        .arg("update")
        .arg("--store")
        .arg(store)
        .arg("--replication")
        .arg(source)
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap()
}

fn sequence_of(store: &Path) -> Option<u64> {
    let db =
        rusqlite::Connection::open_with_flags(store, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
            .ok()?;
    db.busy_timeout(std::time::Duration::from_secs(5)).ok()?;
    db.query_row(
        "SELECT value FROM meta WHERE key = 'replication_sequence'",
        [],
        |r| r.get::<_, String>(0),
    )
    .ok()
    .and_then(|v| v.parse().ok())
}

/// Every row of the store's tables and the meta a diff changes, in order.
fn contents(store: &Path) -> Vec<String> {
    common::table_rows(
        store,
        &[
            &common::STORE_TABLES[..],
            &[
                ("node_moves", "id"),
                ("expired", "x, y"),
                ("meta WHERE key != 'nodes_file'", "key"),
            ],
        ]
        .concat(),
    )
}

#[test]
fn replication_killed_midway_resumes_after_the_last_diff_applied() {
    let dir = tempfile::tempdir().unwrap();
    let source = replication_source(dir.path(), 4);
    let store = dir.path().join("osm.sqlite");
    import(&store, &sample_osm());
    // A store that knows no sequence starts at the source's.
    assert!(catch_up(&store, &source).wait().unwrap().success());
    assert_eq!(sequence_of(&store), Some(0));
    let whole = dir.path().join("whole.sqlite");
    std::fs::copy(&store, &whole).unwrap();
    set_state(&source, 4);

    assert!(catch_up(&whole, &source).wait().unwrap().success());
    assert_eq!(sequence_of(&whole), Some(4));

    // The second diff is a pipe no one writes to: the run applies the first, then waits on
    // the second until it is killed.
    let second = source.join("000/000/002.osc.gz");
    let kept = source.join("002.osc.gz.kept");
    std::fs::rename(&second, &kept).unwrap();
    let fifo = std::ffi::CString::new(second.to_str().unwrap()).unwrap();
    // SAFETY: mkfifo reads a NUL-terminated path and creates a file.
    assert_eq!(unsafe { libc::mkfifo(fifo.as_ptr(), 0o600) }, 0);
    let mut child = catch_up(&store, &source);
    common::wait_for("the first diff to be applied", || {
        (sequence_of(&store).unwrap_or(0) >= 1).then_some(())
    });
    child.kill().unwrap();
    child.wait().unwrap();
    assert_eq!(
        sequence_of(&store),
        Some(1),
        "the run was cut after the first diff"
    );
    std::fs::remove_file(&second).unwrap();
    std::fs::rename(&kept, &second).unwrap();

    assert!(catch_up(&store, &source).wait().unwrap().success());
    assert_eq!(sequence_of(&store), Some(4));
    assert!(
        contents(&store) == contents(&whole),
        "resumed, the store holds what one uninterrupted run wrote"
    );
}

#[test]
fn a_missing_diff_stops_replication_by_name_after_those_before_it() {
    let dir = tempfile::tempdir().unwrap();
    let source = replication_source(dir.path(), 1);
    let store = dir.path().join("osm.sqlite");
    import(&store, &sample_osm());
    assert!(catch_up(&store, &source).wait().unwrap().success());
    set_state(&source, 2);
    // Sequence 2 is missing: 1 is applied, then the run stops with a named error.
    let output = terrastitch()
        .arg("update")
        .arg("--store")
        .arg(&store)
        .arg("--replication")
        .arg(&source)
        .output()
        .unwrap();
    assert!(!output.status.success());
    let message = stderr(&output);
    assert!(message.contains("002.osc.gz"), "{message}");
    assert_eq!(sequence_of(&store), Some(1));
}

/// The variables of the elevation LP the render of `tile` from `store` solves.
fn lp_variables(store: &Path, extract: &Path, tile: &str, out: &Path) -> u64 {
    let output = run(terrastitch()
        .args(["render", tile, "--timings", "--store"])
        .arg(store)
        .arg("--osm")
        .arg(extract)
        .arg("-o")
        .arg(out));
    let said = String::from_utf8_lossy(&output.stdout).to_string() + &stderr(&output);
    said.lines()
        .find_map(|l| l.strip_prefix("elevation LP: "))
        .and_then(|l| l.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no LP figures in {said}"))
}

#[test]
fn a_node_moved_far_away_expires_the_tiles_its_road_crosses_and_its_tile_stays_cheap() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("osm.sqlite");
    import(&store, &sample_osm());
    // The road runs through 14/8527/5973 (its middle node is there).
    let tile = "14/8527/5973";
    let before = lp_variables(&store, &sample_osm(), tile, &dir.path().join("before.glb"));
    for (far, most) in [("1", 600), ("10", 6000)] {
        let osc = dir.path().join(format!("far-{far}.osc"));
        let changed = dir.path().join(format!("far-{far}.osm.pbf"));
        write_diff(&format!("far-node:{far}"), &osc, &changed);
        let moved = dir.path().join(format!("moved-{far}.sqlite"));
        import(&moved, &sample_osm());
        let output = update(&moved, &osc);
        assert!(output.status.success(), "{}", stderr(&output));
        let expired = String::from_utf8_lossy(&output.stdout).lines().count();
        // A band along the road's new segments, not the box they span (about 2,900 tiles for
        // a degree north and east).
        assert!(expired <= most, "{far}°: {expired} tiles expired");
        let fresh = dir.path().join(format!("fresh-{far}.sqlite"));
        import(&fresh, &changed);
        let tables = |store: &Path| common::table_rows(store, &common::STORE_TABLES);
        assert!(
            tables(&moved) == tables(&fresh),
            "{far}°: the updated store holds what an import of the changed extract holds"
        );
        // The road, now hundreds of kilometres long, is drawn from its part near the tile.
        let after = lp_variables(&moved, &sample_osm(), tile, &dir.path().join("after.glb"));
        assert!(
            after * 10 <= before * 11,
            "{far}°: the tile's LP grew from {before} to {after} variables"
        );
    }
}

/// `update --replication` run to its end.
fn catch_up_said(store: &Path, source: &Path) -> Output {
    terrastitch()
        .arg("update")
        .arg("--store")
        .arg(store)
        .arg("--replication")
        .arg(source)
        .output()
        .unwrap()
}

#[test]
fn a_replication_source_gone_back_in_time_or_behind_is_refused_or_told() {
    let dir = tempfile::tempdir().unwrap();
    let source = replication_source(dir.path(), 2);
    let store = dir.path().join("osm.sqlite");
    import(&store, &sample_osm());
    assert!(catch_up(&store, &source).wait().unwrap().success());
    // Sequence 2 holds changes a year older than sequence 1's.
    let second = source.join("000/000/002.osc.gz");
    let gz = std::fs::read(&second).unwrap();
    let mut text = String::new();
    std::io::Read::read_to_string(&mut flate2::read::GzDecoder::new(gz.as_slice()), &mut text)
        .unwrap();
    assert!(text.contains("2030-01-01"));
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    std::io::Write::write_all(
        &mut encoder,
        text.replace("2030-01-01", "2029-01-01").as_bytes(),
    )
    .unwrap();
    std::fs::write(&second, encoder.finish().unwrap()).unwrap();
    set_state(&source, 2);
    let refused = catch_up_said(&store, &source);
    let message = stderr(&refused);
    assert!(!refused.status.success(), "{message}");
    assert!(
        message.contains("002.osc.gz") && message.contains("is older than one applied before"),
        "{message}"
    );
    assert_eq!(sequence_of(&store), Some(1));
    // A state file whose sequence is not a number is named for what it says.
    std::fs::write(source.join("state.txt"), "sequenceNumber=abc\n").unwrap();
    let refused = catch_up_said(&store, &source);
    let message = stderr(&refused);
    assert!(!refused.status.success(), "{message}");
    assert!(message.contains("says sequenceNumber=abc"), "{message}");
    // A source behind the store applies nothing, and says so.
    set_state(&source, 0);
    let behind = catch_up_said(&store, &source);
    let message = stderr(&behind);
    assert!(behind.status.success(), "{message}");
    assert!(message.contains("behind the OSM store"), "{message}");
    assert_eq!(sequence_of(&store), Some(1));
}

#[test]
fn a_server_applies_its_replication_diffs_and_remakes_exactly_the_expired_tiles() {
    use common::process::{request, spawn_server};
    let dir = tempfile::tempdir().unwrap();
    let source = dir.path().join("replication");
    let diff = source.join("000/000/001.osc.gz");
    std::fs::create_dir_all(diff.parent().unwrap()).unwrap();
    write_diff(
        "move-bridge-node",
        &diff,
        &dir.path().join("changed.osm.pbf"),
    );
    set_state(&source, 0);
    let store = dir.path().join("osm.sqlite");
    import(&store, &sample_osm());
    assert!(catch_up(&store, &source).wait().unwrap().success());

    let cache = dir.path().join("cache.sqlite");
    let source_text = source.display().to_string();
    let (child, address, _lines) = spawn_server(
        &[
            "--store",
            store.to_str().unwrap(),
            "--cache",
            cache.to_str().unwrap(),
        ],
        &[
            ("TERRASTITCH_SERVER__CHECK_INTERVAL_S", "1"),
            ("TERRASTITCH_SOURCES__REPLICATION", &source_text),
        ],
    );
    // Stopped however the test ends.
    struct Stop(std::process::Child);
    impl Drop for Stop {
        fn drop(&mut self) {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
    let child = Stop(child);
    common::wait_for("the server to become ready", || {
        (request(&address, "/ready", &[]).0 == 200).then_some(())
    });
    let get = |tile: &str| {
        let (status, head, body) = request(&address, &format!("/tiles/{tile}.glb"), &[]);
        assert_eq!(status, 200, "{head}");
        (head.to_lowercase(), body)
    };
    // The bridge's tile, and one far from it.
    let (near, far) = ("14/8528/5973", "14/8531/5975");
    let (_, near_before) = get(near);
    let (_, far_before) = get(far);

    set_state(&source, 1);
    common::wait_for("the bridge's tile to be made again", || {
        let (_, body) = get(near);
        (body != near_before).then_some(())
    });
    assert_eq!(sequence_of(&store), Some(1));
    let (head, body) = get(far);
    assert_eq!(body, far_before, "a far tile keeps its bytes");
    assert!(head.contains("x-cache: hit"), "{head}");
    // Of the two tiles stored, only the expired one was made again.
    let remade = common::process::metric(&address, "terrastitch_regenerations_total");
    assert_eq!(remade, Some(1.0));
    drop(child);
}
