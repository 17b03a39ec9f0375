//! What some providers can do beyond making tiles: download what a tile lacks, show how a
//! tile's elevations were settled, and follow their inputs as they change. A provider offers
//! each through [`super::TileProvider::fetching`], [`super::TileProvider::explaining`] and
//! [`super::TileProvider::reloading`]; one that cannot (an archive) offers none, and its callers
//! say so instead of calling a method that does nothing.

use std::sync::Arc;

use super::{FetchStats, MakeError, TileProvider, Unavailable};
use crate::tile::TileId;

/// Downloads the source files a tile lacks.
pub trait Fetching {
    /// Downloads what `tile` lacks, when [`super::TileProvider::availability`] says
    /// [`super::Availability::AfterFetch`]. Blocks.
    fn fetch(&self, tile: TileId) -> Result<(), Unavailable>;

    /// Counters of the downloads, when it has a downloader.
    fn downloads(&self) -> Option<&FetchStats>;
}

/// A view into how a tile was made.
pub trait Explaining {
    /// A GeoJSON view of how a tile's elevations were settled. Blocks.
    fn explain(&self, tile: TileId) -> Result<Vec<u8>, MakeError>;
}

/// Inputs that change while the provider serves: files rewritten, a store that follows a
/// replication source.
pub trait Reloading {
    /// A provider on the inputs as they are now, when they changed since this one opened them
    /// (an extract rewritten, an SRTM file added or replaced, a diff applied to its store);
    /// `None` when nothing changed. Changes nothing itself. Blocks.
    fn reopened(&self) -> Result<Option<Arc<dyn TileProvider>>, String>;

    /// Applies to its store the diffs of its replication source the store lacks (a few at a
    /// time: the rest follow at the next call); returns how many it applied. Without a store
    /// or a source it applies none. Failures are logged: the store stays at the last diff
    /// applied. Blocks.
    fn catch_up(&self) -> usize;
}

/// Fetches what `tile` lacks if the provider can; one that cannot fetch has nothing to fetch.
pub fn fetch(provider: &dyn TileProvider, tile: TileId) -> Result<(), Unavailable> {
    match provider.fetching() {
        Some(fetching) => fetching.fetch(tile),
        None => Ok(()),
    }
}
