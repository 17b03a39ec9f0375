//! Tiles answered in haste. A tile made while a client waits is answered in the one coding it
//! asked for, made at a fast level ([`Bodies::quick`]), before it is stored; then, off the
//! request, its forms are made at the levels kept ([`Bodies::compress`]), the tile is stored
//! with them ([`TileStore::put_if_vacant`]) and swapped into memory. Until then the quick tile
//! is served from here, and a client that accepts a coding it lacks waits for the forms kept.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use tokio::sync::watch;

use super::encoding::Bodies;
use super::{CachedTile, Purges, StoredTile, TileFilter, TileStore};
use crate::format::TileKey;

/// What a refinement ends with: the tile with its forms kept, or none (it failed, or the tile
/// was purged or replaced meanwhile). `None` until it ends.
type Outcome = Option<Option<Arc<CachedTile>>>;

/// A refinement under way: the quick tile, the purges made before it was begun, and where its
/// end is told.
struct UnderWay {
    tile: Arc<CachedTile>,
    since: u64,
    ended: watch::Receiver<Outcome>,
    /// Which refinement this is: one of a tile made again after a purge takes the place of
    /// the one of the purged tile.
    number: u64,
}

/// The refinements under way, by key.
#[derive(Default)]
pub(super) struct Refining {
    under_way: Mutex<HashMap<TileKey, UnderWay>>,
    /// Refinements started so far.
    started: std::sync::atomic::AtomicU64,
    /// Tiles the store could not take once refined (disk full, damaged): memory serves them.
    unstored: std::sync::atomic::AtomicU64,
}

/// A quick tile to refine, and where it goes.
pub(super) struct Refinement {
    pub key: TileKey,
    pub tile: Arc<CachedTile>,
    /// Where it is stored (none for a tile held in memory only).
    pub store: Option<Arc<dyn TileStore>>,
    pub memory: moka::future::Cache<TileKey, Arc<CachedTile>>,
    pub purges: Arc<Mutex<Purges>>,
    /// The purges made before the tile was begun.
    pub since: u64,
    /// When it was made, seconds since the Unix epoch.
    pub created_at: i64,
}

impl Refining {
    /// Starts refining. A tile is made again while its last one is refined only after a
    /// purge removed that one: the new refinement takes its place.
    pub fn start(self: &Arc<Self>, refinement: Refinement) {
        let key = refinement.key;
        let (sender, receiver) = watch::channel(None);
        let number = self
            .started
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let entry = UnderWay {
            tile: refinement.tile.clone(),
            since: refinement.since,
            ended: receiver,
            number,
        };
        self.lock().insert(key, entry);
        let refining = self.clone();
        tokio::spawn(async move {
            let refined = refine(refinement, &refining).await;
            {
                let mut under_way = refining.lock();
                if under_way.get(&key).is_some_and(|u| u.number == number) {
                    under_way.remove(&key);
                }
            }
            let _ = sender.send(Some(refined));
        });
    }

    /// The quick tile of `key` while it is refined, unless a purge removed it since.
    pub fn quick(&self, key: &TileKey, purges: &Mutex<Purges>) -> Option<Arc<CachedTile>> {
        let (tile, since) = self
            .lock()
            .get(key)
            .map(|under_way| (under_way.tile.clone(), under_way.since))?;
        let purged = purges
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .purged_since(since, key);
        (!purged).then_some(tile)
    }

    /// The refined tile of `key` once it is made, if a refinement of it is under way.
    pub async fn wait(&self, key: &TileKey) -> Option<Arc<CachedTile>> {
        let mut ended = self.lock().get(key).map(|u| u.ended.clone())?;
        let told = ended.wait_for(Option::is_some).await.ok()?;
        told.clone().flatten()
    }

    /// Waits until the refinements under way now have ended (not those begun meanwhile: a
    /// busy server may never be without one).
    pub async fn all_ended(&self) {
        let under_way: Vec<watch::Receiver<Outcome>> =
            self.lock().values().map(|u| u.ended.clone()).collect();
        for mut ended in under_way {
            let _ = ended.wait_for(Option::is_some).await;
        }
    }

    pub fn len(&self) -> usize {
        self.lock().len()
    }

    /// The keys under way that `filter` selects.
    pub fn keys_matching(&self, filter: &TileFilter) -> Vec<TileKey> {
        self.lock()
            .keys()
            .filter(|key| filter.matches(key.tile))
            .copied()
            .collect()
    }

    /// Refined tiles the store could not take, so far.
    pub fn unstored(&self) -> u64 {
        self.unstored.load(std::sync::atomic::Ordering::Relaxed)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<TileKey, UnderWay>> {
        self.under_way.lock().unwrap_or_else(|p| p.into_inner())
    }
}

/// Makes the forms kept, stores the tile with them (unless another tile was stored there
/// since), and swaps it into memory where memory holds the quick tile or nothing of the key. A
/// purge of the tile since it was begun stops it.
async fn refine(refinement: Refinement, refining: &Refining) -> Option<Arc<CachedTile>> {
    let Refinement {
        key,
        tile,
        store,
        memory,
        purges,
        since,
        created_at,
    } = refinement;
    let checking = purges.clone();
    let made = yielding(move || {
        let bodies = match Bodies::compress(tile.bodies.identity.to_vec()) {
            Ok(bodies) => bodies,
            Err(error) => {
                tracing::warn!(tile = %key.tile, %error, "coding a tile again failed; its quick forms stay");
                return None;
            }
        };
        let stored = StoredTile {
            bodies,
            etag: tile.etag.clone(),
            made_by: tile.made_by.clone(),
            created_at,
        };
        // Checked and stored under the purges' lock, as a remade tile is.
        let purges = checking.lock().unwrap_or_else(|p| p.into_inner());
        if purges.purged_since(since, &key) {
            return None;
        }
        let kept = match store.as_ref().map(|store| store.put_if_vacant(&key, &stored)) {
            None => Some(false),
            Some(Ok(written)) => written.then_some(true),
            Some(Err(error)) => {
                tracing::warn!(tile = %key.tile, format = key.format.as_str(), %error, "the tile could not be stored; served from memory only");
                Some(false)
            }
        };
        drop(purges);
        Some((stored, kept?, store.is_some()))
    })
    .await
    .flatten()?;
    let (stored, kept, to_store) = made;
    if to_store && !kept {
        refining
            .unstored
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }
    let refined = Arc::new(CachedTile {
        bodies: stored.bodies,
        etag: stored.etag,
        made_by: stored.made_by,
        loaded_from: super::Origin::Rendered,
        stored: kept,
    });
    let held = memory.get(&key).await;
    if held.is_some_and(|held| held.etag != refined.etag || held.bodies.quick.is_none()) {
        return None;
    }
    memory.insert(key, refined.clone()).await;
    // A purge between the check and the swap has already forgotten the key: forget it again.
    if purges
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .purged_since(since, &key)
    {
        memory.invalidate(&key).await;
        return None;
    }
    Some(refined)
}

/// How far a thread coding tiles again stands back for the renders (a nice value): it takes
/// the cores they leave idle.
const NICENESS: libc::c_int = 10;

/// Runs `work` on a thread of its own, at a lower priority than the renders a client waits
/// for; `None` if it panicked.
async fn yielding<T: Send + 'static>(work: impl FnOnce() -> T + Send + 'static) -> Option<T> {
    let (done, result) = tokio::sync::oneshot::channel();
    let spawned = std::thread::Builder::new()
        .name("refine".into())
        .spawn(move || {
            // On Linux the nice value is the calling thread's (and the threads it starts
            // inherit it). A thread that cannot stand back still does the work.
            // SAFETY: setpriority reads no memory of ours; `0` names the calling thread.
            unsafe { libc::setpriority(libc::PRIO_PROCESS, 0, NICENESS) };
            let _ = done.send(work());
        });
    match spawned {
        Ok(_) => result.await.ok(),
        Err(error) => {
            tracing::warn!(%error, "no thread to code a tile again on");
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::cache::encoding::Accepted;
    use crate::cache::{Served, SqliteStore, TileCache, TileFilter, TileReader};
    use crate::format::{Encoding, Format, TileKey};
    use std::sync::Arc;

    fn key(x: u32) -> TileKey {
        TileKey {
            tile: crate::tile::TileId { z: 14, x, y: 2 },
            format: Format::GLB,
        }
    }

    /// A body that compresses, as a tile does.
    fn body(length: usize) -> Vec<u8> {
        (0..length as u32).map(|i| (i / 7 % 97) as u8).collect()
    }

    fn cache() -> (TileCache, Arc<SqliteStore>, tempfile::TempDir) {
        let dir = tempfile::tempdir().unwrap();
        let store = Arc::new(SqliteStore::open(&dir.path().join("t.sqlite"), None).unwrap());
        (TileCache::new(store.clone(), 64 << 20), store, dir)
    }

    /// Tile 1 as a client that accepts `accepted` is served it, made by `render` if need be.
    async fn ask(
        cache: &TileCache,
        accepted: Accepted,
        render: impl FnOnce() -> std::io::Result<Vec<u8>> + Send + 'static,
    ) -> Served {
        cache
            .get_or_render_kept(key(1), None, true, Some(accepted), render)
            .await
            .unwrap()
    }

    async fn purge(cache: &TileCache) {
        cache
            .purge(TileFilter::Tiles(vec![key(1).tile]))
            .await
            .unwrap();
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_tile_answered_in_haste_is_then_stored_with_its_smaller_forms() {
        let (cache, store, _dir) = cache();
        let data = body(400_000);
        let made = data.clone();
        let gzip = Accepted::parse(["gzip"]);
        let served = ask(&cache, gzip, move || Ok(made)).await;
        let quick = served.tile.bodies.clone();
        assert_eq!(quick.quick, Some(Encoding::Gzip));
        assert!(quick.brotli.is_none(), "only the form asked for is made");
        assert!(!served.tile.stored);

        cache.refined().await;
        let stored = store.get(&key(1)).unwrap().expect("stored once refined");
        assert_eq!(stored.etag, served.tile.etag);
        assert_eq!(stored.bodies.identity.as_ref(), &data[..]);
        assert!(stored.bodies.brotli.is_some());
        assert!(stored.bodies.gzip.as_ref().unwrap().len() <= quick.gzip.unwrap().len());
        let held = cache.peek(&key(1)).await.expect("held in memory");
        assert_eq!((held.bodies.quick, held.stored), (None, true));
        assert_eq!(cache.refining(), 0);
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_client_taking_a_coding_the_quick_tile_lacks_gets_the_forms_kept() {
        let (cache, _store, _dir) = cache();
        let renders = Arc::new(std::sync::atomic::AtomicUsize::new(0));
        let render = |renders: Arc<std::sync::atomic::AtomicUsize>| {
            move || {
                renders.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                Ok(body(400_000))
            }
        };
        let first = ask(&cache, Accepted::default(), render(renders.clone())).await;
        assert_eq!(first.tile.bodies.quick, Some(Encoding::Identity));
        let brotli = Accepted::parse(["br"]);
        let second = ask(&cache, brotli, render(renders.clone())).await;
        assert_eq!(second.tile.bodies.quick, None);
        assert_eq!(second.tile.bodies.choose(&brotli).0, Encoding::Brotli);
        assert_eq!(second.tile.etag, first.tile.etag);
        assert_eq!(renders.load(std::sync::atomic::Ordering::SeqCst), 1);
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_purge_while_a_tile_is_refined_wins() {
        let (cache, store, _dir) = cache();
        // Large enough that its forms kept take a while: the purge comes before them or after
        // they are stored, and either way the tile is gone.
        ask(&cache, Accepted::parse(["gzip"]), || Ok(body(8 << 20))).await;
        purge(&cache).await;
        cache.refined().await;
        assert_eq!(
            store.usage().unwrap().tiles,
            0,
            "the purged tile stays gone"
        );
        assert!(cache.peek(&key(1)).await.is_none());
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_tile_made_again_after_a_purge_is_stored_though_the_purged_one_was_refined() {
        let (cache, store, _dir) = cache();
        let gzip = Accepted::parse(["gzip"]);
        let render = |fill: u8| move || Ok(vec![fill; 8 << 20]);
        ask(&cache, gzip, render(1)).await;
        purge(&cache).await;
        // Made again, most likely while the purged tile's forms are still being made.
        let again = ask(&cache, gzip, render(2)).await;
        assert_eq!(again.tile.bodies.identity[0], 2);
        cache.refined().await;
        let stored = store.get(&key(1)).unwrap().expect("the new tile is stored");
        assert_eq!(stored.etag, again.tile.etag);
        assert_eq!(cache.peek(&key(1)).await.unwrap().bodies.quick, None);
    }
}
