//! The SQLite store's tests.
use super::*;
use crate::cache::store::unix_now;
use crate::tile::TileId;

fn key(x: u32) -> TileKey {
    TileKey {
        tile: TileId { z: 14, x, y: 2 },
        format: Format::GLB,
    }
}

/// `length` bytes that do not compress (xorshift from `seed`).
fn noise(seed: u64, length: usize) -> Vec<u8> {
    let mut state = seed | 1;
    (0..length)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state as u8
        })
        .collect()
}

fn tile(data: Vec<u8>, pipeline: &str, at: i64) -> StoredTile {
    StoredTile {
        etag: crate::cache::etag_of(&data),
        bodies: Bodies::compress(data).unwrap(),
        made_by: Provenance {
            pipeline: pipeline.to_string(),
            sources: "s1".to_string(),
        },
        created_at: at,
    }
}

#[test]
fn a_tile_put_if_vacant_replaces_only_its_own_forms() {
    let dir = tempfile::tempdir().unwrap();
    let store = SqliteStore::open(&dir.path().join("tiles.sqlite"), None).unwrap();
    let data = vec![7; 10_000];
    let quick = StoredTile {
        bodies: Bodies::quick(data.clone(), &crate::cache::encoding::Accepted::default()).unwrap(),
        ..tile(data.clone(), "v1", 5)
    };
    assert!(store.put_if_vacant(&key(1), &quick).unwrap(), "none held");
    let kept = tile(data, "v1", 6);
    assert!(
        store.put_if_vacant(&key(1), &kept).unwrap(),
        "the same content in other forms"
    );
    let found = store.get(&key(1)).unwrap().unwrap();
    assert_eq!(found.bodies, kept.bodies);
    let usage = store.usage().unwrap();
    assert_eq!(usage.tiles, 1);
    assert!(
        usage.bytes < 1_000,
        "the identity form's bytes went: {usage:?}"
    );
    let other = tile(vec![8; 10_000], "v2", 7);
    assert!(
        !store.put_if_vacant(&key(1), &other).unwrap(),
        "another tile is held"
    );
    assert_eq!(store.get(&key(1)).unwrap().unwrap(), found);
    assert_eq!(usage_scanned(&store), (1, usage.bytes as i64));
}

#[test]
fn stores_a_tile_with_its_provenance_and_reopens_without_migrating_twice() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sub/tiles.sqlite");
    let store = SqliteStore::open(&path, None).unwrap();
    let stored = tile(vec![7; 10_000], "v1", unix_now());
    store.put(&key(1), &stored).unwrap();
    let found = store.get(&key(1)).unwrap().unwrap();
    assert_eq!(found, stored);
    assert!(
        found.bodies.gzip.is_some(),
        "a repetitive tile is stored compressed"
    );
    assert_eq!(store.get(&key(2)).unwrap(), None);
    let usage = store.usage().unwrap();
    assert_eq!(usage.tiles, 1);
    assert!(usage.bytes < 1_000, "{usage:?}");
    assert!(
        usage.bytes > found.bodies.stored_len() as u64 + 64,
        "the row's text and overhead count too: {usage:?}"
    );
    drop(store);
    let store = SqliteStore::open(&path, None).unwrap();
    assert_eq!(store.usage().unwrap().tiles, 1);
    store.check_integrity().unwrap();
}

#[test]
fn a_stored_coding_that_does_not_match_the_digest_is_dropped_not_served() {
    let dir = tempfile::tempdir().unwrap();
    let store = SqliteStore::open(&dir.path().join("t.sqlite"), None).unwrap();
    for (x, column) in [(1, "data_br"), (2, "data")] {
        let stored = tile((0..20_000).map(|i| (i % 251) as u8).collect(), "v", 1);
        assert!(stored.bodies.brotli.is_some() && stored.bodies.gzip.is_some());
        store.put(&key(x), &stored).unwrap();
        // Eight bytes flipped in the middle of one stored form; SQLite sees nothing wrong.
        let body: Vec<u8> = store
            .connection()
            .query_row(
                &format!("SELECT {column} FROM tiles WHERE x = ?1"),
                [x],
                |r| r.get(0),
            )
            .unwrap();
        let mut damaged = body.clone();
        let middle = damaged.len() / 2;
        for byte in &mut damaged[middle..middle + 8] {
            *byte ^= 0x5a;
        }
        store
            .connection()
            .execute(
                &format!("UPDATE tiles SET {column} = ?1 WHERE x = ?2"),
                rusqlite::params![damaged, x],
            )
            .unwrap();
        assert_eq!(store.get(&key(x)).unwrap(), None, "{column}");
        assert!(store
            .list(&TileFilter::All)
            .unwrap()
            .iter()
            .all(|e| e.key != key(x)));
    }
    store.check_integrity().unwrap();
}

#[test]
fn a_cache_file_damaged_in_the_middle_is_moved_aside_and_a_new_one_started() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tiles.sqlite");
    {
        let store = SqliteStore::open(&path, None).unwrap();
        for x in 0..40 {
            let data = noise(u64::from(x), 100_000);
            store.put(&key(x), &tile(data, "v", 1)).unwrap();
        }
        store
            .connection()
            .execute_batch("PRAGMA wal_checkpoint(TRUNCATE)")
            .unwrap();
    }
    let length = std::fs::metadata(&path).unwrap().len();
    assert!(length > 3 << 20, "{length}");
    {
        use std::io::{Seek, Write};
        let mut file = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
        file.seek(std::io::SeekFrom::Start(length / 2 - (512 << 10)))
            .unwrap();
        let garbage: Vec<u8> = (0..1u32 << 20).map(|i| (i % 253) as u8).collect();
        file.write_all(&garbage).unwrap();
    }
    let store = SqliteStore::open_or_set_aside(&path, None).unwrap();
    assert_eq!(store.usage().unwrap().tiles, 0, "a new store");
    store.quick_check().unwrap();
    let aside: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name.starts_with("tiles.sqlite.damaged-"))
        .collect();
    assert!(!aside.is_empty(), "the damaged file is kept aside");
    // A sound store is opened as it is.
    store.put(&key(1), &tile(vec![1; 100], "v", 1)).unwrap();
    drop(store);
    let store = SqliteStore::open_or_set_aside(&path, None).unwrap();
    assert_eq!(store.usage().unwrap().tiles, 1);
}

#[test]
fn a_version_one_cache_keeps_its_tiles_through_the_migration() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("old.sqlite");
    {
        let connection = Connection::open(&path).unwrap();
        connection.execute_batch(MIGRATIONS[0].1).unwrap();
        connection.pragma_update(None, "user_version", 1).unwrap();
        connection
            .execute(
                "INSERT INTO tiles VALUES (14, 1, 2, 'glb', 'old', x'010203', ?1, 5)",
                [crate::cache::etag_of(&[1, 2, 3])],
            )
            .unwrap();
    }
    let store = SqliteStore::open(&path, None).unwrap();
    let found = store.get(&key(1)).unwrap().unwrap();
    assert_eq!(found.bodies.identity.as_ref(), &[1, 2, 3]);
    assert_eq!(found.made_by.pipeline, "old");
    assert_eq!(store.list(&TileFilter::All).unwrap()[0].accessed_at, 5);
}

#[test]
fn over_its_cap_the_store_evicts_the_least_recently_served() {
    let dir = tempfile::tempdir().unwrap();
    let noise = |seed: u64| noise(seed, 10_000);
    let store = SqliteStore::open(&dir.path().join("t.sqlite"), Some(35_000)).unwrap();
    for x in 0..3 {
        store
            .put(
                &key(x),
                &tile(noise(u64::from(x) + 1), "v", 100 + i64::from(x)),
            )
            .unwrap();
    }
    // Tile 0 was served last; tile 1 is now the least recently served.
    store.touch(&[key(0)], 200).unwrap();
    store.put(&key(3), &tile(noise(9), "v", 150)).unwrap();
    let left: Vec<u32> = store
        .list(&TileFilter::All)
        .unwrap()
        .iter()
        .map(|e| e.key.tile.x)
        .collect();
    assert_eq!(left, vec![0, 3, 2], "most recently served first");
    assert!(store.usage().unwrap().bytes <= 35_000);
}

#[test]
fn removes_by_range_and_by_list() {
    let dir = tempfile::tempdir().unwrap();
    let store = SqliteStore::open(&dir.path().join("t.sqlite"), None).unwrap();
    for x in 0..6 {
        store
            .put(&key(x), &tile(vec![x as u8; 100], "v", 1))
            .unwrap();
    }
    let range = crate::tile::TileRange {
        z: 14,
        min_x: 1,
        max_x: 2,
        min_y: 0,
        max_y: 5,
    };
    assert_eq!(store.remove(&TileFilter::Range(range)).unwrap().len(), 2);
    let listed = TileFilter::Tiles(vec![key(4).tile, key(9).tile]);
    assert_eq!(store.remove(&listed).unwrap(), vec![key(4)]);
    assert_eq!(store.usage().unwrap().tiles, 3);
}

#[test]
fn a_long_list_of_tiles_is_listed_and_removed_whole() {
    let dir = tempfile::tempdir().unwrap();
    let store = SqliteStore::open(&dir.path().join("t.sqlite"), None).unwrap();
    for x in 0..1500 {
        store.put(&key(x), &tile(vec![1; 10], "v", 1)).unwrap();
    }
    let every: Vec<TileId> = (0..1500).map(|x| key(x).tile).collect();
    assert_eq!(
        store.list(&TileFilter::Tiles(every.clone())).unwrap().len(),
        1500
    );
    assert_eq!(store.remove(&TileFilter::Tiles(every)).unwrap().len(), 1500);
    assert_eq!(store.usage().unwrap().tiles, 0);
}

#[test]
fn a_long_list_lets_other_requests_in_between_its_chunks() {
    let dir = tempfile::tempdir().unwrap();
    let store = std::sync::Arc::new(SqliteStore::open(&dir.path().join("t.sqlite"), None).unwrap());
    store.put(&key(1), &tile(vec![1; 10], "v", 1)).unwrap();
    // A list far longer than a chunk, of tiles mostly not stored.
    let long: Vec<TileId> = (0..400_000)
        .map(|i| TileId {
            z: 14,
            x: i % 16_384,
            y: i / 16_384,
        })
        .collect();
    let filter = TileFilter::tiles(long);
    let (started, start) = std::sync::mpsc::channel();
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let listing = {
        let (store, done) = (store.clone(), done.clone());
        std::thread::spawn(move || {
            started.send(()).unwrap();
            let listed = store.list(&filter).unwrap().len();
            done.store(true, std::sync::atomic::Ordering::SeqCst);
            listed
        })
    };
    start.recv().unwrap();
    // Requests one after another while the list is read: each gets the connection between
    // two of the list's turns (a list that kept it would let one through at most).
    let mut served_while_listing = 0;
    while !done.load(std::sync::atomic::Ordering::SeqCst) {
        assert!(store.get(&key(1)).unwrap().is_some());
        if !done.load(std::sync::atomic::Ordering::SeqCst) {
            served_while_listing += 1;
        }
    }
    assert!(
        served_while_listing >= 10,
        "only {served_while_listing} requests got the connection while the list was read"
    );
    assert_eq!(listing.join().unwrap(), 1);
}

#[test]
fn a_tile_made_again_keeps_the_time_it_was_last_served() {
    let dir = tempfile::tempdir().unwrap();
    let store = SqliteStore::open(&dir.path().join("t.sqlite"), None).unwrap();
    store.put(&key(1), &tile(vec![1; 10], "v1", 100)).unwrap();
    store.touch(&[key(1)], 150).unwrap();
    store.put(&key(1), &tile(vec![2; 10], "v2", 900)).unwrap();
    let entry = &store.list(&TileFilter::All).unwrap()[0];
    assert_eq!(entry.accessed_at, 150);
    assert_eq!(entry.made_by.pipeline, "v2");
}

#[test]
fn the_usage_kept_by_triggers_matches_a_count_of_the_rows() {
    let dir = tempfile::tempdir().unwrap();
    let store = SqliteStore::open(&dir.path().join("t.sqlite"), None).unwrap();
    for round in 0..3u8 {
        for x in 0..5 {
            // Replacing a tile with one of another size.
            let data = vec![round; 1000 * (usize::from(round) + 1) + x as usize];
            store.put(&key(x), &tile(data, "v", 1)).unwrap();
        }
    }
    store.remove(&TileFilter::Tiles(vec![key(2).tile])).unwrap();
    let usage = store.usage().unwrap();
    assert_eq!(
        (usage.tiles as i64, usage.bytes as i64),
        usage_scanned(&store)
    );
    assert_eq!(usage.tiles, 4);
}

/// The rows and their sizes, counted.
fn usage_scanned(store: &SqliteStore) -> (i64, i64) {
    store
        .connection()
        .query_row("SELECT count(*), sum(size) FROM tiles", [], |r| {
            Ok((r.get(0)?, r.get(1)?))
        })
        .unwrap()
}
