//! Tile cache: an in-memory `moka` cache (weighed in bytes) in front of a durable
//! [`TileStore`] (SQLite).
//!
//! [`TileCache::get_or_render`] looks in memory, then in the store, then renders. Concurrent
//! requests for the same missing tile share one lookup and one render (moka coalesces the
//! initialisation of a key), and both run on the blocking pool, never on the async executor.
//! Every tile carries what it was made from ([`Provenance`]); a tile made by another pipeline
//! or from other source versions is *stale*: it is still served, and [`TileCache::remake`]
//! makes its replacement and swaps it in whole.

pub mod encoding;
pub mod mbtiles;
pub mod sqlite;
pub mod store;

use std::collections::HashSet;
use std::sync::{Arc, Mutex};

use sha2::Digest;

use crate::format::TileKey;
use encoding::Bodies;
pub use mbtiles::MbtilesStore;
pub use sqlite::SqliteStore;
pub use store::{
    unix_now, Provenance, SolutionEntry, StoreError, StoredEntry, StoredTile, TileFilter,
    TileStore, Usage,
};

/// Where a response came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Origin {
    Memory,
    Store,
    Rendered,
}

impl Origin {
    pub fn as_str(self) -> &'static str {
        match self {
            Origin::Memory => "memory",
            Origin::Store => "sqlite",
            Origin::Rendered => "render",
        }
    }
}

/// A cached tile.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CachedTile {
    /// Every coding of the tile, shared, so a response costs a reference count, not a copy.
    pub bodies: Bodies,
    /// Strong validator of the identity body.
    pub etag: String,
    pub made_by: Provenance,
    /// Where the tile was found when it entered memory.
    pub loaded_from: Origin,
}

/// A tile served, and how.
#[derive(Debug, Clone)]
pub struct Served {
    pub tile: Arc<CachedTile>,
    pub origin: Origin,
    /// Made by another pipeline or from other sources than those asked for.
    pub stale: bool,
}

/// A strong ETag from the content.
pub fn etag_of(data: &[u8]) -> String {
    let digest = sha2::Sha256::digest(data);
    let hex: String = digest[..16].iter().map(|b| format!("{b:02x}")).collect();
    format!("\"{hex}\"")
}

/// Why a tile could not be produced.
#[derive(Debug, thiserror::Error)]
pub enum CacheError<E: std::error::Error> {
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Coding(#[from] encoding::CodingError),
    #[error(transparent)]
    Render(E),
    #[error("rendering failed unexpectedly: {0}")]
    Panicked(String),
}

#[derive(Clone)]
pub struct TileCache {
    memory: moka::future::Cache<TileKey, Arc<CachedTile>>,
    store: Arc<dyn TileStore>,
    /// Tiles served from memory since the store last heard of it.
    touched: Arc<Mutex<HashSet<TileKey>>>,
}

impl std::fmt::Debug for TileCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TileCache")
            .field("store", &self.store)
            .finish()
    }
}

/// Makes a tile's body, identity-coded.
type Render<E> = Box<dyn FnOnce() -> Result<Vec<u8>, E> + Send>;

impl TileCache {
    pub fn new(store: Arc<dyn TileStore>, memory_bytes: u64) -> TileCache {
        let memory = moka::future::Cache::builder()
            .weigher(|_key: &TileKey, tile: &Arc<CachedTile>| -> u32 {
                tile.bodies.weight().try_into().unwrap_or(u32::MAX)
            })
            .max_capacity(memory_bytes)
            .build();
        TileCache {
            memory,
            store,
            touched: Arc::default(),
        }
    }

    pub fn store(&self) -> &Arc<dyn TileStore> {
        &self.store
    }

    /// The tile if memory holds it, whatever made it.
    pub async fn peek(&self, key: &TileKey) -> Option<Arc<CachedTile>> {
        self.memory.get(key).await
    }

    /// The tile from memory, the store or `render` (run on the blocking pool), with where it
    /// came from and whether it is stale against `wanted` (never, without one). Concurrent calls
    /// for one key run one lookup and at most one render. A stale tile is returned as it is:
    /// call [`TileCache::remake`] to replace it.
    pub async fn get_or_render<F, E>(
        &self,
        key: TileKey,
        wanted: Option<&Provenance>,
        render: F,
    ) -> Result<Served, Arc<CacheError<E>>>
    where
        F: FnOnce() -> Result<Vec<u8>, E> + Send + 'static,
        E: std::error::Error + Send + Sync + 'static,
    {
        let store = self.store.clone();
        let made_by = wanted.cloned().unwrap_or_default();
        let lookup_or_render = async move {
            let lookup = {
                let store = store.clone();
                tokio::task::spawn_blocking(move || {
                    let found = store.get(&key)?;
                    if found.is_some() {
                        store.touch(&[key], unix_now())?;
                    }
                    Ok::<_, StoreError>(found)
                })
                .await
                .map_err(|e| CacheError::Panicked(e.to_string()))??
            };
            if let Some(found) = lookup {
                return Ok(Arc::new(CachedTile {
                    bodies: found.bodies,
                    etag: found.etag,
                    made_by: found.made_by,
                    loaded_from: Origin::Store,
                }));
            }
            let made = render_and_store(store, key, made_by, Box::new(render)).await?;
            Ok(Arc::new(CachedTile {
                loaded_from: Origin::Rendered,
                ..made
            }))
        };
        // Detached: when the request that started it goes away, the render it paid a slot for
        // still ends in the store.
        let init = async move {
            tokio::spawn(lookup_or_render)
                .await
                .map_err(|e| CacheError::Panicked(panic_message(e)))?
        };
        let entry = self.memory.entry(key).or_try_insert_with(init).await?;
        let origin = if entry.is_fresh() {
            entry.value().loaded_from
        } else {
            self.touched
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .insert(key);
            Origin::Memory
        };
        let tile = entry.into_value();
        Ok(Served {
            stale: wanted.is_some_and(|wanted| tile.made_by != *wanted),
            tile,
            origin,
        })
    }

    /// Makes a tile again with `render` and swaps it in (store, then memory) when it is done;
    /// until then, and if it fails, the old tile is served.
    pub async fn remake<F, E>(
        &self,
        key: TileKey,
        wanted: Provenance,
        render: F,
    ) -> Result<(), CacheError<E>>
    where
        F: FnOnce() -> Result<Vec<u8>, E> + Send + 'static,
        E: std::error::Error + Send + Sync + 'static,
    {
        let tile = render_and_store(self.store.clone(), key, wanted, Box::new(render)).await?;
        self.memory.insert(key, Arc::new(tile)).await;
        Ok(())
    }

    /// Drops tiles from memory (after they were removed from the store).
    pub async fn forget(&self, keys: &[TileKey]) {
        for key in keys {
            self.memory.invalidate(key).await;
        }
    }

    /// Drops every tile from memory.
    pub fn forget_all(&self) {
        self.memory.invalidate_all();
    }

    /// Tells the store which tiles memory served since the last call (for its eviction order).
    pub async fn flush_touches(&self) -> Result<(), StoreError> {
        let keys: Vec<TileKey> =
            std::mem::take(&mut *self.touched.lock().unwrap_or_else(|p| p.into_inner()))
                .into_iter()
                .collect();
        if keys.is_empty() {
            return Ok(());
        }
        let store = self.store.clone();
        tokio::task::spawn_blocking(move || store.touch(&keys, unix_now()))
            .await
            .unwrap_or_else(|e| {
                tracing::warn!(error = %e, "recording served tiles failed");
                Ok(())
            })
    }
}

/// Renders a tile on the blocking pool, compresses it and stores it.
async fn render_and_store<E>(
    store: Arc<dyn TileStore>,
    key: TileKey,
    made_by: Provenance,
    render: Render<E>,
) -> Result<CachedTile, CacheError<E>>
where
    E: std::error::Error + Send + Sync + 'static,
{
    tokio::task::spawn_blocking(move || {
        let data = render().map_err(CacheError::Render)?;
        let stored = StoredTile {
            etag: etag_of(&data),
            bodies: Bodies::compress(data)?,
            made_by,
            created_at: unix_now(),
        };
        store.put(&key, &stored)?;
        Ok(CachedTile {
            bodies: stored.bodies,
            etag: stored.etag,
            made_by: stored.made_by,
            loaded_from: Origin::Rendered,
        })
    })
    .await
    .map_err(|e| CacheError::Panicked(panic_message(e)))?
}

fn panic_message(error: tokio::task::JoinError) -> String {
    match error.try_into_panic() {
        Ok(payload) => crate::panics::text(payload.as_ref()),
        Err(error) => error.to_string(),
    }
}
