//! `terrastitch export`: an area's tiles out of the cache, as an MBTiles file (SQLite: the
//! `metadata` and `tiles` tables of the MBTiles 1.3 layout, rows numbered TMS-style, south to
//! north) or as a directory `DIR/z/x/y.glb` that any static file server can serve. Tiles are
//! written uncompressed. Both are written beside their destination and moved into place when
//! whole, so a failed export leaves no half file where a good one is expected.

use std::path::{Path, PathBuf};

use rusqlite::{params, Connection};

use crate::cache::{StoreError, TileStore};
use crate::format::Variant;
use crate::format::{Format, TileKey};
use crate::output::glb::ATTRIBUTION;
use crate::tile::LonLatBounds;

/// Where an export goes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Target {
    Mbtiles(PathBuf),
    Directory(PathBuf),
}

impl Target {
    /// A path ending in `/` (or naming an existing directory) is a directory; anything else an
    /// MBTiles file.
    pub fn from_path(path: &Path) -> Target {
        let text = path.to_string_lossy();
        if text.ends_with('/') || path.is_dir() {
            Target::Directory(path.to_path_buf())
        } else {
            Target::Mbtiles(path.to_path_buf())
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error("cannot write {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot write MBTiles file {path}: {source}")]
    Sqlite {
        path: PathBuf,
        #[source]
        source: rusqlite::Error,
    },
    #[error("tile {0} is not in the cache; seed it first")]
    Missing(String),
}

/// What went out.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ExportReport {
    pub tiles: usize,
    /// Bytes of tile data written.
    pub bytes: u64,
}

/// Writes the tiles `keys` from `store` to `target`; `bounds` and `zoom` go into the MBTiles
/// metadata. Every tile must be in the store.
pub fn export(
    store: &dyn TileStore,
    keys: &[TileKey],
    target: &Target,
    bounds: &LonLatBounds,
    zoom: u8,
) -> Result<ExportReport, ExportError> {
    match target {
        Target::Mbtiles(path) => export_mbtiles(store, keys, path, bounds, zoom),
        Target::Directory(path) => export_directory(store, keys, path),
    }
}

/// The tile's body, uncompressed.
fn body(store: &dyn TileStore, key: &TileKey) -> Result<Vec<u8>, ExportError> {
    let tile = store
        .get(key)?
        .ok_or_else(|| ExportError::Missing(format!("{} ({})", key.tile, key.format.as_str())))?;
    Ok(tile.bodies.identity.to_vec())
}

fn export_mbtiles(
    store: &dyn TileStore,
    keys: &[TileKey],
    path: &Path,
    bounds: &LonLatBounds,
    zoom: u8,
) -> Result<ExportReport, ExportError> {
    let partial = partial_path(path);
    let _ = std::fs::remove_file(&partial);
    let sqlite = |source| ExportError::Sqlite {
        path: path.to_path_buf(),
        source,
    };
    let mut connection = Connection::open(&partial).map_err(sqlite)?;
    let mut report = ExportReport::default();
    {
        let transaction = connection.transaction().map_err(sqlite)?;
        transaction
            .execute_batch(
                "CREATE TABLE metadata (name TEXT PRIMARY KEY, value TEXT);
                 CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER,
                                     tile_row INTEGER, tile_data BLOB,
                                     PRIMARY KEY (zoom_level, tile_column, tile_row));",
            )
            .map_err(sqlite)?;
        // glb archives name their variant (the MBTiles reader of this server reads it back).
        let format = keys.first().map_or("glb", |k| match k.format {
            Format::Glb(variant) => variant.name(),
            Format::Terrain(_) => "terrain",
        });
        let center_lon = (bounds.west + bounds.east) / 2.0;
        let center_lat = (bounds.south + bounds.north) / 2.0;
        let metadata = [
            ("name", "terrastitch".to_string()),
            ("format", format.to_string()),
            (
                "description",
                "3D tiles of OpenStreetMap on SRTM terrain, glTF binary".to_string(),
            ),
            ("attribution", ATTRIBUTION.to_string()),
            ("type", "overlay".to_string()),
            ("version", "1".to_string()),
            (
                "bounds",
                format!(
                    "{},{},{},{}",
                    bounds.west, bounds.south, bounds.east, bounds.north
                ),
            ),
            ("center", format!("{center_lon},{center_lat},{zoom}")),
            ("minzoom", zoom.to_string()),
            ("maxzoom", zoom.to_string()),
        ];
        for (name, value) in metadata {
            transaction
                .execute(
                    "INSERT INTO metadata (name, value) VALUES (?1, ?2)",
                    params![name, value],
                )
                .map_err(sqlite)?;
        }
        for key in keys {
            let data = body(store, key)?;
            // MBTiles rows count from the south.
            let row = (1u64 << key.tile.z) - 1 - u64::from(key.tile.y);
            transaction
                .execute(
                    "INSERT OR REPLACE INTO tiles VALUES (?1, ?2, ?3, ?4)",
                    params![key.tile.z, key.tile.x, row as i64, data],
                )
                .map_err(sqlite)?;
            report.tiles += 1;
            report.bytes += data.len() as u64;
        }
        transaction.commit().map_err(sqlite)?;
    }
    connection.close().map_err(|(_, e)| sqlite(e))?;
    std::fs::rename(&partial, path).map_err(|source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(report)
}

/// The file name of a tile in a directory export: `{y}.glb`, `{y}.terrain`, and for the other
/// glb variants `{y}.meshopt.glb`, `{y}.enu.glb`, `{y}.enu-meshopt.glb`, so that several
/// variants can go to one directory.
fn file_name(key: &TileKey) -> String {
    format!("{}{}", key.tile.y, file_suffix(key.format))
}

/// What follows the row in a directory export's file name for `format` (`.enu-meshopt.glb`).
pub fn file_suffix(format: Format) -> String {
    match format {
        Format::Glb(variant) if variant != Variant::default() => {
            let name = variant.name().trim_start_matches("glb-");
            format!(".{name}.glb")
        }
        format => format!(".{}", format.extension()),
    }
}

/// Writes a whole file: beside its place first, then moved there.
pub fn write_whole(path: &Path, bytes: &[u8]) -> Result<(), ExportError> {
    let io = |source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    };
    let partial = partial_path(path);
    std::fs::write(&partial, bytes).map_err(io)?;
    std::fs::rename(&partial, path).map_err(io)
}

fn export_directory(
    store: &dyn TileStore,
    keys: &[TileKey],
    root: &Path,
) -> Result<ExportReport, ExportError> {
    let mut report = ExportReport::default();
    for key in keys {
        let data = body(store, key)?;
        let directory = root
            .join(key.tile.z.to_string())
            .join(key.tile.x.to_string());
        let path = directory.join(file_name(key));
        let io = |source| ExportError::Io {
            path: path.clone(),
            source,
        };
        std::fs::create_dir_all(&directory).map_err(io)?;
        write_whole(&path, &data)?;
        report.tiles += 1;
        report.bytes += data.len() as u64;
    }
    Ok(report)
}

/// Where a file is written before it is moved into place.
fn partial_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    path.with_file_name(name)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::Extensions;
    use crate::format::Frame;
    use crate::tile::TileId;

    #[test]
    fn every_format_has_a_file_name_of_its_own() {
        let tile = TileId::new(14, 8529, 5973).unwrap();
        let mut names: Vec<String> = Variant::ALL
            .into_iter()
            .map(Format::Glb)
            .chain([Format::Terrain(Extensions {
                normals: true,
                watermask: true,
            })])
            .map(|format| file_name(&TileKey { tile, format }))
            .collect();
        assert_eq!(names[0], "5973.glb");
        let enu = Format::Glb(Variant {
            frame: Frame::EastNorthUp,
            meshopt: true,
        });
        assert_eq!(
            file_name(&TileKey { tile, format: enu }),
            "5973.enu-meshopt.glb"
        );
        names.sort();
        names.dedup();
        assert_eq!(names.len(), 5);
    }
}
