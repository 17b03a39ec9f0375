//! An exported archive — an MBTiles file or a PMTiles file, as `terrastitch export` writes them
//! — as a read-only tile store ([`ArchiveStore`]; [`open_archive`] opens either kind),
//! with what it holds beside its tiles: the zooms, the ground's heights under the tiles (the bounding volumes of a 3D Tiles
//! tileset over them) and, for terrain, the `layer.json` that describes it. These go into the
//! archive's metadata as one JSON object under [`CONTENTS_KEY`]; an archive without it (written
//! elsewhere, or by an older export) holds what its zoom range says, without heights.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde_json::{json, Value};

pub mod mbtiles;
pub mod pmtiles;

use crate::cache::encoding::Bodies;
use crate::cache::store::{Provenance, StoreError, StoredTile, TileReader};
use crate::format::{Extensions, Format, TileKey, Variant, ATTRIBUTION};
use crate::tile::{LonLatBounds, TileId};

/// The name of the metadata entry holding [`Contents`].
pub const CONTENTS_KEY: &str = "terrastitch";

/// What an archive holds.
#[derive(Debug, Clone, PartialEq)]
pub struct Contents {
    pub format: Format,
    pub bounds: Option<LonLatBounds>,
    /// The zooms it holds tiles of, ascending.
    pub zooms: Vec<u8>,
    /// The ground's lowest and highest point under each tile of its tileset, in the heights the
    /// content is written in.
    pub ground: HashMap<TileId, (f64, f64)>,
    /// For terrain, the `layer.json` document of the export.
    pub layer: Option<Value>,
}

impl Contents {
    /// The finest zoom held.
    pub fn max_zoom(&self) -> u8 {
        self.zooms.last().copied().unwrap_or(0)
    }

    /// The JSON written under [`CONTENTS_KEY`].
    pub fn to_json(&self) -> Value {
        let mut ground: Vec<(&TileId, &(f64, f64))> = self.ground.iter().collect();
        ground.sort_by_key(|(t, _)| (t.z, t.y, t.x));
        let ground: Vec<Value> = ground
            .into_iter()
            .map(|(t, (low, high))| json!([t.z, t.x, t.y, low, high]))
            .collect();
        let mut value = json!({
            "format": format_name(self.format),
            "zooms": self.zooms,
            "ground": ground,
        });
        if let Some(layer) = &self.layer {
            value["layer"] = layer.clone();
        }
        value
    }

    /// The contents of an archive of `format`, `bounds` and zooms `min..=max` from its metadata
    /// entry `entry` (absent in archives written elsewhere).
    pub fn read(
        format: Format,
        bounds: Option<LonLatBounds>,
        (min, max): (u8, u8),
        entry: Option<&Value>,
    ) -> Contents {
        let zooms = entry
            .and_then(|e| e["zooms"].as_array())
            .map(|zooms| {
                let mut zooms: Vec<u8> = zooms
                    .iter()
                    .filter_map(|z| u8::try_from(z.as_u64()?).ok())
                    .filter(|&z| z <= crate::tile::MAX_ZOOM)
                    .collect();
                zooms.sort_unstable();
                zooms.dedup();
                zooms
            })
            .filter(|zooms| !zooms.is_empty())
            .unwrap_or_else(|| (min.min(max)..=max).collect());
        let ground = entry
            .and_then(|e| e["ground"].as_array())
            .map(|rows| rows.iter().filter_map(ground_row).collect())
            .unwrap_or_default();
        let layer = entry
            .map(|e| e["layer"].clone())
            .filter(|layer| layer.is_object());
        Contents {
            format,
            bounds,
            zooms,
            ground,
            layer,
        }
    }
}

/// `[z, x, y, low, high]`.
fn ground_row(row: &Value) -> Option<(TileId, (f64, f64))> {
    let number = |i: usize| row.get(i).and_then(Value::as_u64);
    let tile = TileId::new(u32::try_from(number(0)?).ok()?, number(1)?, number(2)?).ok()?;
    let (low, high) = (row.get(3)?.as_f64()?, row.get(4)?.as_f64()?);
    Some((tile, (low, high)))
}

/// The format an archive names: a glb variant's name, or `terrain`.
pub fn format_named(name: &str) -> Option<Format> {
    match name {
        "terrain" => Some(Format::Terrain(Extensions {
            normals: true,
            watermask: true,
        })),
        name => Variant::from_name(name).map(Format::Glb),
    }
}

/// The name an archive gives its format.
pub fn format_name(format: Format) -> &'static str {
    match format {
        Format::Glb(variant) => variant.name(),
        Format::Terrain(_) => "terrain",
    }
}

/// A tile read from an archive, as a store holds it: its codings made once, its validator.
pub(super) fn archived_tile(data: Vec<u8>, made_by: Provenance) -> Result<StoredTile, StoreError> {
    Ok(StoredTile {
        etag: crate::cache::etag_of(&data),
        bodies: Bodies::compress(data)?,
        made_by,
        created_at: 0,
    })
}

/// Opens an MBTiles or a PMTiles file, told apart by their first bytes; a tile in it longer than
/// `max_tile` bytes, uncompressed, is damaged.
pub fn open_archive(
    path: &std::path::Path,
    max_tile: u64,
) -> Result<Arc<dyn ArchiveStore>, StoreError> {
    let mut magic = [0u8; 16];
    let read =
        std::fs::File::open(path).and_then(|mut file| std::io::Read::read(&mut file, &mut magic));
    let read = read.map_err(|source| StoreError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let magic = &magic[..read];
    if magic.starts_with(b"PMTiles") {
        Ok(Arc::new(pmtiles::PmtilesStore::open(path, max_tile)?))
    } else if magic.starts_with(b"SQLite format 3\0") {
        Ok(Arc::new(mbtiles::MbtilesStore::open(path, max_tile)?))
    } else {
        Err(StoreError::Damaged {
            path: path.to_path_buf(),
            report: "it is neither a PMTiles nor an MBTiles file".to_string(),
        })
    }
}

/// Why an archive could not be written.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
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
        source: ::pmtiles::PmtError,
    },
}

/// The body of each tile an archive is written with, asked for in the order it is written.
pub type TileBodies<'a, E> = dyn FnMut(&TileKey) -> Result<Vec<u8>, E> + 'a;

/// The metadata both archives carry: name, format, description, attribution, bounds, centre,
/// zooms, and the contents under [`CONTENTS_KEY`].
pub(crate) fn metadata(contents: &Contents) -> Vec<(&'static str, String)> {
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

/// A read-only store of an exported file.
pub trait ArchiveStore: TileReader {
    fn contents(&self) -> &Contents;
    fn path(&self) -> &Path;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contents_read_back_from_their_json() {
        let bounds: LonLatBounds = "7.40,43.72,7.44,43.75".parse().unwrap();
        let format = format_named("terrain").unwrap();
        let tile = TileId::new(14, 8528, 5974).unwrap();
        let contents = Contents {
            format,
            bounds: Some(bounds),
            zooms: (0..=14).collect(),
            ground: HashMap::from([(tile, (-3.5, 161.25))]),
            layer: Some(json!({"tiles": ["tiles/{z}/{x}/{y}.terrain"]})),
        };
        let json = contents.to_json();
        let read = Contents::read(format, Some(bounds), (0, 14), Some(&json));
        assert_eq!(read, contents);
    }

    #[test]
    fn an_archive_without_contents_holds_its_zoom_range() {
        let format = format_named("glb-meshopt").unwrap();
        let read = Contents::read(format, None, (12, 14), None);
        assert_eq!(read.zooms, vec![12, 13, 14]);
        assert!(read.ground.is_empty());
        assert_eq!(read.layer, None);
        let odd = json!({"zooms": ["x", 99], "ground": [[14, 1], "no"]});
        let read = Contents::read(format, None, (14, 14), Some(&odd));
        assert_eq!(read.zooms, vec![14]);
        assert!(read.ground.is_empty());
    }

    #[test]
    fn a_file_of_neither_kind_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("tiles.pmtiles");
        std::fs::write(&path, b"not an archive").unwrap();
        let error = open_archive(&path, crate::cache::store::DEFAULT_MAX_TILE_BYTES)
            .err()
            .unwrap()
            .to_string();
        assert!(
            error.contains("neither a PMTiles nor an MBTiles"),
            "{error}"
        );
        let missing = open_archive(
            &dir.path().join("absent.pmtiles"),
            crate::cache::store::DEFAULT_MAX_TILE_BYTES,
        )
        .err()
        .unwrap();
        assert!(missing.to_string().contains("absent.pmtiles"), "{missing}");
    }
}
