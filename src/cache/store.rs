//! What a durable tile store does, whatever keeps the bytes: [`TileStore`], in SQLite (one
//! file, the default: [`super::sqlite::SqliteStore`]) or PostgreSQL (shared by several
//! processes: [`super::postgres::PostgresStore`]).

use std::path::PathBuf;

use super::encoding::{Bodies, CodingError};
use crate::format::TileKey;
use crate::tile::{TileId, TileRange};

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("tile cache {path}: {source}")]
    Sqlite {
        path: PathBuf,
        #[source]
        source: rusqlite::Error,
    },
    #[error("tile cache {place}: {source}")]
    Postgres {
        place: String,
        #[source]
        source: postgres::Error,
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
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("tile cache {path} is damaged: {report}")]
    Damaged { path: PathBuf, report: String },
    #[error(transparent)]
    Coding(#[from] CodingError),
    #[error("{path} is read-only: tiles are served from it, never written to it")]
    ReadOnly { path: PathBuf },
    #[error("tile cache work failed unexpectedly: {0}")]
    Panicked(String),
}

impl StoreError {
    /// Whether the error tells of a damaged file (rather than a full disk, a lock, a newer
    /// schema).
    pub fn is_damage(&self) -> bool {
        match self {
            StoreError::Damaged { .. } => true,
            StoreError::Sqlite { source, .. } => matches!(
                source.sqlite_error_code(),
                Some(rusqlite::ErrorCode::DatabaseCorrupt | rusqlite::ErrorCode::NotADatabase)
            ),
            _ => false,
        }
    }
}

/// What a tile was made from: the rendering pipeline and the versions of the sources.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Provenance {
    pub pipeline: String,
    pub sources: String,
}

/// A tile as stored.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StoredTile {
    pub bodies: Bodies,
    /// Strong validator of the identity body.
    pub etag: String,
    pub made_by: Provenance,
    /// Seconds since the Unix epoch.
    pub created_at: i64,
}

/// A stored tile's bookkeeping, without its bytes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StoredEntry {
    pub key: TileKey,
    pub made_by: Provenance,
    /// Bytes stored.
    pub size: u64,
    /// When it was last served, seconds since the Unix epoch.
    pub accessed_at: i64,
}

/// Which stored tiles an operation applies to.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TileFilter {
    All,
    Range(TileRange),
    /// Named tiles; a list longer than a few dozen must be sorted ([`TileFilter::tiles`]):
    /// [`TileFilter::matches`] searches it.
    Tiles(Vec<TileId>),
}

/// Lists of tiles up to this long are scanned; longer ones searched, when sorted.
const SCANNED: usize = 32;

impl TileFilter {
    /// A filter of the tiles listed, sorted and each once.
    pub fn tiles(mut tiles: Vec<TileId>) -> TileFilter {
        tiles.sort_unstable();
        tiles.dedup();
        TileFilter::Tiles(tiles)
    }

    pub fn matches(&self, tile: TileId) -> bool {
        match self {
            TileFilter::All => true,
            TileFilter::Range(range) => range.contains(tile),
            TileFilter::Tiles(tiles) if tiles.len() > SCANNED => {
                debug_assert!(tiles.is_sorted(), "a long list of tiles is sorted");
                tiles.binary_search(&tile).is_ok()
            }
            TileFilter::Tiles(tiles) => tiles.contains(&tile),
        }
    }
}

/// The largest tile a store gives unless told otherwise ([`crate::cache`]'s stores take
/// `cache.max_tile_mib`): 64 MiB, where a zoom-14 tile of a dense city is a few MiB.
pub const DEFAULT_MAX_TILE_BYTES: u64 = 64 << 20;

/// How much a store holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Usage {
    pub tiles: u64,
    pub bytes: u64,
}

/// A solved component of the elevation LP as a store keeps it: its digest and its encoded
/// solution, opaque to the store.
pub type SolutionEntry = ([u8; 32], Vec<u8>);

/// Where rendered tiles are read from: a durable store, or an exported archive that is all
/// there is of its tiles. Every call is blocking; callers on the async executor run them on
/// the blocking pool.
pub trait TileReader: Send + Sync + std::fmt::Debug {
    /// The stored tile, whatever made it (the caller decides whether it is stale).
    fn get(&self, key: &TileKey) -> Result<Option<StoredTile>, StoreError>;
    /// The matching tiles, most recently served first.
    fn list(&self, filter: &TileFilter) -> Result<Vec<StoredEntry>, StoreError>;
    /// Each matching tile in turn, in [`TileReader::list`]'s order; a store that holds runs of
    /// tiles under one entry (an archive) walks them without listing them.
    fn each(
        &self,
        filter: &TileFilter,
        visit: &mut dyn FnMut(StoredEntry),
    ) -> Result<(), StoreError> {
        for entry in self.list(filter)? {
            visit(entry);
        }
        Ok(())
    }
    fn usage(&self) -> Result<Usage, StoreError>;
    /// Up to `limit` solved components of the elevation LP kept beside the tiles, newest first,
    /// as (digest, encoded solution): opaque to the store. A store that keeps none has none.
    fn solutions(&self, limit: usize) -> Result<Vec<SolutionEntry>, StoreError> {
        let _ = limit;
        Ok(Vec::new())
    }
}

/// A durable home for rendered tiles: read, and written as tiles are made, served and purged.
pub trait TileStore: TileReader {
    /// Stores a tile in one step, replacing the one before: a reader sees the old tile or the
    /// new one, never a mix. May evict the least recently used tiles to stay under a size cap.
    fn put(&self, key: &TileKey, tile: &StoredTile) -> Result<(), StoreError>;
    /// As [`TileStore::put`] where the store holds no tile of `key`, or holds this one (the
    /// same validator) in other forms; false, and nothing written, where it holds another (one
    /// stored since this one was begun).
    fn put_if_vacant(&self, key: &TileKey, tile: &StoredTile) -> Result<bool, StoreError>;
    /// Records that tiles were served at `at` (seconds since the Unix epoch).
    fn touch(&self, keys: &[TileKey], at: i64) -> Result<(), StoreError>;
    /// Removes the matching tiles and names them.
    fn remove(&self, filter: &TileFilter) -> Result<Vec<TileKey>, StoreError>;
    /// Keeps solved components for later renders (bounded; an entry already kept stays).
    fn keep_solutions(&self, entries: &[SolutionEntry]) -> Result<(), StoreError> {
        let _ = entries;
        Ok(())
    }
}

/// Says that a store over its size cap evicted tiles (nothing when it evicted none).
pub(super) fn log_eviction(evicted: u64, cap: Option<u64>) {
    if evicted > 0 {
        tracing::info!(
            evicted,
            cap,
            "cache over its size cap; least recently served tiles evicted"
        );
    }
}

/// Now, in seconds since the Unix epoch.
pub fn unix_now() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs() as i64)
        .unwrap_or(0)
}
