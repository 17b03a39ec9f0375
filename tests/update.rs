//! OSM diffs applied to the store: the tiles whose bytes change are all in the expire list, the
//! list holds no tile far from the change, the updated store makes the same tiles as a store
//! imported from the extract with the change applied, and a bad or out-of-order diff leaves the
//! store as it was.
//!
//! The diffs are written by `scripts/osm_diff.py` (pyosmium), with the changed extract.

mod common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::process::Output;

use common::{sample_osm, terrastitch};
use sha2::{Digest, Sha256};

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
/// elements it chose (`way 123`).
fn write_diff(edit: &str, osc: &Path, changed: &Path) -> Vec<String> {
    let output = run(std::process::Command::new(python())
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

/// The digest of each of the area's tiles made from `store` (imported from `extract`).
fn tiles(store: &Path, extract: &Path, dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let out = dir.join("tiles");
    run(terrastitch()
        .arg("export")
        .arg("--bbox")
        .arg(AREA)
        .arg("--store")
        .arg(store)
        .arg("--osm")
        .arg(extract)
        .arg("--cache")
        .arg(dir.join("cache.sqlite"))
        .arg("-o")
        .arg(format!("{}/", out.display())));
    let mut found = BTreeMap::new();
    for x in std::fs::read_dir(out.join("14")).unwrap() {
        let x = x.unwrap();
        for y in std::fs::read_dir(x.path()).unwrap() {
            let y = y.unwrap().path();
            let name = format!(
                "14/{}/{}",
                x.file_name().to_string_lossy(),
                y.file_stem().unwrap().to_string_lossy()
            );
            found.insert(name, Sha256::digest(std::fs::read(&y).unwrap()).to_vec());
        }
    }
    found
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
/// makes every tile as a store imported from the changed extract does.
fn apply(edit: &str) -> Outcome {
    let dir = tempfile::tempdir().unwrap();
    let osc = dir.path().join("change.osc.gz");
    let changed_extract = dir.path().join("changed.osm.pbf");
    write_diff(edit, &osc, &changed_extract);
    let store = dir.path().join("osm.sqlite");
    import(&store, &sample_osm());
    let before = tiles(&store, &sample_osm(), &dir.path().join("before"));

    let output = update(&store, &osc);
    assert!(output.status.success(), "{}", stderr(&output));
    let expired: BTreeSet<String> = String::from_utf8_lossy(&output.stdout)
        .lines()
        .map(str::to_string)
        .collect();
    let after = tiles(&store, &sample_osm(), &dir.path().join("after"));

    let fresh = dir.path().join("fresh.sqlite");
    import(&fresh, &changed_extract);
    let imported = tiles(&fresh, &changed_extract, &dir.path().join("fresh"));
    assert_eq!(
        after, imported,
        "the updated store makes each tile as a store imported from the changed extract"
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

#[test]
fn a_moved_bridge_node_expires_the_tiles_around_its_group_and_no_far_tile() {
    let outcome = apply("move-bridge-node");
    assert!(
        !outcome.changed.is_empty(),
        "moving a bridge changes a tile"
    );
    assert!(
        outcome.changed.is_subset(&outcome.expired),
        "every changed tile is expired: changed {:?}, expired {:?}",
        outcome.changed,
        outcome.expired
    );
    assert!(
        outcome.expired.is_subset(&around(&outcome.changed)),
        "no tile far from the change is expired: changed {:?}, expired {:?}",
        outcome.changed,
        outcome.expired
    );
    assert!(
        outcome.expired.len() * 4 < outcome.all,
        "{} of {} tiles expired",
        outcome.expired.len(),
        outcome.all
    );
}

#[test]
fn a_deleted_building_changes_its_tiles_only() {
    let outcome = apply("delete-building");
    assert!(
        !outcome.changed.is_empty(),
        "deleting a building changes a tile"
    );
    assert!(
        outcome.changed.is_subset(&outcome.expired),
        "changed {:?}, expired {:?}",
        outcome.changed,
        outcome.expired
    );
    assert!(
        outcome.expired.is_subset(&around(&outcome.changed)),
        "changed {:?}, expired {:?}",
        outcome.changed,
        outcome.expired
    );
}

#[test]
fn many_changes_expire_every_tile_they_change() {
    let outcome = apply("many:300");
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
