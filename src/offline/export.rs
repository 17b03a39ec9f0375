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

use serde_json::Value;

use super::seed::Layer;
use crate::cache::archive;
use crate::cache::{Contents, StoreError, TileReader};
use crate::format::{Format, Frame, TileKey, Variant};
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
    #[error(transparent)]
    Archive(#[from] archive::WriteError),
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
    store: &dyn TileReader,
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
fn body(store: &dyn TileReader, key: &TileKey) -> Result<Vec<u8>, ExportError> {
    let tile = store
        .get(key)?
        .ok_or_else(|| ExportError::Missing(format!("{} ({})", key.tile, key.format.as_str())))?;
    Ok(tile.bodies.identity.to_vec())
}

fn export_mbtiles(
    store: &dyn TileReader,
    keys: &[TileKey],
    path: &Path,
    contents: &Contents,
) -> Result<ExportReport, ExportError> {
    let partial = partial_path(path);
    let mut report = ExportReport::default();
    archive::mbtiles::write::<ExportError>((&partial, path), contents, keys, &mut |key| {
        let data = body(store, key)?;
        report.add(&data);
        Ok(data)
    })?;
    move_into_place(&partial, path)?;
    Ok(report)
}

fn export_pmtiles(
    store: &dyn TileReader,
    keys: &[TileKey],
    path: &Path,
    contents: &Contents,
) -> Result<ExportReport, ExportError> {
    let partial = partial_path(path);
    let mut report = ExportReport::default();
    archive::pmtiles::write::<ExportError>((&partial, path), contents, keys, &mut |key| {
        let data = body(store, key)?;
        report.add(&data);
        Ok(data)
    })?;
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
    store: &dyn TileReader,
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
