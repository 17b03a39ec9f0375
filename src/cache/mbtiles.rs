//! An MBTiles file (as `terrastitch export` writes it) as a read-only tile store, so a server
//! without any source data can serve an exported area: `terrastitch serve --archive FILE`.
//!
//! A tile enters memory compressed once, like a rendered one; the file is never written.

use std::path::Path;

use rusqlite::{Connection, OpenFlags, OptionalExtension};

use super::archive::{archived_tile, format_named, ArchiveStore, Contents, CONTENTS_KEY};
use super::sqlite::Database;
use super::store::{Provenance, StoreError, StoredEntry, StoredTile, TileFilter, TileStore, Usage};
use crate::format::TileKey;
use crate::tile::{LonLatBounds, TileId};

#[derive(Debug)]
pub struct MbtilesStore {
    db: Database,
    contents: Contents,
}

impl MbtilesStore {
    /// Opens the file read-only and reads its metadata; a file without the MBTiles tables, or
    /// of a format other than glb or terrain, is an error naming it.
    pub fn open(path: &Path) -> Result<MbtilesStore, StoreError> {
        let sqlite = |source| StoreError::Sqlite {
            path: path.to_path_buf(),
            source,
        };
        let connection =
            Connection::open_with_flags(path, OpenFlags::SQLITE_OPEN_READ_ONLY).map_err(sqlite)?;
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
        })
    }

    fn connection(&self) -> std::sync::MutexGuard<'_, Connection> {
        self.db.lock()
    }

    fn error(&self, source: rusqlite::Error) -> StoreError {
        self.db.error(source)
    }

    fn read_only(&self) -> StoreError {
        StoreError::ReadOnly {
            path: self.db.path().to_path_buf(),
        }
    }

    /// What every tile of the file was made from, as far as a server that only reads it knows.
    pub fn provenance(&self) -> Provenance {
        Provenance {
            pipeline: "mbtiles".to_string(),
            sources: self.db.path().display().to_string(),
        }
    }
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

impl TileStore for MbtilesStore {
    fn get(&self, key: &TileKey) -> Result<Option<StoredTile>, StoreError> {
        if key.format != self.contents.format {
            return Ok(None);
        }
        let data: Option<Vec<u8>> = self
            .connection()
            .query_row(
                "SELECT tile_data FROM tiles
                 WHERE zoom_level = ?1 AND tile_column = ?2 AND tile_row = ?3",
                rusqlite::params![key.tile.z, key.tile.x, tms_row(key.tile)],
                |row| row.get(0),
            )
            .optional()
            .map_err(|e| self.error(e))?;
        let Some(data) = data else {
            return Ok(None);
        };
        archived_tile(data, self.provenance()).map(Some)
    }

    fn put(&self, _key: &TileKey, _tile: &StoredTile) -> Result<(), StoreError> {
        Err(self.read_only())
    }

    fn touch(&self, _keys: &[TileKey], _at: i64) -> Result<(), StoreError> {
        Ok(())
    }

    fn remove(&self, _filter: &TileFilter) -> Result<Vec<TileKey>, StoreError> {
        Err(self.read_only())
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
