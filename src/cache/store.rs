//! The durable tile store: one SQLite file (WAL), its schema made by the numbered SQL files in
//! `migrations/` (compiled into the binary, applied in order, tracked by `PRAGMA user_version`).

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use rusqlite::{params, Connection, OptionalExtension};

use super::TileKey;

/// The migrations, in order; the schema version is the number of migrations applied.
const MIGRATIONS: &[(&str, &str)] = &[(
    "0001_tiles.sql",
    include_str!("../../migrations/0001_tiles.sql"),
)];

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("tile cache {path}: {source}")]
    Sqlite {
        path: PathBuf,
        #[source]
        source: rusqlite::Error,
    },
    #[error("tile cache {path}: cannot create its directory: {source}")]
    Directory {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("tile cache {path} has schema version {found}, newer than this program's {supported}")]
    NewerSchema {
        path: PathBuf,
        found: i64,
        supported: usize,
    },
}

/// A tile as stored.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StoredTile {
    pub data: Vec<u8>,
    pub etag: String,
}

pub struct TileStore {
    path: PathBuf,
    connection: Mutex<Connection>,
}

impl std::fmt::Debug for TileStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TileStore")
            .field("path", &self.path)
            .finish()
    }
}

impl TileStore {
    /// Opens (creating if needed) the store at `path` and brings its schema up to date.
    pub fn open(path: &Path) -> Result<TileStore, StoreError> {
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
        Ok(TileStore {
            path: path.to_path_buf(),
            connection: Mutex::new(connection),
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    fn connection(&self) -> std::sync::MutexGuard<'_, Connection> {
        // A panic while holding the lock cannot leave SQLite inconsistent (each statement is
        // atomic), so a poisoned lock is still usable.
        self.connection.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn error(&self, source: rusqlite::Error) -> StoreError {
        StoreError::Sqlite {
            path: self.path.clone(),
            source,
        }
    }

    /// The stored tile for `key` if it was made by `pipeline`.
    pub fn get(&self, key: &TileKey, pipeline: &str) -> Result<Option<StoredTile>, StoreError> {
        self.connection()
            .query_row(
                "SELECT data, etag FROM tiles
                 WHERE z = ?1 AND x = ?2 AND y = ?3 AND format = ?4 AND pipeline = ?5",
                params![
                    key.tile.z,
                    key.tile.x,
                    key.tile.y,
                    key.format.as_str(),
                    pipeline
                ],
                |row| {
                    Ok(StoredTile {
                        data: row.get(0)?,
                        etag: row.get(1)?,
                    })
                },
            )
            .optional()
            .map_err(|e| self.error(e))
    }

    /// Stores (or replaces) a tile.
    pub fn put(&self, key: &TileKey, pipeline: &str, tile: &StoredTile) -> Result<(), StoreError> {
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs() as i64)
            .unwrap_or(0);
        self.connection()
            .execute(
                "INSERT OR REPLACE INTO tiles (z, x, y, format, pipeline, data, etag, created_at)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
                params![
                    key.tile.z,
                    key.tile.x,
                    key.tile.y,
                    key.format.as_str(),
                    pipeline,
                    tile.data,
                    tile.etag,
                    now
                ],
            )
            .map(|_| ())
            .map_err(|e| self.error(e))
    }

    /// Number of stored tiles.
    pub fn len(&self) -> Result<u64, StoreError> {
        self.connection()
            .query_row("SELECT count(*) FROM tiles", [], |row| row.get(0))
            .map_err(|e| self.error(e))
    }

    pub fn is_empty(&self) -> Result<bool, StoreError> {
        Ok(self.len()? == 0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cache::Format;
    use crate::tile::TileId;

    #[test]
    fn stores_and_finds_a_tile_of_the_same_pipeline_only() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub/tiles.sqlite");
        let store = TileStore::open(&path).unwrap();
        let key = TileKey {
            tile: TileId { z: 14, x: 1, y: 2 },
            format: Format::Glb,
        };
        let tile = StoredTile {
            data: vec![1, 2, 3],
            etag: "\"abc\"".to_string(),
        };
        store.put(&key, "v1", &tile).unwrap();
        assert_eq!(store.get(&key, "v1").unwrap(), Some(tile));
        assert_eq!(store.get(&key, "v2").unwrap(), None);
        drop(store);
        // Reopening applies no migration twice.
        let store = TileStore::open(&path).unwrap();
        assert_eq!(store.len().unwrap(), 1);
    }
}
