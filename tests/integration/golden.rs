//! The same inputs give the same bytes: the SHA-256 of a fixed set of tiles, made by the command
//! line (`seed`, the server's pipeline) from the bundled sample, in every glb variant and as
//! terrain, and read back as the cache serves them, against the digests recorded in
//! `tests/golden/digests.txt`.
//!
//! A change that leaves the output alone leaves these digests alone. A change meant to alter the
//! bytes records the new digests in a commit of its own that says why:
//! `TERRASTITCH_GOLDEN_WRITE=1 cargo test --release --test integration golden::` rewrites the
//! file.

use crate::common;

use std::collections::BTreeMap;
use std::path::Path;

use common::{bbox, repo, terrastitch};
use sha2::{Digest, Sha256};
use terrastitch::cache::encoding::Accepted;
use terrastitch::cache::{SqliteStore, TileFilter, TileReader};
use terrastitch::format::Encoding;
use terrastitch::offline::export::file_suffix;

/// Monaco's ten densest tiles: the coast, the port, the bridges and tunnels of the centre.
const COLUMNS: std::ops::RangeInclusive<u32> = 8527..=8531;
const ROWS: std::ops::RangeInclusive<u32> = 5973..=5974;
const FORMATS: &str = "glb,glb-meshopt,glb-enu,glb-enu-meshopt,terrain";

fn digests_file() -> std::path::PathBuf {
    repo().join("tests/golden/digests.txt")
}

/// Every tile the cache at `path` holds, by its path in a directory export (`14/x/y.glb`,
/// `14/x/y.enu-meshopt.glb`, …), with the SHA-256 of its bytes as served uncompressed.
fn digests_in(path: &Path) -> BTreeMap<String, String> {
    let store = SqliteStore::open(path, None).unwrap();
    let identity = Accepted::parse([]);
    let mut digests = BTreeMap::new();
    for entry in store.list(&TileFilter::All).unwrap() {
        let key = entry.key;
        let tile = store.get(&key).unwrap().expect("a listed tile is held");
        let (coding, bytes) = tile.bodies.choose(&identity);
        assert_eq!(coding, Encoding::Identity);
        let relative = format!(
            "{}/{}/{}{}",
            key.tile.z,
            key.tile.x,
            key.tile.y,
            file_suffix(key.format)
        );
        let digest: String = Sha256::digest(bytes)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        digests.insert(relative, digest);
    }
    digests
}

fn recorded() -> BTreeMap<String, String> {
    let text = std::fs::read_to_string(digests_file()).unwrap_or_default();
    text.lines()
        .filter(|line| !line.trim().is_empty() && !line.starts_with('#'))
        .map(|line| {
            let (digest, path) = line.split_once("  ").expect("'digest  path' lines");
            (path.to_string(), digest.to_string())
        })
        .collect()
}

/// The golden tiles made by `seed` into a cache of their own (the served zoom only), with
/// `extra` arguments, by their paths.
fn seed(work: &Path, extra: &[&std::ffi::OsStr]) -> BTreeMap<String, String> {
    let cache = work.join("cache.sqlite");
    let output = terrastitch()
        .args(["seed", "--bbox"])
        .arg(bbox(
            *COLUMNS.start(),
            *COLUMNS.end(),
            *ROWS.start(),
            *ROWS.end(),
        ))
        .args(["--format", FORMATS])
        .arg("--cache")
        .arg(&cache)
        .args(extra)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    digests_in(&cache)
}

/// The tiles that differ from the recorded digests.
fn changed(made: &BTreeMap<String, String>) -> Vec<String> {
    let expected = recorded();
    made.keys()
        .chain(expected.keys())
        .filter(|path| made.get(*path) != expected.get(*path))
        .cloned()
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect()
}

#[test]
fn golden_tiles_keep_their_bytes() {
    let work = tempfile::tempdir().unwrap();
    let made = seed(work.path(), &[]);
    assert_eq!(made.len(), 50, "ten tiles in five formats: {made:#?}");
    if std::env::var_os("TERRASTITCH_GOLDEN_WRITE").is_some() {
        let mut text = String::from(
            "# SHA-256 of the golden tiles (tests/golden.rs); rewrite only in a commit that says \
             why the bytes change.\n",
        );
        for (path, digest) in &made {
            text.push_str(&format!("{digest}  {path}\n"));
        }
        std::fs::create_dir_all(digests_file().parent().unwrap()).unwrap();
        std::fs::write(digests_file(), text).unwrap();
        return;
    }
    let changed = changed(&made);
    assert!(
        changed.is_empty(),
        "{} of {} golden tiles changed: {changed:?}",
        changed.len(),
        made.len()
    );
}

/// Tiles read from the imported store are the tiles made from the extract in memory.
#[test]
fn golden_tiles_from_the_store_keep_their_bytes() {
    let work = tempfile::tempdir().unwrap();
    let store = work.path().join("osm.sqlite");
    let made = seed(work.path(), &["--store".as_ref(), store.as_os_str()]);
    assert!(
        store.exists(),
        "seed imported the store it was told to read"
    );
    assert_eq!(made.len(), 50);
    let changed = changed(&made);
    assert!(
        changed.is_empty(),
        "{} of {} golden tiles from the store differ: {changed:?}",
        changed.len(),
        made.len()
    );
}
