//! Tile cache: an in-memory `moka` cache (weighed in bytes) in front of a durable
//! [`TileStore`] (SQLite).
//!
//! [`TileCache::get_or_render`] looks in memory, then in the store, then renders. Concurrent
//! requests for the same missing tile share one lookup and one render (moka coalesces the
//! initialisation of a key), and both run on the blocking pool, never on the async executor.
//! Every tile carries what it was made from ([`Provenance`]); a tile made by another pipeline
//! or from other source versions is *stale*: it is still served, and [`TileCache::remake`]
//! makes its replacement and swaps it in whole.

pub mod archive;
pub mod coordinator;
pub mod encoding;
mod flight;
pub mod postgres;
mod refine;
pub mod sqlite;
pub mod store;

use std::collections::HashSet;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use sha2::Digest;

use crate::format::TileKey;
pub use archive::mbtiles::MbtilesStore;
pub use archive::pmtiles::PmtilesStore;
pub use archive::{open_archive, ArchiveStore, Contents};
pub use coordinator::{Coordinator, Event, Local};
use encoding::{Accepted, Bodies};
pub use postgres::PostgresStore;
pub use sqlite::SqliteStore;
pub use store::{
    unix_now, Provenance, SolutionEntry, StoreError, StoredEntry, StoredTile, TileFilter,
    TileReader, TileStore, Usage,
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
            Origin::Store => "store",
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
    /// Whether the durable store holds it (a tile that could not be stored, its disk full, is
    /// served from memory only; a tile answered in haste is stored a moment later, see
    /// [`refine`]).
    pub stored: bool,
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

/// What a cache keeps its tiles in.
#[derive(Clone, Debug)]
enum Held {
    /// A store: read, written as tiles are made, its served tiles recorded.
    Store(Arc<dyn TileStore>),
    /// An exported archive at a path: read only, and all there is of its tiles.
    Archive(Arc<dyn TileReader>, Arc<std::path::Path>),
}

impl Held {
    fn reader(&self) -> Arc<dyn TileReader> {
        match self {
            Held::Store(store) => store.clone(),
            Held::Archive(archive, _) => archive.clone(),
        }
    }

    fn writer(&self) -> Result<&Arc<dyn TileStore>, StoreError> {
        match self {
            Held::Store(store) => Ok(store),
            Held::Archive(_, path) => Err(StoreError::ReadOnly {
                path: path.to_path_buf(),
            }),
        }
    }
}

#[derive(Clone)]
pub struct TileCache {
    memory: moka::future::Cache<TileKey, Arc<CachedTile>>,
    store: Held,
    /// Tiles served from memory since the store last heard of it.
    touched: Arc<Mutex<HashSet<TileKey>>>,
    /// Lookups and renders under way, by key.
    flights: Arc<flight::Flights>,
    /// Requests waiting for a tile to be looked up or made.
    waiting: Arc<AtomicUsize>,
    /// Purges lately made, so a tile made again from before one is not stored after it.
    purges: Arc<Mutex<Purges>>,
    /// Tiles answered in haste whose forms kept are being made.
    refining: Arc<refine::Refining>,
    /// How the processes sharing the store share its work: a tile is claimed before it is
    /// made, and purges and new versions are told to the others.
    coordinator: Arc<dyn Coordinator>,
}

/// How often a process waiting for another's render of a tile looks for it in the store.
const LANDING_POLL: std::time::Duration = std::time::Duration::from_millis(50);

/// How long a purge is remembered; a remake begun before the oldest purge remembered is not
/// stored if any purge came since.
const PURGE_MEMORY: std::time::Duration = std::time::Duration::from_secs(3600);

/// The purges made lately, numbered in order.
#[derive(Debug, Default)]
struct Purges {
    /// How many purges were made.
    made: u64,
    /// The last ones: number, when, and what each removed.
    recent: std::collections::VecDeque<(u64, std::time::Instant, TileFilter)>,
}

impl Purges {
    /// Whether a purge numbered above `since` removed `key`'s tile (or may have: it is
    /// forgotten).
    fn purged_since(&self, since: u64, key: &TileKey) -> bool {
        let oldest_remembered = self.recent.front().map_or(self.made + 1, |p| p.0);
        if since + 1 < oldest_remembered && since < self.made {
            return true;
        }
        self.recent
            .iter()
            .any(|(number, _, filter)| *number > since && filter.matches(key.tile))
    }
}

impl std::fmt::Debug for TileCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TileCache")
            .field("store", &self.store)
            .finish()
    }
}

/// One request counted as waiting for as long as it waits, even when it is dropped.
struct Waiting<'a>(&'a AtomicUsize);

impl<'a> Waiting<'a> {
    fn on(count: &'a AtomicUsize) -> Waiting<'a> {
        count.fetch_add(1, Ordering::SeqCst);
        Waiting(count)
    }
}

impl Drop for Waiting<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Makes a tile's body, identity-coded.
type Render<E> = Box<dyn FnOnce() -> Result<Vec<u8>, E> + Send>;

/// A render that gave no tile though no purge was asked for it.
fn dropped<E: std::error::Error>() -> CacheError<E> {
    CacheError::Panicked("a tile was dropped unasked".into())
}

impl TileCache {
    /// A cache over a store it reads and writes.
    pub fn new(store: Arc<dyn TileStore>, memory_bytes: u64) -> TileCache {
        TileCache::holding(Held::Store(store), memory_bytes)
    }

    /// A cache over an exported archive: it serves the archive's tiles and stores nothing.
    pub fn reading(archive: Arc<dyn ArchiveStore>, memory_bytes: u64) -> TileCache {
        let path: Arc<std::path::Path> = Arc::from(archive.path());
        TileCache::holding(Held::Archive(archive, path), memory_bytes)
    }

    fn holding(store: Held, memory_bytes: u64) -> TileCache {
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
            flights: Arc::default(),
            waiting: Arc::default(),
            purges: Arc::default(),
            refining: Arc::default(),
            coordinator: Arc::new(Local::new()),
        }
    }

    /// Requests waiting now for a tile to be looked up or made: each request for a tile under
    /// way waits here, and one make serves them all.
    pub fn waiting(&self) -> usize {
        self.waiting.load(Ordering::SeqCst)
    }

    /// The same cache, its renders, purges and new versions coordinated by `coordinator` (a
    /// new cache is the only process of its store).
    pub fn coordinated_by(self, coordinator: Arc<dyn Coordinator>) -> TileCache {
        TileCache {
            coordinator,
            ..self
        }
    }

    pub fn coordinator(&self) -> &Arc<dyn Coordinator> {
        &self.coordinator
    }

    /// Where its tiles are read from.
    pub fn reader(&self) -> Arc<dyn TileReader> {
        self.store.reader()
    }

    /// Its store, to write to; an archive is read only.
    pub fn writer(&self) -> Result<&Arc<dyn TileStore>, StoreError> {
        self.store.writer()
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
        self.get_or_render_kept(key, wanted, true, None, render)
            .await
    }

    /// As [`TileCache::get_or_render`]; with `keep` false a tile made now is held in memory
    /// only, never stored (a tile that holds no data). With `answer`, what the client asking
    /// accepts: a tile made now for it is answered in that coding made fast, and its forms
    /// kept are made afterwards (see [`refine`]); a client that accepts a coding such a
    /// tile lacks waits for them.
    pub async fn get_or_render_kept<F, E>(
        &self,
        key: TileKey,
        wanted: Option<&Provenance>,
        keep: bool,
        answer: Option<Accepted>,
        render: F,
    ) -> Result<Served, Arc<CacheError<E>>>
    where
        F: FnOnce() -> Result<Vec<u8>, E> + Send + 'static,
        E: std::error::Error + Send + Sync + 'static,
    {
        let held = self.store.clone();
        let coordinator = self.coordinator.clone();
        let made_by = wanted.cloned().unwrap_or_default();
        let refining = self.refining.clone();
        let memory = self.memory.clone();
        let purges = self.purges.clone();
        let since = self.purges_so_far();
        let lookup_or_render = async move {
            // A tile answered in haste is stored once its forms kept are made.
            if let Some(quick) = refining.quick(&key, &purges) {
                return Ok(quick);
            }
            if let Some(found) = lookup(&held, key).await? {
                return Ok(Arc::new(found));
            }
            let store = held.writer().ok().filter(|_| keep).cloned();
            // A process alone with its store claims nothing: the single flight here is the
            // whole of it. The processes of a cluster read each other's tiles from the store
            // as soon as they land, so they store them with their forms kept at once.
            let made = match store {
                Some(store) if !coordinator.alone() => {
                    render_claimed(coordinator, store, key, made_by, Box::new(render)).await?
                }
                store if answer.is_some() => {
                    let quick =
                        render_and_store(None, key, made_by, None, answer, Box::new(render))
                            .await?
                            .ok_or_else(dropped)?;
                    let quick = Arc::new(quick);
                    refining.start(refine::Refinement {
                        key,
                        tile: quick.clone(),
                        store,
                        memory,
                        purges,
                        since,
                        created_at: unix_now(),
                    });
                    return Ok(quick);
                }
                store => render_and_store(store, key, made_by, None, None, Box::new(render))
                    .await?
                    .ok_or_else(dropped)?,
            };
            // Made here, or found in the store once another process made it.
            Ok(Arc::new(made))
        };
        // Detached and shared: when the request that started it goes away, the render it paid
        // a slot for still ends in the store, and a request that comes meanwhile waits for it
        // rather than starting another.
        let flights = self.flights.clone();
        let init = async move { flights.join_or_start(key, lookup_or_render).await };
        let waiting = Waiting::on(&self.waiting);
        let entry = self
            .memory
            .entry(key)
            .or_try_insert_with(init)
            .await
            .map_err(|shared| (*shared).clone())?;
        drop(waiting);
        let origin = if entry.is_fresh() {
            entry.value().loaded_from
        } else {
            self.touched
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .insert(key);
            Origin::Memory
        };
        let mut tile = entry.into_value();
        if answer.is_some_and(|accepted| tile.bodies.awaits_better_for(&accepted)) {
            if let Some(refined) = self.refining.wait(&key).await {
                if refined.etag == tile.etag {
                    tile = refined;
                }
            }
        }
        Ok(Served {
            stale: wanted.is_some_and(|wanted| tile.made_by != *wanted),
            tile,
            origin,
        })
    }

    /// Tiles answered in haste whose forms kept are being made now.
    pub fn refining(&self) -> usize {
        self.refining.len()
    }

    /// Waits until the forms kept of every tile answered in haste so far are made (and
    /// stored).
    pub async fn refined(&self) {
        self.refining.all_ended().await
    }

    /// Waits until the tile of `key`, if it was answered in haste, is stored with its forms
    /// kept.
    pub async fn refined_one(&self, key: &TileKey) {
        self.refining.wait(key).await;
    }

    /// Tiles answered in haste that the store then could not take, so far (served from
    /// memory).
    pub fn unstored_after_answer(&self) -> u64 {
        self.refining.unstored()
    }

    /// How many purges were made so far: give it to [`TileCache::remake`] for a tile chosen
    /// now.
    pub fn purges_so_far(&self) -> u64 {
        self.purges.lock().unwrap_or_else(|p| p.into_inner()).made
    }

    /// Makes a tile again with `render` and swaps it in (store, then memory) when it is done;
    /// until then, and if it fails, the old tile is served. A purge of the tile made after
    /// `purges_so_far` wins: the new tile is then dropped, not stored.
    pub async fn remake<F, E>(
        &self,
        key: TileKey,
        wanted: Provenance,
        purges_so_far: u64,
        render: F,
    ) -> Result<Remade, CacheError<E>>
    where
        F: FnOnce() -> Result<Vec<u8>, E> + Send + 'static,
        E: std::error::Error + Send + Sync + 'static,
    {
        let purges = Some((self.purges.clone(), purges_so_far));
        let store = self.store.writer().ok().cloned();
        match render_and_store(store, key, wanted, purges, None, Box::new(render)).await? {
            Some(tile) => {
                let remade = if tile.stored {
                    Remade::Stored
                } else {
                    Remade::Unstored
                };
                self.memory.insert(key, Arc::new(tile)).await;
                if remade == Remade::Stored {
                    self.tell(Event::Stored(vec![key])).await;
                }
                Ok(remade)
            }
            None => Ok(Remade::Purged),
        }
    }

    /// Removes the tiles `filter` selects from the store and from memory; a remake of one of
    /// them under way is not stored. Returns the keys removed.
    pub async fn purge(&self, filter: TileFilter) -> Result<Vec<TileKey>, StoreError> {
        self.record_purge(filter.clone());
        // A tile answered in haste is in memory before it is in the store.
        let refining = self.refining.keys_matching(&filter);
        let all = filter == TileFilter::All;
        let store = self.store.writer()?.clone();
        let removing = filter.clone();
        let removed = tokio::task::spawn_blocking(move || store.remove(&removing))
            .await
            .map_err(|e| StoreError::Panicked(panic_message(e)))??;
        if all {
            self.forget_all();
        } else {
            self.forget(&removed).await;
            self.forget(&refining).await;
        }
        self.tell(Event::Purged(filter)).await;
        // The tiles answered in haste that it keeps out of the store count as removed.
        let unstored: Vec<TileKey> = refining
            .into_iter()
            .filter(|key| !removed.contains(key))
            .collect();
        let mut removed = removed;
        removed.extend(unstored);
        Ok(removed)
    }

    /// Remembers a purge, so a remake under way of a tile it removed is not stored.
    fn record_purge(&self, filter: TileFilter) {
        let mut purges = self.purges.lock().unwrap_or_else(|p| p.into_inner());
        purges.made += 1;
        let number = purges.made;
        purges
            .recent
            .push_back((number, std::time::Instant::now(), filter));
        while purges
            .recent
            .front()
            .is_some_and(|p| p.1.elapsed() > PURGE_MEMORY)
        {
            purges.recent.pop_front();
        }
    }

    /// Tells the other processes sharing the store, if there are any (a failure is logged: their
    /// memory then holds a tile longer, until its next broadcast or eviction).
    async fn tell(&self, event: Event) {
        if self.coordinator.alone() {
            return;
        }
        let coordinator = self.coordinator.clone();
        let told = tokio::task::spawn_blocking(move || coordinator.broadcast(&event)).await;
        if let Ok(Err(error)) = told {
            tracing::warn!(%error, "telling the other processes failed");
        }
    }

    /// Applies what another process of the cluster told: its new tiles and purges leave
    /// memory (a purge is also remembered, as one made here would be).
    pub async fn heard(&self, event: Event) {
        match event {
            Event::Stored(keys) => self.forget(&keys).await,
            Event::Purged(TileFilter::All) | Event::Missed => {
                self.record_purge(TileFilter::All);
                self.forget_all();
            }
            Event::Purged(filter) => {
                self.record_purge(filter.clone());
                let held: Vec<TileKey> = self
                    .memory
                    .iter()
                    .map(|(key, _)| *key)
                    .filter(|key| filter.matches(key.tile))
                    .collect();
                self.forget(&held).await;
            }
            Event::Work => {}
        }
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
        // An archive records nothing.
        let Ok(store) = self.store.writer() else {
            return Ok(());
        };
        if keys.is_empty() {
            return Ok(());
        }
        let store = store.clone();
        tokio::task::spawn_blocking(move || store.touch(&keys, unix_now()))
            .await
            .unwrap_or_else(|e| {
                tracing::warn!(error = %e, "recording served tiles failed");
                Ok(())
            })
    }
}

/// What a remake came to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Remade {
    /// The new tile is stored and served.
    Stored,
    /// The new tile is served from memory, but could not be stored.
    Unstored,
    /// The tile was purged while it was made: the new one is dropped.
    Purged,
}

/// The stored tile, marked as read from the store (and its use recorded). A store that cannot
/// be read (damaged, its disk gone) does not stop the tile: it is made again.
async fn lookup<E>(held: &Held, key: TileKey) -> Result<Option<CachedTile>, CacheError<E>>
where
    E: std::error::Error + Send + Sync + 'static,
{
    let reading = held.clone();
    let lookup = tokio::task::spawn_blocking(move || {
        let found = reading.reader().get(&key)?;
        if let (Some(_), Ok(store)) = (&found, reading.writer()) {
            store.touch(&[key], unix_now())?;
        }
        Ok::<_, StoreError>(found)
    })
    .await
    .map_err(|e| CacheError::Panicked(e.to_string()))?;
    let found = match lookup {
        Ok(found) => found,
        // An archive is all there is of its tiles: one it cannot read is not made again.
        Err(error) if matches!(held, Held::Archive(..)) => return Err(CacheError::Store(error)),
        Err(error) => {
            tracing::error!(tile = %key.tile, format = key.format.as_str(), %error, "reading the stored tile failed; making it again");
            None
        }
    };
    Ok(found.map(|found| CachedTile {
        bodies: found.bodies,
        etag: found.etag,
        made_by: found.made_by,
        loaded_from: Origin::Store,
        stored: true,
    }))
}

/// Makes and stores a tile once among the processes sharing the store: claims it first; while
/// another process holds the claim, waits for the tile to land in the store (or for the claim
/// to lapse, its holder gone, and takes it over).
async fn render_claimed<E>(
    coordinator: Arc<dyn Coordinator>,
    store: Arc<dyn TileStore>,
    key: TileKey,
    made_by: Provenance,
    render: Render<E>,
) -> Result<CachedTile, CacheError<E>>
where
    E: std::error::Error + Send + Sync + 'static,
{
    loop {
        let claiming = coordinator.clone();
        let claim = tokio::task::spawn_blocking(move || claiming.claim(&key))
            .await
            .map_err(|e| CacheError::Panicked(panic_message(e)))?;
        match claim {
            Ok(true) => {
                // It may have landed between the lookup and the claim.
                let made = match lookup(&Held::Store(store.clone()), key).await? {
                    Some(found) => Ok(found),
                    None => render_and_store(Some(store), key, made_by, None, None, render)
                        .await
                        .and_then(|made| made.ok_or_else(dropped)),
                };
                let releasing = coordinator.clone();
                let released = tokio::task::spawn_blocking(move || releasing.release(&key)).await;
                if let Ok(Err(error)) = released {
                    tracing::warn!(tile = %key.tile, %error, "releasing the claim on a tile failed; it lapses");
                }
                return made;
            }
            Ok(false) => {}
            Err(error) => {
                tracing::warn!(tile = %key.tile, %error, "claiming the tile failed; made here");
                return render_and_store(Some(store), key, made_by, None, None, render)
                    .await
                    .and_then(|made| made.ok_or_else(dropped));
            }
        }
        tokio::time::sleep(LANDING_POLL).await;
        if let Some(found) = lookup(&Held::Store(store.clone()), key).await? {
            return Ok(found);
        }
    }
}

/// Renders a tile on the blocking pool, compresses it and stores it (when given a store); with
/// `purges`, not when a purge numbered past the one given removed it meanwhile (then `None`).
/// With `quick`, what the client waiting accepts: only the form it takes is made, fast
/// ([`Bodies::quick`]); else every form kept.
async fn render_and_store<E>(
    store: Option<Arc<dyn TileStore>>,
    key: TileKey,
    made_by: Provenance,
    purges: Option<(Arc<Mutex<Purges>>, u64)>,
    quick: Option<Accepted>,
    render: Render<E>,
) -> Result<Option<CachedTile>, CacheError<E>>
where
    E: std::error::Error + Send + Sync + 'static,
{
    tokio::task::spawn_blocking(move || {
        let data = render().map_err(CacheError::Render)?;
        let etag = etag_of(&data);
        let bodies = match quick {
            Some(accepted) => Bodies::quick(data, &accepted)?,
            None => Bodies::compress(data)?,
        };
        let stored = StoredTile {
            etag,
            bodies,
            made_by,
            created_at: unix_now(),
        };
        // Checked and stored under the purges' lock: a purge is recorded either before (the
        // tile is dropped) or after (its removal finds the tile).
        let guard = purges
            .as_ref()
            .map(|(purges, since)| (purges.lock().unwrap_or_else(|p| p.into_inner()), *since));
        if let Some((purges, since)) = &guard {
            if purges.purged_since(*since, &key) {
                return Ok(None);
            }
        }
        // A tile that cannot be stored (disk full, store damaged) is served all the same.
        let kept = match store.as_ref().map(|store| store.put(&key, &stored)) {
            Some(Ok(())) => true,
            None => false,
            Some(Err(error)) => {
                tracing::warn!(tile = %key.tile, format = key.format.as_str(), %error, "the tile could not be stored; served from memory only");
                false
            }
        };
        drop(guard);
        Ok(Some(CachedTile {
            bodies: stored.bodies,
            etag: stored.etag,
            made_by: stored.made_by,
            loaded_from: Origin::Rendered,
            stored: kept,
        }))
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
