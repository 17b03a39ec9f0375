//! Where tiles come from. A [`TileProvider`] says what it offers, whether it can have a tile,
//! what a tile made now would be made from, and makes it; the server, `seed` and `export` ask
//! it and nothing else, so they do not know whether tiles are rendered or read from a file.
//!
//! Two providers: the [`Renderer`] (the opened inputs — extracts, SRTM files and their index —
//! with the render settings, made into tiles by [`pipeline`]), and the [`Archive`] (an exported
//! MBTiles file, whose tiles are the cache's store: it never makes one).

pub mod archive;
pub mod capabilities;
pub mod inputs;
pub mod osm_source;
pub mod pipeline;
pub mod renderer;

use crate::cache::Provenance;
use crate::format::{Format, TileKey};
use crate::tile::{LonLatBounds, TileId};

pub use archive::Archive;
pub use capabilities::{Explaining, Fetching, Reloading};
pub use inputs::Inputs;
pub use pipeline::{Made, MakeError};
pub use renderer::Renderer;
// What the layers above see of making a tile: its time limit, what its stages took, and what
// the downloads it needed did.
pub use crate::render::{Deadline, Solutions, StageTimings};
pub use crate::source::fetch::FetchStats;

/// Solved LP components read from a tile store when a process starts, at most.
const SOLUTIONS_AT_START: usize = 50_000;

/// Reads the solved LP components `store` keeps into `solutions`, for the renders that use it
/// to find; returns how many it kept.
pub fn load_solutions(
    store: &dyn crate::cache::TileReader,
    solutions: &Solutions,
) -> Result<usize, crate::cache::StoreError> {
    let entries = store.solutions(SOLUTIONS_AT_START)?;
    Ok(solutions.remember(entries))
}

/// Writes the LP components `solutions` solved since the last call to `store`; returns how
/// many.
pub fn save_solutions(
    store: &dyn crate::cache::TileStore,
    solutions: &Solutions,
) -> Result<usize, crate::cache::StoreError> {
    let entries = solutions.take_unsaved();
    store.keep_solutions(&entries)?;
    Ok(entries.len())
}

/// What a provider offers.
#[derive(Debug, Clone, PartialEq)]
pub struct Offer {
    /// The zoom of its tiles (terrain also at every coarser zoom, when it makes tiles).
    pub zoom: u8,
    /// The areas its data covers.
    pub coverage: Vec<LonLatBounds>,
    /// The one format it holds; `None` when it makes every format.
    pub only: Option<Format>,
    /// Whether tiles outside the coverage may still be had (downloaded when asked for).
    pub open_ended: bool,
    /// The SRTM cells whose terrain it has at its zoom; `None` when it offers no terrain layer.
    /// The coarser zooms it makes glb at for far views, finest first (none for an archive).
    pub far_zooms: Vec<u8>,
}

/// Whether a tile can be had now.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Availability {
    Ready,
    /// Once [`TileProvider::fetch`] has downloaded what it lacks.
    AfterFetch,
    /// Never: why not.
    Missing(String),
}

/// Why a tile cannot be had.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Unavailable {
    /// Its zoom, or its format, is not offered.
    #[error("{0}")]
    NotOffered(String),
    /// The data does not cover it.
    #[error("{0}")]
    NotCovered(String),
    /// A download it needs failed.
    #[error("{0}")]
    FetchFailed(String),
}

/// A source of tiles: the core every provider has, and the capabilities some add
/// ([`Fetching`], [`Explaining`], [`Reloading`]). Every method but [`TileProvider::offer`],
/// [`TileProvider::resolve`], [`TileProvider::availability`] and the capabilities' accessors
/// may block (read files or a store, render): call them off the async executor.
pub trait TileProvider: Send + Sync + std::fmt::Debug {
    /// What it offers.
    fn offer(&self) -> Offer;

    /// The key a request for `tile` in `format` is served under, or why it is not offered.
    fn resolve(&self, tile: TileId, format: Format) -> Result<TileKey, Unavailable>;

    /// Whether `key` can be had now.
    fn availability(&self, key: TileKey) -> Availability;

    /// What a tile made now would be made from: a stored tile made otherwise is stale. `None`
    /// when the provider makes no tiles (held tiles are never stale). May block: a store's
    /// provider reads the tile's last diff.
    fn provenance(&self, tile: TileId) -> Option<Provenance>;

    /// Makes the tile, uncompressed.
    fn make(&self, key: TileKey, deadline: Deadline) -> Result<Made, MakeError>;

    /// Makes one tile in several formats (`keys`, all of one tile), uncompressed and in their
    /// order: the bytes [`TileProvider::make`] gives each, made together where the formats
    /// share their work. The keys fail together.
    fn make_together(&self, keys: &[TileKey], deadline: Deadline) -> Result<Vec<Made>, MakeError> {
        keys.iter().map(|key| self.make(*key, deadline)).collect()
    }

    /// Whether the tile holds any of the sources' data; one that holds none (a coarse
    /// terrain tile over the open sea, far from every SRTM file) is cheap to make again and is
    /// not kept in the durable cache, so that no one can fill it with such tiles.
    fn holds_data(&self, key: TileKey) -> bool {
        let _ = key;
        true
    }

    /// The quantized-mesh terrain layer offered, if any.
    fn terrain_layer(&self) -> Option<crate::output::layer::TerrainLayer> {
        None
    }

    /// Lowest and highest ground under a tile, metres, for a bounding volume: sampled at the
    /// provider's zoom, the whole source files' range at coarser ones.
    fn ground_range(&self, tile: TileId) -> Option<(f64, f64)> {
        let _ = tile;
        None
    }

    /// What `/ready` says of it.
    fn status(&self) -> serde_json::Value;

    /// Its downloads of what tiles lack, if it downloads.
    fn fetching(&self) -> Option<&dyn Fetching> {
        None
    }

    /// Its view into how a tile was made, if it makes tiles.
    fn explaining(&self) -> Option<&dyn Explaining> {
        None
    }

    /// How it follows its inputs as they change, if they can.
    fn reloading(&self) -> Option<&dyn Reloading> {
        None
    }
}
