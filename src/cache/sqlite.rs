//! The SQLite tile store: one file in WAL mode, its schema made by the numbered SQL files in
//! `migrations/` (compiled into the binary, applied in order, tracked by `PRAGMA user_version`),
//! with an optional size cap kept by evicting the least recently served tiles.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use rusqlite::{params, Connection, OptionalExtension};

use super::encoding::Bodies;
use super::store::{
    Provenance, StoreError, StoredEntry, StoredTile, TileFilter, TileReader, TileStore, Usage,
};
use crate::format::Encoding;
use crate::format::{Format, TileKey};
use crate::tile::TileId;

/// The migrations, in order; the schema version is the number of migrations applied.
/// Solved LP components kept at most (a few hundred bytes to a few kilobytes each).
pub(super) const MAX_SOLUTIONS: i64 = 100_000;

const MIGRATIONS: &[(&str, &str)] = &[
    (
        "0001_tiles.sql",
        include_str!("../../migrations/0001_tiles.sql"),
    ),
    (
        "0002_codings_versions_access.sql",
        include_str!("../../migrations/0002_codings_versions_access.sql"),
    ),
    (
        "0003_solutions.sql",
        include_str!("../../migrations/0003_solutions.sql"),
    ),
];

/// Eviction brings the store down to this share of its cap, so it does not run on every put.
pub(super) const EVICT_TO: f64 = 0.9;

/// One SQLite connection behind a lock, with the file it is on for its errors.
pub(super) struct Database {
    path: PathBuf,
    connection: Mutex<Connection>,
}

impl std::fmt::Debug for Database {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Database")
            .field("path", &self.path)
            .finish()
    }
}

impl Database {
    pub(super) fn new(path: &Path, connection: Connection) -> Database {
        Database {
            path: path.to_path_buf(),
            connection: Mutex::new(connection),
        }
    }

    pub(super) fn path(&self) -> &Path {
        &self.path
    }

    pub(super) fn lock(&self) -> std::sync::MutexGuard<'_, Connection> {
        // A panic while holding the lock cannot leave SQLite inconsistent (each statement is
        // atomic), so a poisoned lock is still usable.
        self.connection.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// A SQLite error, naming the file.
    pub(super) fn error(&self, source: rusqlite::Error) -> StoreError {
        StoreError::Sqlite {
            path: self.path.clone(),
            source,
        }
    }
}

#[derive(Debug)]
pub struct SqliteStore {
    db: Database,
    /// Largest total of stored bytes, if capped.
    max_bytes: Option<u64>,
    /// Largest tile, uncompressed, a row may give.
    max_tile: u64,
}

impl SqliteStore {
    /// Opens (creating if needed) the store at `path` and brings its schema up to date.
    /// `max_bytes` caps the stored bytes (`None`: no cap).
    pub fn open(path: &Path, max_bytes: Option<u64>) -> Result<SqliteStore, StoreError> {
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(|source| StoreError::Directory {
                path: path.to_path_buf(),
                source,
            })?;
        }
        let sqlite = |source| StoreError::Sqlite {
            path: path.to_path_buf(),
            source,
        };
        let mut connection = Connection::open(path).map_err(sqlite)?;
        connection
            .pragma_update(None, "journal_mode", "WAL")
            .map_err(sqlite)?;
        connection
            .pragma_update(None, "synchronous", "NORMAL")
            .map_err(sqlite)?;
        connection
            .busy_timeout(std::time::Duration::from_secs(5))
            .map_err(sqlite)?;
        let version: i64 = connection
            .pragma_query_value(None, "user_version", |row| row.get(0))
            .map_err(sqlite)?;
        if version > MIGRATIONS.len() as i64 {
            return Err(StoreError::NewerSchema {
                path: path.to_path_buf(),
                found: version,
                supported: MIGRATIONS.len(),
            });
        }
        for (number, (_, sql)) in MIGRATIONS.iter().enumerate().skip(version.max(0) as usize) {
            let transaction = connection.transaction().map_err(sqlite)?;
            transaction.execute_batch(sql).map_err(sqlite)?;
            transaction
                .pragma_update(None, "user_version", (number + 1) as i64)
                .map_err(sqlite)?;
            transaction.commit().map_err(sqlite)?;
        }
        Ok(SqliteStore {
            db: Database::new(path, connection),
            max_bytes,
            max_tile: super::store::DEFAULT_MAX_TILE_BYTES,
        })
    }

    /// The store with `bytes` as the largest tile, uncompressed, a row may give: a row that
    /// would inflate past it is damaged.
    pub fn with_max_tile(mut self, bytes: u64) -> SqliteStore {
        self.max_tile = bytes;
        self
    }

    pub fn path(&self) -> &Path {
        self.db.path()
    }

    fn connection(&self) -> std::sync::MutexGuard<'_, Connection> {
        self.db.lock()
    }

    fn error(&self, source: rusqlite::Error) -> StoreError {
        self.db.error(source)
    }

    /// Opens the store at `path` as [`SqliteStore::open`] does, after a quick check of the
    /// file; a damaged file is moved aside (`PATH.damaged-UNIXTIME`, logged) and a new store
    /// started in its place: its tiles are made again as they are asked for.
    pub fn open_or_set_aside(
        path: &Path,
        max_bytes: Option<u64>,
    ) -> Result<SqliteStore, StoreError> {
        let opened = SqliteStore::open(path, max_bytes).and_then(|store| {
            store.quick_check()?;
            Ok(store)
        });
        match opened {
            Err(error) if error.is_damage() => {
                let aside = with_suffix(path, &format!(".damaged-{}", crate::cache::unix_now()));
                tracing::error!(cache = %path.display(), moved_to = %aside.display(), %error, "the tile cache is damaged; it is moved aside and a new one started");
                std::fs::rename(path, &aside).map_err(|source| StoreError::Directory {
                    path: path.to_path_buf(),
                    source,
                })?;
                for suffix in ["-wal", "-shm"] {
                    let _ = std::fs::rename(with_suffix(path, suffix), with_suffix(&aside, suffix));
                }
                SqliteStore::open(path, max_bytes)
            }
            other => other,
        }
    }

    /// `PRAGMA quick_check`: the file's pages and records are sound (indexes not compared).
    pub fn quick_check(&self) -> Result<(), StoreError> {
        self.pragma_check("quick_check")
    }

    /// `PRAGMA integrity_check`: an error naming the damage if the file is not sound.
    pub fn check_integrity(&self) -> Result<(), StoreError> {
        self.pragma_check("integrity_check")
    }

    fn pragma_check(&self, pragma: &str) -> Result<(), StoreError> {
        let connection = self.connection();
        let mut statement = connection
            .prepare(&format!("PRAGMA {pragma}"))
            .map_err(|e| self.error(e))?;
        let lines: Vec<String> = statement
            .query_map([], |row| row.get(0))
            .map_err(|e| self.error(e))?
            .collect::<Result<_, _>>()
            .map_err(|e| self.error(e))?;
        if lines == ["ok"] {
            Ok(())
        } else {
            Err(StoreError::Damaged {
                path: self.db.path().to_path_buf(),
                report: lines.join("; "),
            })
        }
    }

    /// Stores a tile in one step, replacing the one before where `only` (a `WHERE` on the row
    /// held, or nothing) allows; says whether it was written.
    fn upsert(&self, key: &TileKey, tile: &StoredTile, only: &str) -> Result<bool, StoreError> {
        let (coding, primary) = tile.bodies.primary();
        let mut connection = self.connection();
        let transaction = connection.transaction().map_err(|e| self.error(e))?;
        // An upsert, not a replace: the usage triggers see one update, not a delete and an
        // insert. A tile made again keeps the time it was last served.
        let written = transaction
            .execute(
                &format!(
                    "INSERT INTO tiles
                       (z, x, y, format, pipeline, data, etag, created_at,
                        encoding, data_br, sources, size, accessed_at)
                     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?8)
                     ON CONFLICT (z, x, y, format) DO UPDATE SET
                       pipeline = excluded.pipeline, data = excluded.data, etag = excluded.etag,
                       created_at = excluded.created_at, encoding = excluded.encoding,
                       data_br = excluded.data_br, sources = excluded.sources,
                       size = excluded.size
                     {only}"
                ),
                params![
                    key.tile.z,
                    key.tile.x,
                    key.tile.y,
                    key.format.as_str(),
                    tile.made_by.pipeline,
                    primary.as_ref(),
                    tile.etag,
                    tile.created_at,
                    coding.as_str(),
                    tile.bodies.brotli.as_deref(),
                    tile.made_by.sources,
                    stored_bytes(key, tile) as i64,
                ],
            )
            .map_err(|e| self.error(e))?;
        let evicted = match written {
            0 => 0,
            _ => self.evict(&transaction, key).map_err(|e| self.error(e))?,
        };
        transaction.commit().map_err(|e| self.error(e))?;
        super::store::log_eviction(evicted, self.max_bytes);
        Ok(written > 0)
    }

    /// Deletes the least recently served tiles (never `keep`) until the store is under
    /// [`EVICT_TO`] of its cap; returns how many went.
    fn evict(&self, connection: &Connection, keep: &TileKey) -> Result<u64, rusqlite::Error> {
        let Some(cap) = self.max_bytes else {
            return Ok(0);
        };
        let mut total: u64 = connection.query_row("SELECT bytes FROM usage", [], |row| {
            row.get::<_, i64>(0).map(|t| t.max(0) as u64)
        })?;
        if total <= cap {
            return Ok(0);
        }
        let target = (cap as f64 * EVICT_TO) as u64;
        let mut evicted = 0;
        let mut oldest = connection
            .prepare("SELECT z, x, y, format, size FROM tiles ORDER BY accessed_at ASC")?;
        let mut rows = oldest.query([])?;
        let mut doomed = Vec::new();
        while total > target {
            let Some(row) = rows.next()? else { break };
            let (z, x, y, format, size): (u8, u32, u32, String, u64) = (
                row.get(0)?,
                row.get(1)?,
                row.get(2)?,
                row.get(3)?,
                row.get(4)?,
            );
            let same = (z, x, y) == (keep.tile.z, keep.tile.x, keep.tile.y)
                && format == keep.format.as_str();
            if same {
                continue;
            }
            doomed.push((z, x, y, format));
            total = total.saturating_sub(size);
        }
        drop(rows);
        for (z, x, y, format) in doomed {
            evicted += connection.execute(
                "DELETE FROM tiles WHERE z = ?1 AND x = ?2 AND y = ?3 AND format = ?4",
                params![z, x, y, format],
            )? as u64;
        }
        Ok(evicted)
    }
}

/// Bytes a row takes in the file besides its columns' contents (record header, the key's
/// integers and the primary key's index entry), near enough.
const ROW_OVERHEAD: usize = 64;

/// The bytes a stored tile counts against the cap: its bodies, its text columns and the row's
/// overhead, so that many small tiles fill the cap as the file grows.
pub(super) fn stored_bytes(key: &TileKey, tile: &StoredTile) -> usize {
    tile.bodies.stored_len()
        + tile.etag.len()
        + tile.made_by.pipeline.len()
        + tile.made_by.sources.len()
        + key.format.as_str().len()
        + ROW_OVERHEAD
}

/// Tiles of a list read or removed while the connection is held once.
const TILES_PER_TURN: usize = 1_000;

/// Between two turns of a long list: the connection's lock is not fair (whoever let it go
/// takes it again first), so the list's thread steps aside a moment for those waiting.
fn let_others_in() {
    std::thread::sleep(std::time::Duration::from_micros(200));
}

/// The SQL condition, with its parameters, that selects a box's or all tiles (a list of tiles
/// is read by the primary key, one at a time).
fn filter_sql(filter: &TileFilter) -> Vec<(String, Vec<i64>)> {
    match filter {
        TileFilter::All => vec![("1".to_string(), Vec::new())],
        TileFilter::Range(range) => vec![(
            "z = ? AND x BETWEEN ? AND ? AND y BETWEEN ? AND ?".to_string(),
            vec![
                i64::from(range.z),
                i64::from(range.min_x),
                i64::from(range.max_x),
                i64::from(range.min_y),
                i64::from(range.max_y),
            ],
        )],
        TileFilter::Tiles(_) => Vec::new(),
    }
}

/// The tile of a row whose first three columns are `z`, `x`, `y`.
fn tile_of(row: &rusqlite::Row<'_>) -> rusqlite::Result<TileId> {
    Ok(TileId {
        z: row.get(0)?,
        x: row.get(1)?,
        y: row.get(2)?,
    })
}

impl TileReader for SqliteStore {
    fn get(&self, key: &TileKey) -> Result<Option<StoredTile>, StoreError> {
        type Row = (
            Vec<u8>,
            String,
            Option<Vec<u8>>,
            String,
            String,
            String,
            i64,
        );
        let row: Result<Option<Row>, StoreError> = self
            .connection()
            .query_row(
                "SELECT data, encoding, data_br, etag, pipeline, sources, created_at FROM tiles
                 WHERE z = ?1 AND x = ?2 AND y = ?3 AND format = ?4",
                params![key.tile.z, key.tile.x, key.tile.y, key.format.as_str()],
                |row| {
                    Ok((
                        row.get(0)?,
                        row.get(1)?,
                        row.get(2)?,
                        row.get(3)?,
                        row.get(4)?,
                        row.get(5)?,
                        row.get(6)?,
                    ))
                },
            )
            .optional()
            .map_err(|e| self.error(e));
        let row = match row {
            Err(error) if error.is_damage() => {
                // The row (or the page it is on) is damaged: drop what can be dropped; the tile
                // is made again.
                tracing::error!(tile = %key.tile, format = key.format.as_str(), %error, "a damaged cached tile could not be read; it is dropped and made again");
                let _ = self.connection().execute(
                    "DELETE FROM tiles WHERE z = ?1 AND x = ?2 AND y = ?3 AND format = ?4",
                    params![key.tile.z, key.tile.x, key.tile.y, key.format.as_str()],
                );
                return Ok(None);
            }
            other => other?,
        };
        let Some((data, encoding, brotli, etag, pipeline, sources, created_at)) = row else {
            return Ok(None);
        };
        let coding = Encoding::from_name(&encoding).unwrap_or(Encoding::Identity);
        let bodies = match Bodies::from_stored(data, coding, brotli, self.max_tile)
            .and_then(|bodies| bodies.verify(&etag).map(|()| bodies))
        {
            Ok(bodies) => bodies,
            Err(error) => {
                // A damaged row is dropped and made again rather than served.
                tracing::warn!(tile = %key.tile, format = key.format.as_str(), %error, "dropping a damaged cached tile");
                self.connection()
                    .execute(
                        "DELETE FROM tiles WHERE z = ?1 AND x = ?2 AND y = ?3 AND format = ?4",
                        params![key.tile.z, key.tile.x, key.tile.y, key.format.as_str()],
                    )
                    .map_err(|e| self.error(e))?;
                return Ok(None);
            }
        };
        Ok(Some(StoredTile {
            bodies,
            etag,
            made_by: Provenance { pipeline, sources },
            created_at,
        }))
    }

    fn solutions(&self, limit: usize) -> Result<Vec<super::store::SolutionEntry>, StoreError> {
        let connection = self.connection();
        let mut newest = connection
            .prepare("SELECT key, data FROM solutions ORDER BY rowid DESC LIMIT ?1")
            .map_err(|e| self.error(e))?;
        let rows = newest
            .query_map([i64::try_from(limit).unwrap_or(i64::MAX)], |row| {
                Ok((row.get::<_, Vec<u8>>(0)?, row.get::<_, Vec<u8>>(1)?))
            })
            .map_err(|e| self.error(e))?;
        let mut out = Vec::new();
        for row in rows {
            let (key, data) = row.map_err(|e| self.error(e))?;
            // A key of another length is not one of ours: skipped.
            if let Ok(key) = <[u8; 32]>::try_from(key.as_slice()) {
                out.push((key, data));
            }
        }
        Ok(out)
    }

    fn list(&self, filter: &TileFilter) -> Result<Vec<StoredEntry>, StoreError> {
        const COLUMNS: &str = "z, x, y, format, pipeline, sources, size, accessed_at";
        let mut entries = Vec::new();
        let mut read = |statement: &mut rusqlite::Statement<'_>, values: &[i64]| {
            let rows = statement
                .query_map(rusqlite::params_from_iter(values), |row| {
                    Ok((
                        tile_of(row)?,
                        row.get::<_, String>(3)?,
                        Provenance {
                            pipeline: row.get(4)?,
                            sources: row.get(5)?,
                        },
                        row.get::<_, i64>(6)?,
                        row.get::<_, i64>(7)?,
                    ))
                })
                .map_err(|e| self.error(e))?;
            for row in rows {
                let (tile, format, made_by, size, accessed_at) = row.map_err(|e| self.error(e))?;
                // Rows of a format this program does not know are left alone.
                if let Some(format) = Format::from_name(&format) {
                    entries.push(StoredEntry {
                        key: TileKey { tile, format },
                        made_by,
                        size: size.max(0) as u64,
                        accessed_at,
                    });
                }
            }
            Ok::<_, StoreError>(())
        };
        match filter {
            // A list of tiles is read by the primary key, a chunk at a time, the connection
            // let go between chunks so that other requests get in.
            TileFilter::Tiles(tiles) => {
                for chunk in tiles.chunks(TILES_PER_TURN) {
                    let_others_in();
                    let connection = self.connection();
                    let mut statement = connection
                        .prepare_cached(&format!(
                            "SELECT {COLUMNS} FROM tiles WHERE z = ?1 AND x = ?2 AND y = ?3"
                        ))
                        .map_err(|e| self.error(e))?;
                    for t in chunk {
                        read(
                            &mut statement,
                            &[i64::from(t.z), i64::from(t.x), i64::from(t.y)],
                        )?;
                    }
                }
            }
            other => {
                let connection = self.connection();
                for (condition, values) in filter_sql(other) {
                    let mut statement = connection
                        .prepare(&format!("SELECT {COLUMNS} FROM tiles WHERE {condition}"))
                        .map_err(|e| self.error(e))?;
                    read(&mut statement, &values)?;
                }
            }
        }
        // Most recently served first.
        entries.sort_by(|a, b| b.accessed_at.cmp(&a.accessed_at).then(a.key.cmp(&b.key)));
        Ok(entries)
    }

    fn usage(&self) -> Result<Usage, StoreError> {
        self.connection()
            .query_row("SELECT tiles, bytes FROM usage", [], |row| {
                Ok(Usage {
                    tiles: row.get::<_, i64>(0)?.max(0) as u64,
                    bytes: row.get::<_, i64>(1)?.max(0) as u64,
                })
            })
            .map_err(|e| self.error(e))
    }
}

impl TileStore for SqliteStore {
    fn put(&self, key: &TileKey, tile: &StoredTile) -> Result<(), StoreError> {
        self.upsert(key, tile, "").map(|_| ())
    }

    fn put_if_vacant(&self, key: &TileKey, tile: &StoredTile) -> Result<bool, StoreError> {
        self.upsert(key, tile, "WHERE tiles.etag = excluded.etag")
    }

    fn keep_solutions(&self, entries: &[super::store::SolutionEntry]) -> Result<(), StoreError> {
        if entries.is_empty() {
            return Ok(());
        }
        let mut connection = self.connection();
        let transaction = connection.transaction().map_err(|e| self.error(e))?;
        {
            let mut insert = transaction
                .prepare_cached("INSERT OR IGNORE INTO solutions (key, data) VALUES (?1, ?2)")
                .map_err(|e| self.error(e))?;
            for (key, data) in entries {
                insert
                    .execute(params![key.as_slice(), data])
                    .map_err(|e| self.error(e))?;
            }
        }
        transaction
            .execute(
                "DELETE FROM solutions WHERE rowid <= (SELECT MAX(rowid) FROM solutions) - ?1",
                [MAX_SOLUTIONS],
            )
            .map_err(|e| self.error(e))?;
        transaction.commit().map_err(|e| self.error(e))
    }

    fn touch(&self, keys: &[TileKey], at: i64) -> Result<(), StoreError> {
        let mut connection = self.connection();
        let transaction = connection.transaction().map_err(|e| self.error(e))?;
        {
            let mut statement = transaction
                .prepare_cached(
                    "UPDATE tiles SET accessed_at = max(accessed_at, ?5)
                     WHERE z = ?1 AND x = ?2 AND y = ?3 AND format = ?4",
                )
                .map_err(|e| self.error(e))?;
            for key in keys {
                statement
                    .execute(params![
                        key.tile.z,
                        key.tile.x,
                        key.tile.y,
                        key.format.as_str(),
                        at
                    ])
                    .map_err(|e| self.error(e))?;
            }
        }
        transaction.commit().map_err(|e| self.error(e))
    }

    fn remove(&self, filter: &TileFilter) -> Result<Vec<TileKey>, StoreError> {
        let mut removed = Vec::new();
        let delete = |transaction: &rusqlite::Transaction<'_>,
                      condition: &str,
                      values: &[i64],
                      removed: &mut Vec<TileKey>| {
            let mut statement = transaction
                .prepare_cached(&format!(
                    "DELETE FROM tiles WHERE {condition} RETURNING z, x, y, format"
                ))
                .map_err(|e| self.error(e))?;
            let rows = statement
                .query_map(rusqlite::params_from_iter(values), |row| {
                    Ok((tile_of(row)?, row.get::<_, String>(3)?))
                })
                .map_err(|e| self.error(e))?;
            for row in rows {
                let (tile, format) = row.map_err(|e| self.error(e))?;
                if let Some(format) = Format::from_name(&format) {
                    removed.push(TileKey { tile, format });
                }
            }
            Ok::<_, StoreError>(())
        };
        match filter {
            // A list of tiles goes a chunk at a time, each chunk a transaction of its own, the
            // connection let go between chunks so that other requests get in.
            TileFilter::Tiles(tiles) => {
                for chunk in tiles.chunks(TILES_PER_TURN) {
                    let_others_in();
                    let mut connection = self.connection();
                    let transaction = connection.transaction().map_err(|e| self.error(e))?;
                    for t in chunk {
                        let values = [i64::from(t.z), i64::from(t.x), i64::from(t.y)];
                        delete(
                            &transaction,
                            "z = ?1 AND x = ?2 AND y = ?3",
                            &values,
                            &mut removed,
                        )?;
                    }
                    transaction.commit().map_err(|e| self.error(e))?;
                }
            }
            other => {
                let mut connection = self.connection();
                let transaction = connection.transaction().map_err(|e| self.error(e))?;
                for (condition, values) in filter_sql(other) {
                    delete(&transaction, &condition, &values, &mut removed)?;
                }
                transaction.commit().map_err(|e| self.error(e))?;
            }
        }
        removed.sort();
        Ok(removed)
    }
}

/// `path` with `suffix` appended to its file name.
fn with_suffix(path: &Path, suffix: &str) -> std::path::PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(suffix);
    std::path::PathBuf::from(name)
}

#[cfg(test)]
mod tests {
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
            bodies: Bodies::quick(data.clone(), &crate::cache::encoding::Accepted::default())
                .unwrap(),
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
        let store =
            std::sync::Arc::new(SqliteStore::open(&dir.path().join("t.sqlite"), None).unwrap());
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
}
