//! An MBTiles file (as `terrastitch export` writes it) as a read-only tile store, so a server
//! without any source data can serve an exported area: `terrastitch serve --archive FILE`.
//!
//! A tile enters memory compressed once, like a rendered one; the file is never written.
//!
//! The file is not trusted: it is opened read-only, its `tiles` must be a table or view with
//! the MBTiles columns that answers a first lookup in time, every statement on it is stopped
//! past [`QUERY_LIMIT`] (SQLite's progress handler: a `tiles` view that never ends cannot hold a
//! thread, nor a server that is stopping), and a tile longer than the largest a tile may be is
//! damaged before it is read.

use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use rusqlite::{params, Connection, OpenFlags, OptionalExtension};

use super::{
    archived_tile, format_named, metadata, ArchiveStore, Contents, TileBodies, WriteError,
    CONTENTS_KEY,
};
use crate::cache::sqlite::Database;
use crate::cache::store::{
    Provenance, StoreError, StoredEntry, StoredTile, TileFilter, TileReader, Usage,
};
use crate::format::TileKey;
use crate::tile::{LonLatBounds, TileId};

/// Longest a statement on the file may run. A lookup takes microseconds and a list of a
/// country's million tiles about a second.
const QUERY_LIMIT: Duration = Duration::from_secs(10);
/// SQLite virtual-machine steps between two looks at the clock.
const STEPS_PER_CHECK: i32 = 10_000;

/// The columns an MBTiles `tiles` table has.
const TILE_COLUMNS: [&str; 4] = ["zoom_level", "tile_column", "tile_row", "tile_data"];

#[derive(Debug)]
pub struct MbtilesStore {
    db: Database,
    contents: Contents,
    /// When the running statement must stop: milliseconds after `epoch`.
    stop_at: Arc<AtomicU64>,
    epoch: Instant,
    /// Largest tile it may give.
    max_tile: u64,
}

impl MbtilesStore {
    /// Opens the file read-only and reads its metadata; a file without the MBTiles tables
    /// (or whose `tiles` does not answer in time), or of a format other than glb or terrain, is
    /// an error naming it. A tile longer than `max_tile` bytes is damaged.
    pub fn open(path: &Path, max_tile: u64) -> Result<MbtilesStore, StoreError> {
        let sqlite = |source| StoreError::Sqlite {
            path: path.to_path_buf(),
            source,
        };
        let connection =
            Connection::open_with_flags(path, OpenFlags::SQLITE_OPEN_READ_ONLY).map_err(sqlite)?;
        let epoch = Instant::now();
        let stop_at = Arc::new(AtomicU64::new(limit_from(epoch)));
        let watched = stop_at.clone();
        connection.progress_handler(
            STEPS_PER_CHECK,
            Some(move || millis_since(epoch) > watched.load(Ordering::Relaxed)),
        );
        let damaged = |report: String| StoreError::Damaged {
            path: path.to_path_buf(),
            report,
        };
        check_tiles_table(&connection).map_err(damaged)?;
        let meta = |name: &str| -> Result<Option<String>, StoreError> {
            connection
                .query_row(
                    "SELECT value FROM metadata WHERE name = ?1",
                    [name],
                    |row| row.get(0),
                )
                .optional()
                .map_err(sqlite)
        };
        let named = meta("format")?;
        let format =
            named
                .as_deref()
                .and_then(format_named)
                .ok_or_else(|| StoreError::Damaged {
                    path: path.to_path_buf(),
                    report: format!("its format is {named:?}, not a glb variant or terrain"),
                })?;
        let bounds = meta("bounds")?.and_then(|b| b.parse::<LonLatBounds>().ok());
        let zoom = |name: &str| -> Result<Option<u8>, StoreError> {
            Ok(meta(name)?.and_then(|z| z.trim().parse::<u8>().ok()))
        };
        let max = zoom("maxzoom")?.unwrap_or(14);
        let min = zoom("minzoom")?.unwrap_or(max);
        let entry = meta(CONTENTS_KEY)?.and_then(|text| serde_json::from_str(&text).ok());
        let contents = Contents::read(format, bounds, (min, max), entry.as_ref());
        Ok(MbtilesStore {
            db: Database::new(path, connection),
            contents,
            stop_at,
            epoch,
            max_tile,
        })
    }

    /// The connection, its next statement given [`QUERY_LIMIT`] from now.
    fn connection(&self) -> std::sync::MutexGuard<'_, Connection> {
        let connection = self.db.lock();
        self.stop_at
            .store(limit_from(self.epoch), Ordering::Relaxed);
        connection
    }

    fn error(&self, source: rusqlite::Error) -> StoreError {
        if source.sqlite_error_code() == Some(rusqlite::ErrorCode::OperationInterrupted) {
            return StoreError::Damaged {
                path: self.db.path().to_path_buf(),
                report: format!(
                    "a query on it ran past {} s and was stopped",
                    QUERY_LIMIT.as_secs()
                ),
            };
        }
        self.db.error(source)
    }

    /// What every tile of the file was made from, as far as a server that only reads it knows.
    pub fn provenance(&self) -> Provenance {
        Provenance {
            pipeline: "mbtiles".to_string(),
            sources: self.db.path().display().to_string(),
        }
    }
}

fn millis_since(epoch: Instant) -> u64 {
    u64::try_from(epoch.elapsed().as_millis()).unwrap_or(u64::MAX)
}

/// [`QUERY_LIMIT`] from now, in milliseconds after `epoch`.
fn limit_from(epoch: Instant) -> u64 {
    millis_since(epoch).saturating_add(QUERY_LIMIT.as_millis() as u64)
}

/// `tiles` is a table or a view with the MBTiles columns, and a lookup in it answers (within
/// the connection's limit), and `metadata` is there.
fn check_tiles_table(connection: &Connection) -> Result<(), String> {
    let kind: Option<String> = connection
        .query_row(
            "SELECT type FROM sqlite_master WHERE name = 'tiles'",
            [],
            |row| row.get(0),
        )
        .optional()
        .map_err(|e| format!("its schema cannot be read: {e}"))?;
    match kind.as_deref() {
        Some("table" | "view") => {}
        Some(other) => return Err(format!("its tiles is a {other}, not a table")),
        None => return Err("it has no tiles table".to_string()),
    }
    let columns: Vec<String> = connection
        .prepare("SELECT name FROM pragma_table_info('tiles')")
        .and_then(|mut s| s.query_map([], |row| row.get(0))?.collect())
        .map_err(|e| format!("its tiles table cannot be read: {e}"))?;
    if let Some(missing) = TILE_COLUMNS
        .iter()
        .find(|c| !columns.iter().any(|n| n == *c))
    {
        return Err(format!("its tiles table has no {missing} column"));
    }
    connection
        .query_row(
            "SELECT count(*) FROM sqlite_master WHERE name = 'metadata'",
            [],
            |row| row.get::<_, i64>(0),
        )
        .ok()
        .filter(|&n| n > 0)
        .ok_or("it has no metadata table")?;
    connection
        .query_row(
            "SELECT length(tile_data) FROM tiles
             WHERE zoom_level = 0 AND tile_column = 0 AND tile_row = 0",
            [],
            |_| Ok(()),
        )
        .optional()
        .map_err(|e| format!("a lookup in its tiles failed: {e}"))?;
    Ok(())
}

/// MBTiles rows count from the south.
fn tms_row(tile: TileId) -> i64 {
    (1i64 << tile.z) - 1 - i64::from(tile.y)
}

impl ArchiveStore for MbtilesStore {
    fn contents(&self) -> &Contents {
        &self.contents
    }

    fn path(&self) -> &Path {
        self.db.path()
    }
}

impl TileReader for MbtilesStore {
    fn get(&self, key: &TileKey) -> Result<Option<StoredTile>, StoreError> {
        if key.format != self.contents.format {
            return Ok(None);
        }
        // The blob is read only when it is no longer than a tile may be.
        let row: Option<(Option<Vec<u8>>, Option<i64>)> = self
            .connection()
            .query_row(
                "SELECT CASE WHEN length(tile_data) <= ?4 THEN tile_data END, length(tile_data)
                 FROM tiles WHERE zoom_level = ?1 AND tile_column = ?2 AND tile_row = ?3",
                rusqlite::params![
                    key.tile.z,
                    key.tile.x,
                    tms_row(key.tile),
                    i64::try_from(self.max_tile).unwrap_or(i64::MAX)
                ],
                |row| Ok((row.get(0)?, row.get(1)?)),
            )
            .optional()
            .map_err(|e| self.error(e))?;
        match row {
            None => Ok(None),
            Some((Some(data), _)) => archived_tile(data, self.provenance()).map(Some),
            Some((None, length)) => Err(StoreError::Damaged {
                path: self.db.path().to_path_buf(),
                report: match length {
                    Some(length) => format!(
                        "tile {} holds {length} bytes, more than the {} a tile may hold",
                        key.tile, self.max_tile
                    ),
                    None => format!("tile {} has no data", key.tile),
                },
            }),
        }
    }

    fn list(&self, filter: &TileFilter) -> Result<Vec<StoredEntry>, StoreError> {
        let connection = self.connection();
        let mut statement = connection
            .prepare("SELECT zoom_level, tile_column, tile_row, length(tile_data) FROM tiles")
            .map_err(|e| self.error(e))?;
        let rows = statement
            .query_map([], |row| {
                Ok((
                    row.get::<_, u8>(0)?,
                    row.get::<_, u32>(1)?,
                    row.get::<_, i64>(2)?,
                    row.get::<_, i64>(3)?,
                ))
            })
            .map_err(|e| self.error(e))?;
        let mut entries = Vec::new();
        for row in rows {
            let (z, x, row, size) = row.map_err(|e| self.error(e))?;
            if z > crate::tile::MAX_ZOOM {
                continue;
            }
            let Ok(y) = u32::try_from((1i64 << z) - 1 - row) else {
                continue;
            };
            let tile = TileId { z, x, y };
            if filter.matches(tile) {
                entries.push(StoredEntry {
                    key: TileKey {
                        tile,
                        format: self.contents.format,
                    },
                    made_by: self.provenance(),
                    size: size.max(0) as u64,
                    accessed_at: 0,
                });
            }
        }
        Ok(entries)
    }

    fn usage(&self) -> Result<Usage, StoreError> {
        self.connection()
            .query_row(
                "SELECT count(*), coalesce(sum(length(tile_data)), 0) FROM tiles",
                [],
                |row| {
                    Ok(Usage {
                        tiles: row.get::<_, i64>(0)?.max(0) as u64,
                        bytes: row.get::<_, i64>(1)?.max(0) as u64,
                    })
                },
            )
            .map_err(|e| self.error(e))
    }
}

/// Writes an MBTiles file of `keys` into `into` (named `path` in errors): the `metadata` and
/// `tiles` tables of the MBTiles 1.3 layout, rows numbered TMS-style, south to north, each
/// tile's bytes asked of `body` in turn.
pub fn write<E: From<WriteError>>(
    (into, path): (&Path, &Path),
    contents: &Contents,
    keys: &[TileKey],
    body: &mut TileBodies<'_, E>,
) -> Result<(), E> {
    let _ = std::fs::remove_file(into);
    let sqlite = |source| WriteError::Sqlite {
        path: path.to_path_buf(),
        source,
    };
    let mut connection = Connection::open(into).map_err(sqlite)?;
    let transaction = connection.transaction().map_err(sqlite)?;
    transaction
        .execute_batch(
            "CREATE TABLE metadata (name TEXT PRIMARY KEY, value TEXT);
             CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER,
                                 tile_row INTEGER, tile_data BLOB,
                                 PRIMARY KEY (zoom_level, tile_column, tile_row));",
        )
        .map_err(sqlite)?;
    for (name, value) in metadata(contents) {
        transaction
            .execute(
                "INSERT INTO metadata (name, value) VALUES (?1, ?2)",
                params![name, value],
            )
            .map_err(sqlite)?;
    }
    for key in keys {
        let data = body(key)?;
        // MBTiles rows count from the south.
        let row = (1u64 << key.tile.z) - 1 - u64::from(key.tile.y);
        transaction
            .execute(
                "INSERT OR REPLACE INTO tiles VALUES (?1, ?2, ?3, ?4)",
                params![key.tile.z, key.tile.x, row as i64, data],
            )
            .map_err(sqlite)?;
    }
    transaction.commit().map_err(sqlite)?;
    connection.close().map_err(|(_, e)| sqlite(e))?;
    Ok(())
}
