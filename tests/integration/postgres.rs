//! The tile cache in PostgreSQL (`cache.url`), on a real server: a throwaway cluster started
//! in a temporary directory for these tests (see `common/pg_cluster.rs`): what the SQLite store
//! does, and two stores on one database seeing each other's tiles.

use crate::common;

use common::pg_cluster::Cluster;
use terrastitch::cache::encoding::{Accepted, Bodies};
use terrastitch::cache::{
    etag_of, PostgresStore, Provenance, StoredTile, TileFilter, TileReader, TileStore,
};
use terrastitch::format::{Format, TileKey};
use terrastitch::tile::{TileId, TileRange};

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
        etag: etag_of(&data),
        bodies: Bodies::compress(data).expect("compressed"),
        made_by: Provenance {
            pipeline: pipeline.to_string(),
            sources: "s1".to_string(),
        },
        created_at: at,
    }
}

#[test]
fn a_tile_one_process_stores_is_read_by_another_with_its_codings_and_provenance() {
    let cluster = Cluster::start();
    let url = cluster.database("shared");
    let (one, two) = (
        PostgresStore::open(&url, None).expect("first replica"),
        PostgresStore::open(&url, None).expect("second replica, schema already there"),
    );
    let stored = tile(vec![7; 10_000], "v1", 1_000);
    one.put(&key(1), &stored).expect("stored");
    let found = two.get(&key(1)).expect("read").expect("found");
    assert_eq!(found, stored);
    assert!(found.bodies.gzip.is_some(), "stored compressed");
    assert_eq!(two.get(&key(2)).expect("read"), None);
    // Made again by the other: replaced, one row.
    let again = tile(noise(3, 5_000), "v2", 2_000);
    two.put(&key(1), &again).expect("replaced");
    assert_eq!(one.get(&key(1)).expect("read"), Some(again.clone()));
    let usage = one.usage().expect("usage");
    assert_eq!(usage.tiles, 1);
    assert!(usage.bytes > again.bodies.stored_len() as u64, "{usage:?}");
}

#[test]
fn a_tile_put_if_vacant_replaces_only_its_own_forms() {
    let cluster = Cluster::start();
    let store = PostgresStore::open(&cluster.database("vacant"), None).expect("store");
    let data = vec![7; 10_000];
    let quick = StoredTile {
        bodies: Bodies::quick(data.clone(), &Accepted::default()).expect("identity"),
        ..tile(data.clone(), "v1", 5)
    };
    assert!(
        store.put_if_vacant(&key(1), &quick).expect("put"),
        "none held"
    );
    let kept = tile(data, "v1", 6);
    assert!(
        store.put_if_vacant(&key(1), &kept).expect("put"),
        "the same content in other forms"
    );
    let found = store.get(&key(1)).expect("read").expect("found");
    assert_eq!(found.bodies, kept.bodies);
    let other = tile(noise(8, 5_000), "v2", 7);
    assert!(
        !store.put_if_vacant(&key(1), &other).expect("put"),
        "another tile is held"
    );
    assert_eq!(store.get(&key(1)).expect("read"), Some(found));
    assert_eq!(store.usage().expect("usage").tiles, 1);
}

#[test]
fn processes_opening_a_new_database_at_once_migrate_it_once() {
    let cluster = Cluster::start();
    let url = cluster.database("fresh");
    let opened: Vec<bool> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..6)
            .map(|_| scope.spawn(|| PostgresStore::open(&url, None).is_ok()))
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or(false))
            .collect()
    });
    assert!(opened.iter().all(|&ok| ok), "{opened:?}");
    let mut client = postgres::Client::connect(&url, postgres::NoTls).expect("connect");
    let version: i64 = client
        .query_one("SELECT version FROM terrastitch_schema", &[])
        .expect("the schema's version")
        .get(0);
    let migrations = std::fs::read_dir(common::repo().join("migrations/postgres"))
        .expect("the migrations")
        .count();
    assert_eq!(version, migrations as i64, "every migration applied once");
}

#[test]
fn over_its_cap_the_store_evicts_the_least_recently_served() {
    let cluster = Cluster::start();
    let url = cluster.database("capped");
    let store = PostgresStore::open(&url, Some(100_000)).expect("opened");
    for x in 0..8u32 {
        store
            .put(
                &key(x),
                &tile(noise(u64::from(x) + 1, 20_000), "v1", 100 + i64::from(x)),
            )
            .expect("stored");
        // Tile 0 is served again and again: it stays.
        store
            .touch(&[key(0)], 1_000 + i64::from(x))
            .expect("touched");
    }
    let usage = store.usage().expect("usage");
    assert!(usage.bytes <= 100_000, "{usage:?}");
    assert!(
        store.get(&key(0)).expect("read").is_some(),
        "the tile served last stays"
    );
    assert!(
        store.get(&key(7)).expect("read").is_some(),
        "the tile just made stays"
    );
    assert!(
        store.get(&key(1)).expect("read").is_none(),
        "the oldest went"
    );
    let listed = store.list(&TileFilter::All).expect("listed");
    assert_eq!(listed.len() as u64, usage.tiles);
    assert_eq!(listed[0].key, key(0), "most recently served first");
}

#[test]
fn removes_by_range_and_by_list_and_names_what_went() {
    let cluster = Cluster::start();
    let store = PostgresStore::open(&cluster.database("removing"), None).expect("opened");
    for x in 0..10u32 {
        store
            .put(&key(x), &tile(vec![x as u8; 100], "v1", 1))
            .expect("stored");
    }
    let range = TileRange {
        z: 14,
        min_x: 2,
        max_x: 4,
        min_y: 0,
        max_y: 9,
    };
    let mut gone = store.remove(&TileFilter::Range(range)).expect("removed");
    gone.sort_by_key(|k| k.tile.x);
    assert_eq!(gone, vec![key(2), key(3), key(4)]);
    let listed = TileFilter::tiles(vec![key(7).tile, key(3).tile, key(8).tile]);
    assert_eq!(store.list(&listed).expect("listed").len(), 2);
    let mut gone = store.remove(&listed).expect("removed");
    gone.sort_by_key(|k| k.tile.x);
    assert_eq!(gone, vec![key(7), key(8)]);
    assert_eq!(store.usage().expect("usage").tiles, 5);
}

#[test]
fn a_stored_coding_that_does_not_match_its_digest_is_dropped_not_served() {
    let cluster = Cluster::start();
    let url = cluster.database("damaged");
    let store = PostgresStore::open(&url, None).expect("opened");
    store
        .put(&key(1), &tile(noise(9, 4_000), "v1", 1))
        .expect("stored");
    let mut client = postgres::Client::connect(&url, postgres::NoTls).expect("connect");
    client
        .execute(
            "UPDATE tiles SET data = overlay(data placing '\\x0102030405060708'::bytea from 100)",
            &[],
        )
        .expect("damaged");
    assert_eq!(store.get(&key(1)).expect("read"), None);
    assert_eq!(
        store.usage().expect("usage").tiles,
        0,
        "the damaged row is gone"
    );
}

#[test]
fn solved_components_are_kept_once_and_read_newest_first() {
    let cluster = Cluster::start();
    let store = PostgresStore::open(&cluster.database("solutions"), None).expect("opened");
    store
        .keep_solutions(&[([1; 32], vec![1, 2]), ([2; 32], vec![3])])
        .expect("kept");
    store
        .keep_solutions(&[([1; 32], vec![9])])
        .expect("kept again");
    let kept = store.solutions(10).expect("read");
    assert_eq!(kept, vec![([2; 32], vec![3]), ([1; 32], vec![1, 2])]);
}
