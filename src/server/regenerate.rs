//! Making tiles again in the background: stale tiles a request met (first in line), tiles an
//! operator asked for (`POST /admin/regenerate`), and tiles whose sources changed (found by
//! the periodic source check), hottest first. Workers take one render slot each at background
//! priority, so live requests always go first.
//!
//! With a store shared by a cluster, the queue is the cluster's (`work` rows in PostgreSQL):
//! any process's workers take its tiles, and a tile stale on every process is queued once.

use std::collections::{HashSet, VecDeque};
use std::sync::{Arc, Mutex};

use tokio::sync::Notify;

use super::metrics::Metrics;
use super::tiles::{render_job, Priority};
use super::AppState;
use crate::cache::postgres::cluster::{Cluster, JobKind, Priority as QueuePriority};
use crate::cache::{Remade, TileFilter};
use crate::format::TileKey;
use crate::provider::Availability;
use crate::tile::TileId;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Job {
    key: TileKey,
    /// Make it even if the tile held is current.
    force: bool,
}

#[derive(Debug, Default)]
struct Queue {
    order: VecDeque<Job>,
    /// Queued or being made.
    held: HashSet<TileKey>,
}

/// The queue of tiles to make again.
#[derive(Debug)]
pub struct Regenerator {
    queue: Mutex<Queue>,
    wake: Notify,
    /// Stale tiles lately queued in the cluster's queue, not queued again meanwhile.
    told_stale: moka::sync::Cache<TileKey, ()>,
}

impl Default for Regenerator {
    fn default() -> Self {
        Regenerator {
            queue: Mutex::default(),
            wake: Notify::new(),
            told_stale: moka::sync::Cache::builder()
                .max_capacity(100_000)
                .time_to_live(STALE_REQUEUE)
                .build(),
        }
    }
}

/// How long a stale tile queued in the cluster is not queued again by this process.
const STALE_REQUEUE: std::time::Duration = std::time::Duration::from_secs(30);

/// How long an idle worker of the cluster's queue waits before it looks again (queued work
/// wakes it at once when the broadcast arrives).
const IDLE_LOOK: std::time::Duration = std::time::Duration::from_secs(2);

impl Regenerator {
    fn lock(&self) -> std::sync::MutexGuard<'_, Queue> {
        self.queue.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// A stale tile a request just met: made next, unless it is already in line (in the
    /// cluster's queue when the store is shared).
    pub fn stale(&self, key: TileKey, cluster: Option<&std::sync::Arc<Cluster>>) {
        let Some(cluster) = cluster.cloned() else {
            return self.stale_here(key);
        };
        if self.told_stale.contains_key(&key) {
            return;
        }
        self.told_stale.insert(key, ());
        tokio::task::spawn_blocking(move || {
            let queued = cluster.enqueue(&[key], JobKind::Regenerate, QueuePriority::Stale, false);
            if let Err(error) = queued {
                tracing::warn!(tile = %key.tile, %error, "queueing a stale tile in the cluster failed");
            }
        });
    }

    fn stale_here(&self, key: TileKey) {
        let mut queue = self.lock();
        if queue.held.insert(key) {
            queue.order.push_front(Job { key, force: false });
            drop(queue);
            self.wake.notify_one();
        }
    }

    /// Tiles to make again, in the order given, after those already in line; returns how many
    /// were added.
    pub fn enqueue(&self, keys: impl IntoIterator<Item = TileKey>, force: bool) -> usize {
        let mut queue = self.lock();
        let mut added = 0;
        for key in keys {
            if queue.held.insert(key) {
                queue.order.push_back(Job { key, force });
                added += 1;
            }
        }
        drop(queue);
        for _ in 0..added {
            self.wake.notify_one();
        }
        added
    }

    /// Takes the tiles `filter` selects out of the line; returns how many. A tile already being
    /// made finishes and is stored (a remake checks that its tile is still stored only before
    /// it starts).
    pub fn forget(&self, filter: &TileFilter) -> usize {
        let mut queue = self.lock();
        let before = queue.order.len();
        let Queue { order, held } = &mut *queue;
        order.retain(|job| {
            let keep = !filter.matches(job.key.tile);
            if !keep {
                held.remove(&job.key);
            }
            keep
        });
        before - queue.order.len()
    }

    /// Wakes every idle worker (work was queued in the cluster).
    pub fn wake_all(&self) {
        self.wake.notify_waiters();
    }

    /// Tiles in line or being made.
    pub fn len(&self) -> usize {
        self.lock().held.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    async fn next(&self) -> Job {
        loop {
            let notified = self.wake.notified();
            if let Some(job) = self.lock().order.pop_front() {
                return job;
            }
            notified.await;
        }
    }

    fn done(&self, key: &TileKey) {
        self.lock().held.remove(key);
    }
}

/// One worker: takes tiles from the queue and makes them again, one at a time.
pub async fn work(state: AppState) {
    if let Some(cluster) = state.cache.cluster().cloned() {
        return work_shared(state, cluster).await;
    }
    let queue = state.work.regenerator.clone();
    loop {
        let job = queue.next().await;
        let _ = remake(&state, job).await;
        queue.done(&job.key);
    }
}

/// One worker on the cluster's queue: takes a row, makes its tile again, and finishes the row
/// (or hands it back as failed, to be tried again later).
async fn work_shared(state: AppState, cluster: std::sync::Arc<Cluster>) {
    let queue = state.work.regenerator.clone();
    loop {
        let queued = queue.wake.notified();
        let taking = cluster.clone();
        let taken = tokio::task::spawn_blocking(move || taking.take(JobKind::Regenerate)).await;
        let job = match taken {
            Ok(Ok(Some(job))) => job,
            Ok(Ok(None)) => {
                let _ = tokio::time::timeout(IDLE_LOOK, queued).await;
                continue;
            }
            Ok(Err(error)) => {
                tracing::warn!(%error, "taking work from the cluster's queue failed");
                tokio::time::sleep(IDLE_LOOK).await;
                continue;
            }
            Err(_) => continue,
        };
        let key = job.key;
        let outcome = remake(
            &state,
            Job {
                key,
                force: job.force,
            },
        )
        .await;
        let finishing = cluster.clone();
        let finished = tokio::task::spawn_blocking(move || match outcome {
            Ok(made) => finishing.finish(&key, made),
            Err(error) => finishing.fail(&key, &error).map(|_| ()),
        })
        .await;
        if let Ok(Err(error)) = finished {
            tracing::warn!(tile = %key.tile, %error, "finishing work in the cluster's queue failed; it is taken again when its claim lapses");
        }
    }
}

/// Makes a queued tile again: `Ok(true)` when a new tile was made, `Ok(false)` when there was
/// nothing to make (current already, purged, no longer covered), the error when it failed.
async fn remake(state: &AppState, job: Job) -> Result<bool, String> {
    let provider = state.provider().map_err(|e| e.message)?;
    let key = job.key;
    if provider.availability(key) != Availability::Ready {
        tracing::warn!(tile = %key.tile, "not made again: the sources no longer cover it");
        return Ok(false);
    }
    // A provider that makes no tiles has none to make again.
    let Some(wanted) = provider.provenance(key.tile) else {
        return Ok(false);
    };
    // Counted before the tile is looked for: a purge after this, even one that comes between
    // the look and the render, keeps the new tile out of the store.
    let purges_so_far = state.cache.purges_so_far();
    let store = state.cache.store().clone();
    let listed =
        tokio::task::spawn_blocking(move || store.list(&TileFilter::Tiles(vec![key.tile]))).await;
    let stored = match listed {
        Ok(Ok(entries)) => entries.into_iter().find(|e| e.key == key),
        _ => None,
    };
    // A tile purged since it was queued is not brought back.
    let Some(stored) = stored else {
        return Ok(false);
    };
    // Current already (another process made it meanwhile, or it was queued twice).
    if !job.force && stored.made_by == wanted {
        return Ok(false);
    }
    let render = render_job(state, provider, key, Priority::Background);
    match state.cache.remake(key, wanted, purges_so_far, render).await {
        Ok(Remade::Stored) => {
            Metrics::count(&state.metrics.regenerations);
            Ok(true)
        }
        Ok(Remade::Unstored) => {
            Metrics::count(&state.metrics.regenerations);
            Metrics::count(&state.metrics.tiles_unstored);
            Ok(true)
        }
        Ok(Remade::Purged) => {
            tracing::info!(tile = %key.tile, "made again but purged meanwhile: not stored");
            Ok(false)
        }
        Err(error) => {
            Metrics::count(&state.metrics.regeneration_failures);
            tracing::warn!(tile = %key.tile, format = key.format.as_str(), %error, "a tile could not be made again; the old one stays");
            Err(error.to_string())
        }
    }
}

/// Queues the stored tiles that `filter` selects, most recently served first; `only_stale`
/// keeps those the provider would make otherwise now. Returns how many.
pub async fn queue_stored(
    state: &AppState,
    filter: TileFilter,
    only_stale: bool,
) -> Result<usize, String> {
    let provider = state.provider().map_err(|e| e.message)?;
    // A provider that makes no tiles (an archive) has none to make again.
    if provider.provenance(TileId { z: 0, x: 0, y: 0 }).is_none() {
        return Ok(0);
    }
    let store = state.cache.store().clone();
    let keys: Vec<TileKey> = tokio::task::spawn_blocking(move || {
        let mut keys = Vec::new();
        store.each(&filter, &mut |entry| {
            let remade = provider.provenance(entry.key.tile);
            if remade.is_some_and(|wanted| !only_stale || entry.made_by != wanted) {
                keys.push(entry.key);
            }
        })?;
        Ok::<_, crate::cache::StoreError>(keys)
    })
    .await
    .map_err(|e| e.to_string())?
    .map_err(|e| e.to_string())?;
    let force = !only_stale;
    let Some(cluster) = state.cache.cluster().cloned() else {
        return Ok(state.work.regenerator.enqueue(keys, force));
    };
    let queued = tokio::task::spawn_blocking(move || {
        cluster.enqueue(&keys, JobKind::Regenerate, QueuePriority::Regenerate, force)
    })
    .await
    .map_err(|e| e.to_string())?
    .map_err(|e| e.to_string())?;
    Ok(queued as usize)
}

/// Starts the workers.
pub fn start(state: &AppState, workers: usize) -> Vec<tokio::task::JoinHandle<()>> {
    (0..workers.max(1))
        .map(|_| tokio::spawn(work(state.clone())))
        .collect()
}

/// A shared queue.
pub fn new_queue() -> Arc<Regenerator> {
    Arc::new(Regenerator::default())
}

/// Checks the sources every `interval`; see [`check_sources`].
pub async fn watch_sources(state: AppState, interval: std::time::Duration) {
    let mut ticker = tokio::time::interval(interval);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    ticker.tick().await;
    loop {
        ticker.tick().await;
        if let Err(error) = check_sources(&state).await {
            tracing::error!(%error, "checking the sources failed; the tiles are still made from the sources loaded before");
        }
    }
}

/// When the provider's inputs changed (an extract rewritten, an SRTM file added or
/// replaced), puts a provider on the new ones in place, and queues every stored tile it makes
/// stale, most recently served first. Returns how many tiles were queued.
pub async fn check_sources(state: &AppState) -> Result<usize, String> {
    let current = state.provider().map_err(|e| e.message)?;
    let reopened = tokio::task::spawn_blocking(move || current.reopened())
        .await
        .map_err(|e| e.to_string())??;
    let Some(provider) = reopened else {
        return Ok(0);
    };
    state.provide(provider);
    let queued = queue_stored(state, TileFilter::All, true).await?;
    tracing::info!(
        queued,
        "tiles made stale by the new sources queued to be made again"
    );
    Ok(queued)
}
