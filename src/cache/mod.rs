//! Tile cache: an in-memory `moka` cache (weighed in bytes) in front of the SQLite store.
//!
//! [`TileCache::get_or_render`] looks in memory, then in SQLite, then renders. Concurrent
//! requests for the same missing tile share one lookup and one render (moka coalesces the
//! initialisation of a key), and both the lookup and the render run on the blocking pool, never
//! on the async executor.

pub mod store;

use std::sync::Arc;

use axum::body::Bytes;
use sha2::Digest;

use crate::output::quantized_mesh::Extensions;
use crate::tile::TileId;
pub use store::{StoreError, StoredTile, TileStore};

/// The formats tiles are made in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Format {
    Glb,
    /// quantized-mesh-1.0 with the extensions asked for, stored gzipped.
    Terrain(Extensions),
}

impl Format {
    pub fn as_str(self) -> &'static str {
        match self {
            Format::Glb => "glb",
            Format::Terrain(extensions) => extensions.key(),
        }
    }

    /// The file extension in URLs.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Glb => "glb",
            Format::Terrain(_) => "terrain",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TileKey {
    pub tile: TileId,
    pub format: Format,
}

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
    /// Shared, so a response costs a reference count, not a copy.
    pub data: Bytes,
    pub etag: String,
    /// Where the tile was found when it entered memory.
    pub loaded_from: Origin,
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
    Render(E),
    #[error("rendering failed unexpectedly: {0}")]
    Panicked(String),
}

#[derive(Clone)]
pub struct TileCache {
    memory: moka::future::Cache<TileKey, Arc<CachedTile>>,
    store: Arc<TileStore>,
    pipeline: Arc<str>,
}

impl std::fmt::Debug for TileCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TileCache")
            .field("store", &self.store)
            .field("pipeline", &self.pipeline)
            .finish()
    }
}

impl TileCache {
    /// `pipeline` identifies the code and settings that render tiles; stored tiles made by
    /// another pipeline are not served.
    pub fn new(store: TileStore, memory_bytes: u64, pipeline: String) -> TileCache {
        let memory = moka::future::Cache::builder()
            .weigher(|_key: &TileKey, tile: &Arc<CachedTile>| -> u32 {
                tile.data.len().try_into().unwrap_or(u32::MAX)
            })
            .max_capacity(memory_bytes)
            .build();
        TileCache {
            memory,
            store: Arc::new(store),
            pipeline: pipeline.into(),
        }
    }

    pub fn store(&self) -> &TileStore {
        &self.store
    }

    /// The tile from memory, SQLite or `render` (run on the blocking pool), with where it came
    /// from. Concurrent calls for one key run one lookup and at most one render.
    pub async fn get_or_render<F, E>(
        &self,
        key: TileKey,
        render: F,
    ) -> Result<(Arc<CachedTile>, Origin), Arc<CacheError<E>>>
    where
        F: FnOnce() -> Result<Vec<u8>, E> + Send + 'static,
        E: std::error::Error + Send + Sync + 'static,
    {
        let store = self.store.clone();
        let pipeline = self.pipeline.clone();
        let init = async move {
            let lookup = {
                let (store, pipeline) = (store.clone(), pipeline.clone());
                tokio::task::spawn_blocking(move || store.get(&key, &pipeline))
                    .await
                    .map_err(|e| CacheError::Panicked(e.to_string()))??
            };
            if let Some(found) = lookup {
                return Ok(Arc::new(CachedTile {
                    data: Bytes::from(found.data),
                    etag: found.etag,
                    loaded_from: Origin::Store,
                }));
            }
            let rendered = tokio::task::spawn_blocking(move || {
                let data = render().map_err(CacheError::Render)?;
                let stored = StoredTile {
                    etag: etag_of(&data),
                    data,
                };
                store.put(&key, &pipeline, &stored)?;
                Ok::<_, CacheError<E>>(stored)
            })
            .await
            .map_err(|e| CacheError::Panicked(panic_message(e)))??;
            Ok(Arc::new(CachedTile {
                data: Bytes::from(rendered.data),
                etag: rendered.etag,
                loaded_from: Origin::Rendered,
            }))
        };
        let entry = self.memory.entry(key).or_try_insert_with(init).await?;
        let origin = if entry.is_fresh() {
            entry.value().loaded_from
        } else {
            Origin::Memory
        };
        Ok((entry.into_value(), origin))
    }
}

fn panic_message(error: tokio::task::JoinError) -> String {
    match error.try_into_panic() {
        Ok(payload) => crate::render::panic_text(payload.as_ref()),
        Err(error) => error.to_string(),
    }
}
