//! The provider of an exported archive served as it is (`serve --archive FILE`, an MBTiles or a
//! PMTiles file). The file is the cache's store: every tile it has is found there, so this
//! provider never makes one — a tile the file lacks is not held — and its tiles are never
//! stale. What the file says it holds ([`Contents`]) gives the zooms served, the far views, the
//! heights of the 3D Tiles tileset and the terrain layer.

use std::path::PathBuf;

use super::{Availability, Made, MakeError, Offer, TileProvider, Unavailable};
use crate::cache::{ArchiveStore, Contents, Provenance};
use crate::format::{Format, TileKey};
use crate::output::layer::TerrainLayer;
use crate::render::Deadline;
use crate::tile::TileId;

/// What an exported file holds.
#[derive(Debug, Clone)]
pub struct Archive {
    pub path: PathBuf,
    pub contents: Contents,
}

impl Archive {
    pub fn of(store: &dyn ArchiveStore) -> Archive {
        Archive {
            path: store.path().to_path_buf(),
            contents: store.contents().clone(),
        }
    }

    fn zooms(&self) -> String {
        let zooms: Vec<String> = self.contents.zooms.iter().map(u8::to_string).collect();
        zooms.join(", ")
    }
}

impl TileProvider for Archive {
    fn offer(&self) -> Offer {
        let zoom = self.contents.max_zoom();
        let far_zooms = match self.contents.format {
            Format::Glb(_) => self
                .contents
                .zooms
                .iter()
                .copied()
                .filter(|&z| z < zoom)
                .rev()
                .collect(),
            Format::Terrain(_) => Vec::new(),
        };
        Offer {
            zoom,
            coverage: self.contents.bounds.into_iter().collect(),
            only: Some(self.contents.format),
            // Without recorded heights, a tileset lists its tiles with wide ones.
            open_ended: self.contents.ground.is_empty(),
            far_zooms,
        }
    }

    fn resolve(&self, tile: TileId, format: Format) -> Result<TileKey, Unavailable> {
        if !self.contents.zooms.contains(&tile.z) {
            return Err(Unavailable::NotOffered(format!(
                "zoom {} is not served; {} holds tiles at zooms {}",
                tile.z,
                self.path.display(),
                self.zooms()
            )));
        }
        // A terrain tile is the file's whatever extensions the client accepts.
        let format = match (format, self.contents.format) {
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

    /// The layer the export described; for an archive without one, every zoom over its box.
    fn terrain_layer(&self) -> Option<TerrainLayer> {
        let Format::Terrain(_) = self.contents.format else {
            return None;
        };
        let described = self.contents.layer.as_ref();
        described.and_then(TerrainLayer::from_document).or_else(|| {
            let bounds = self.contents.bounds?;
            Some(TerrainLayer::over_box(self.contents.max_zoom(), &bounds))
        })
    }

    fn ground_range(&self, tile: TileId) -> Option<(f64, f64)> {
        self.contents.ground.get(&tile).copied()
    }

    fn status(&self) -> serde_json::Value {
        serde_json::json!({ "archive": self.path.display().to_string() })
    }
}
