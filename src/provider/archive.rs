//! The provider of an exported MBTiles file served as it is (`serve --mbtiles FILE`). The file
//! is the cache's store: every tile it has is found there, so this provider never makes one —
//! a tile the file lacks is not held — and its tiles are never stale.

use std::path::PathBuf;

use super::{Availability, Made, MakeError, Offer, TileProvider, Unavailable};
use crate::cache::{MbtilesStore, Provenance};
use crate::format::{Format, TileKey};
use crate::render::Deadline;
use crate::tile::{LonLatBounds, TileId};

/// What an exported file holds.
#[derive(Debug, Clone)]
pub struct Archive {
    pub path: PathBuf,
    pub format: Format,
    pub zoom: u8,
    pub bounds: Option<LonLatBounds>,
}

impl Archive {
    /// The archive an opened file describes; its zoom is `zoom` when the file names none.
    pub fn of(path: PathBuf, store: &MbtilesStore, zoom: u8) -> Archive {
        Archive {
            path,
            format: store.format(),
            zoom: store.zoom().unwrap_or(zoom),
            bounds: store.bounds(),
        }
    }
}

impl TileProvider for Archive {
    fn offer(&self) -> Offer {
        Offer {
            zoom: self.zoom,
            coverage: self.bounds.into_iter().collect(),
            only: Some(self.format),
            open_ended: true,
            terrain_cells: None,
            far_zooms: Vec::new(),
        }
    }

    fn resolve(&self, tile: TileId, format: Format) -> Result<TileKey, Unavailable> {
        if tile.z != self.zoom {
            return Err(Unavailable::NotOffered(format!(
                "zoom {} is not served; {} holds tiles at zoom {}",
                tile.z,
                self.path.display(),
                self.zoom
            )));
        }
        // A terrain tile is the file's whatever extensions the client accepts.
        let format = match (format, self.format) {
            (Format::Terrain(_), Format::Terrain(held)) => Format::Terrain(held),
            (asked, _) => asked,
        };
        Ok(TileKey { tile, format })
    }

    fn availability(&self, _key: TileKey) -> Availability {
        Availability::Ready
    }

    fn provenance(&self, _tile: TileId) -> Option<Provenance> {
        None
    }

    fn make(&self, key: TileKey, _deadline: Deadline) -> Result<Made, MakeError> {
        Err(MakeError::NotHeld(format!(
            "tile {} ({}) is not in {}",
            key.tile,
            key.format.as_str(),
            self.path.display()
        )))
    }

    fn status(&self) -> serde_json::Value {
        serde_json::json!({ "archive": self.path.display().to_string() })
    }
}
