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
mod tests;
