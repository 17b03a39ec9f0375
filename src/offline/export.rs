//! `terrastitch export`: an area's tiles out of the cache, at the served zoom and the coarser
//! zooms viewers ask for, as
//! - an MBTiles file (SQLite: the `metadata` and `tiles` tables of the MBTiles 1.3 layout, rows
//!   numbered TMS-style, south to north);
//! - a PMTiles v3 file (one file that a CDN or an object store serves with HTTP range
//!   requests), written with the `pmtiles` crate, tiles in Hilbert order;
//! - or a directory `DIR/z/x/y.glb` that any static file server can serve, with the
//!   `tileset.json` of its east-north-up tiles and the `layer.json` of its terrain.
//!
//! Tiles are written uncompressed, the bytes the cache holds. An archive carries what it holds
//! ([`Contents`]: zooms, heights under the tiles, terrain layer) in its metadata, so `serve
//! --archive` gives the same `tileset.json` and `layer.json`. Everything is written beside its
//! destination and moved into place when whole, so a failed export leaves no half file where a
//! good one is expected.

use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

use rusqlite::{params, Connection};
use serde_json::Value;

use super::seed::Layer;
use crate::cache::archive::{format_name, CONTENTS_KEY};
use crate::cache::{Contents, StoreError, TileStore};
use crate::format::{Format, Frame, TileKey, Variant};
use crate::output::glb::ATTRIBUTION;
use crate::output::layer::TerrainLayer;
use crate::output::tileset::{Plan, Root};
use crate::tile::{LonLatBounds, TileId};

/// Where a server of an archive serves its terrain tiles.
const SERVED_TERRAIN: &str = "tiles/{z}/{x}/{y}.terrain";

/// Where an export goes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Target {
    Mbtiles(PathBuf),
    Pmtiles(PathBuf),
    Directory(PathBuf),
}

impl Target {
    /// A path ending in `/` (or naming an existing directory) is a directory, one ending in
    /// `.pmtiles` a PMTiles file, anything else an MBTiles file.
    pub fn from_path(path: &Path) -> Target {
        let text = path.to_string_lossy();
        if text.ends_with('/') || path.is_dir() {
            Target::Directory(path.to_path_buf())
        } else if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("pmtiles"))
        {
            Target::Pmtiles(path.to_path_buf())
        } else {
            Target::Mbtiles(path.to_path_buf())
        }
    }

    /// Whether the target holds one format only (a file).
    pub fn holds_one_format(&self) -> bool {
        !matches!(self, Target::Directory(_))
    }
}

/// What an export writes: the tiles, and what each format's tiles hold.
#[derive(Debug, Clone)]
pub struct Export {
    pub keys: Vec<TileKey>,
    /// One for each format exported.
    pub contents: Vec<Contents>,
}

/// What the tiles of `format` in `layers` hold: their zooms, the heights under each tile of
/// their 3D Tiles tileset (from `heights`, for east-north-up glb) and, for terrain, its layer.
pub fn contents_of(
    format: Format,
    layers: &[Layer],
    bbox: &LonLatBounds,
    heights: &dyn Fn(TileId) -> Option<(f64, f64)>,
) -> Contents {
    let mut zooms: Vec<u8> = layers
        .iter()
        .filter(|l| l.formats.contains(&format))
        .map(|l| l.range.z)
        .collect();
    zooms.sort_unstable();
    let mut contents = Contents {
        format,
        bounds: Some(*bbox),
        zooms,
        ground: HashMap::new(),
        layer: None,
    };
    match format {
        Format::Glb(variant) if variant.frame == Frame::EastNorthUp => {
            contents.ground =
                recorded_ground(&tileset_plan(&contents, Some(String::new())), heights);
        }
        Format::Glb(_) => {}
        Format::Terrain(_) => {
            let layer = TerrainLayer::over_box(contents.max_zoom(), bbox);
            contents.layer = Some(layer.document(SERVED_TERRAIN));
        }
    }
    contents
}

/// The 3D Tiles plan over an export's tiles; `files` names them as a directory does.
pub fn tileset_plan(contents: &Contents, files: Option<String>) -> Plan {
    Plan {
        content_zoom: contents.max_zoom(),
        coverage: contents.bounds.into_iter().collect(),
        query: String::new(),
        list_unknown: contents.ground.is_empty(),
        parent_content: contents.zooms.len() > 1,
        files,
    }
}

/// The heights `plan`'s tileset asks for, as `heights` gives them.
fn recorded_ground(
    plan: &Plan,
    heights: &dyn Fn(TileId) -> Option<(f64, f64)>,
) -> HashMap<TileId, (f64, f64)> {
    let recorded = RefCell::new(HashMap::new());
    let record = |tile: TileId| {
        let range = heights(tile);
        if let Some(range) = range {
            recorded.borrow_mut().insert(tile, range);
        }
        range
    };
    // Listing the whole hierarchy in one document asks for every tile's heights.
    plan.root(&record, Root::InFolder);
    recorded.into_inner()
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
    #[error("cannot write PMTiles file {path}: {source}")]
    Pmtiles {
        path: PathBuf,
        #[source]
        source: pmtiles::PmtError,
    },
    #[error("tile {0} is not in the cache; seed it first")]
    Missing(String),
    #[error(
        "an MBTiles or PMTiles file holds one format; export to a directory (-o DIR/) for several"
    )]
    SeveralFormats,
}

/// What went out.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ExportReport {
    pub tiles: usize,
    /// Bytes of tile data written.
    pub bytes: u64,
    /// The documents written beside a directory's tiles.
    pub described: Vec<&'static str>,
}

impl ExportReport {
    fn add(&mut self, data: &[u8]) {
        self.tiles += 1;
        self.bytes += data.len() as u64;
    }
}

/// Writes `export` from `store` to `target`; every tile must be in the store. A file target
/// takes one format.
pub fn export(
    store: &dyn TileStore,
    export: &Export,
    target: &Target,
) -> Result<ExportReport, ExportError> {
    let single = || match export.contents.as_slice() {
        [contents] => Ok(contents),
        _ => Err(ExportError::SeveralFormats),
    };
    match target {
        Target::Mbtiles(path) => export_mbtiles(store, &export.keys, path, single()?),
        Target::Pmtiles(path) => export_pmtiles(store, &export.keys, path, single()?),
        Target::Directory(path) => export_directory(store, export, path),
    }
}

/// The tile's body, uncompressed.
fn body(store: &dyn TileStore, key: &TileKey) -> Result<Vec<u8>, ExportError> {
    let tile = store
        .get(key)?
        .ok_or_else(|| ExportError::Missing(format!("{} ({})", key.tile, key.format.as_str())))?;
    Ok(tile.bodies.identity.to_vec())
}

/// The metadata both archives carry: name, format, description, attribution, bounds, centre,
/// zooms, and the contents under [`CONTENTS_KEY`].
fn metadata(contents: &Contents) -> Vec<(&'static str, String)> {
    let zoom = contents.max_zoom();
    let min_zoom = contents.zooms.first().copied().unwrap_or(zoom);
    let description = match contents.format {
        Format::Glb(_) => "3D tiles of OpenStreetMap on SRTM terrain, glTF binary",
        Format::Terrain(_) => "Terrain from SRTM with OpenStreetMap roads, railways and water stitched into it, quantized-mesh",
    };
    let mut rows = vec![
        ("name", "terrastitch".to_string()),
        ("format", format_name(contents.format).to_string()),
        ("description", description.to_string()),
        ("attribution", ATTRIBUTION.to_string()),
        ("type", "overlay".to_string()),
        ("version", "1".to_string()),
        ("minzoom", min_zoom.to_string()),
        ("maxzoom", zoom.to_string()),
        (CONTENTS_KEY, contents.to_json().to_string()),
    ];
    if let Some(b) = contents.bounds {
        let (lon, lat) = ((b.west + b.east) / 2.0, (b.south + b.north) / 2.0);
        rows.push((
            "bounds",
            format!("{},{},{},{}", b.west, b.south, b.east, b.north),
        ));
        rows.push(("center", format!("{lon},{lat},{zoom}")));
    }
    rows
}

fn export_mbtiles(
    store: &dyn TileStore,
    keys: &[TileKey],
    path: &Path,
    contents: &Contents,
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
        for (name, value) in metadata(contents) {
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
            report.add(&data);
        }
        transaction.commit().map_err(sqlite)?;
    }
    connection.close().map_err(|(_, e)| sqlite(e))?;
    move_into_place(&partial, path)?;
    Ok(report)
}

fn export_pmtiles(
    store: &dyn TileStore,
    keys: &[TileKey],
    path: &Path,
    contents: &Contents,
) -> Result<ExportReport, ExportError> {
    let failed = |source| ExportError::Pmtiles {
        path: path.to_path_buf(),
        source,
    };
    let io = |source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    };
    // The specification wants tiles in Hilbert order for a clustered archive.
    let mut ordered: Vec<(pmtiles::TileCoord, &TileKey)> = Vec::with_capacity(keys.len());
    for key in keys {
        let (z, x, y) = (key.tile.z, key.tile.x, key.tile.y);
        ordered.push((pmtiles::TileCoord::new(z, x, y).map_err(failed)?, key));
    }
    ordered.sort_by_key(|(coord, _)| pmtiles::TileId::from(*coord).value());
    let rows = metadata(contents);
    let mut document = serde_json::Map::new();
    for (name, value) in &rows {
        let value = match *name {
            CONTENTS_KEY => serde_json::from_str(value).unwrap_or(Value::Null),
            _ => Value::String(value.clone()),
        };
        document.insert(name.to_string(), value);
    }
    let zoom = contents.max_zoom();
    let mut writer = pmtiles::PmTilesWriter::new(pmtiles::TileType::Unknown)
        .min_zoom(contents.zooms.first().copied().unwrap_or(zoom))
        .max_zoom(zoom)
        .center_zoom(zoom)
        .metadata(Value::Object(document).to_string());
    if let Some(b) = contents.bounds {
        writer = writer
            .bounds(b.west, b.south, b.east, b.north)
            .center((b.west + b.east) / 2.0, (b.south + b.north) / 2.0);
    }
    let partial = partial_path(path);
    let file = std::fs::File::create(&partial).map_err(io)?;
    let mut writer = writer
        .create(std::io::BufWriter::new(file))
        .map_err(failed)?;
    let mut report = ExportReport::default();
    for (coord, key) in ordered {
        let data = body(store, key)?;
        writer.add_tile(coord, &data).map_err(failed)?;
        report.add(&data);
    }
    writer.finalize().map_err(failed)?;
    move_into_place(&partial, path)?;
    Ok(report)
}

fn move_into_place(partial: &Path, path: &Path) -> Result<(), ExportError> {
    std::fs::rename(partial, path).map_err(|source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    })
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
    export: &Export,
    root: &Path,
) -> Result<ExportReport, ExportError> {
    let mut report = ExportReport::default();
    for key in &export.keys {
        let data = body(store, key)?;
        let directory = root
            .join(key.tile.z.to_string())
            .join(key.tile.x.to_string());
        let path = directory.join(file_name(key));
        std::fs::create_dir_all(&directory).map_err(|source| ExportError::Io {
            path: path.clone(),
            source,
        })?;
        write_whole(&path, &data)?;
        report.add(&data);
    }
    for contents in &export.contents {
        if let Some((name, document)) = description(contents) {
            write_whole(&root.join(name), document.to_string().as_bytes())?;
            report.described.push(name);
        }
    }
    Ok(report)
}

/// The document that describes a directory's tiles of one format to a client: `tileset.json`
/// for east-north-up glb, `layer.json` for terrain.
fn description(contents: &Contents) -> Option<(&'static str, Value)> {
    match contents.format {
        Format::Glb(variant) if variant.frame == Frame::EastNorthUp => {
            let plan = tileset_plan(contents, Some(file_suffix(contents.format)));
            let heights = |tile: TileId| contents.ground.get(&tile).copied();
            Some(("tileset.json", plan.root(&heights, Root::InFolder)))
        }
        Format::Glb(_) => None,
        Format::Terrain(_) => {
            let layer = TerrainLayer::from_document(contents.layer.as_ref()?)?;
            let template = format!("{{z}}/{{x}}/{{y}}{}", file_suffix(contents.format));
            Some(("layer.json", layer.document(&template)))
        }
    }
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
