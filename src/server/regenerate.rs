//! Making tiles again in the background: stale tiles a request met (first in line), tiles an
//! operator asked for (`POST /admin/regenerate`), and tiles whose sources changed (found by
//! the periodic source check), hottest first. Workers take one render slot each at background
//! priority, so live requests always go first.
//!
//! With a store shared by a cluster, the queue is the cluster's (`work` rows in PostgreSQL):
//! any process's workers take its tiles, and a tile stale on every process is queued once.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use tokio::sync::Notify;

use super::metrics::Metrics;
use super::tiles::{render_job, Priority};
use super::AppState;
use crate::cache::coordinator::{Coordinator, Job, JobKind, Priority as QueuePriority};
use crate::cache::{Remade, TileFilter};
use crate::format::TileKey;
use crate::provider::Availability;
use crate::tile::TileId;

/// The line of tiles to make again: the coordinator's queue (in memory, or the cluster's), and
/// what wakes the workers when work is queued.
#[derive(Debug)]
pub struct Regenerator {
    coordinator: Arc<dyn Coordinator>,
    wake: Notify,
    /// Stale tiles on their way into the queue.
    queuing: AtomicUsize,
}

/// How long an idle worker waits before it looks at the queue again (queued work wakes it at
/// once; rows another process handed back come due without a word).
const IDLE_LOOK: std::time::Duration = std::time::Duration::from_secs(2);

impl Regenerator {
    pub fn new(coordinator: Arc<dyn Coordinator>) -> Regenerator {
        Regenerator {
            coordinator,
            wake: Notify::new(),
            queuing: AtomicUsize::new(0),
        }
    }

    /// A stale tile a request just met: made before the other work, unless it is already in
    /// line.
    pub fn stale(self: &Arc<Self>, key: TileKey) {
        self.queuing.fetch_add(1, Ordering::SeqCst);
        let regenerator = self.clone();
        tokio::task::spawn_blocking(move || {
            let queued = regenerator.coordinator.enqueue(
                &[key],
                JobKind::Regenerate,
                QueuePriority::Stale,
                false,
            );
            regenerator.queuing.fetch_sub(1, Ordering::SeqCst);
            if let Err(error) = queued {
                tracing::warn!(tile = %key.tile, %error, "queueing a stale tile failed");
            }
        });
    }

    /// Takes the tiles `filter` selects out of the line; returns how many. A tile already being
    /// made finishes and is stored (a remake checks that its tile is still stored only before
    /// it starts).
    pub fn forget(&self, filter: &TileFilter) -> usize {
        self.coordinator.withdraw(filter)
    }

    /// Wakes every idle worker (work was queued).
    pub fn wake_all(&self) {
        self.wake.notify_waiters();
    }

    /// Tiles this process has in line or is making.
    pub fn len(&self) -> usize {
        self.queuing.load(Ordering::SeqCst) + self.coordinator.in_hand()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// One worker: takes a tile from the queue, makes it again, and finishes its row (or hands it
/// back as failed, to be tried again later when the queue is shared).
pub async fn work(state: AppState) {
    let queue = state.work.regenerator.clone();
    let coordinator = state.cache.coordinator().clone();
    loop {
        let queued = queue.wake.notified();
        let taking = coordinator.clone();
        let taken = tokio::task::spawn_blocking(move || taking.take(JobKind::Regenerate)).await;
        let jobs = match taken {
            Ok(Ok(jobs)) if jobs.is_empty() => {
                let _ = tokio::time::timeout(IDLE_LOOK, queued).await;
                continue;
            }
            Ok(Ok(jobs)) => jobs,
            Ok(Err(error)) => {
                tracing::warn!(%error, "taking work from the queue failed");
                tokio::time::sleep(IDLE_LOOK).await;
                continue;
            }
            Err(_) => continue,
        };
        // A tile's formats one after the other: each is a request's render, in flight alone.
        for job in jobs {
            let key = job.key;
            let outcome = remake(&state, job).await;
            let finishing = coordinator.clone();
            let finished = tokio::task::spawn_blocking(move || match outcome {
                Ok(made) => finishing.finish(&key, made),
                Err(error) => finishing.fail(&key, &error).map(|_| ()),
            })
            .await;
            if let Ok(Err(error)) = finished {
                tracing::warn!(tile = %key.tile, %error, "finishing work in the queue failed; it is taken again when its claim lapses");
            }
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
    // A provider that makes no tiles has none to make again (asked on the blocking pool: a
    // store's provider reads the tile's last diff).
    let asking = provider.clone();
    let wanted = tokio::task::spawn_blocking(move || asking.provenance(key.tile))
        .await
        .map_err(|e| e.to_string())?;
    let Some(wanted) = wanted else {
        return Ok(false);
    };
    // Counted before the tile is looked for: a purge after this, even one that comes between
    // the look and the render, keeps the new tile out of the store.
    let purges_so_far = state.cache.purges_so_far();
    // A tile answered in haste is looked for once it is stored.
    state.cache.refined_one(&key).await;
    let store = state.cache.reader();
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
    // The tiles answered in haste are among those stored once their forms kept are made.
    state.cache.refined().await;
    let store = state.cache.reader();
    let keys: Vec<TileKey> = tokio::task::spawn_blocking(move || {
        let mut keys = Vec::new();
        // A provider that makes no tiles (an archive) has none to make again.
        if provider.provenance(TileId { z: 0, x: 0, y: 0 }).is_none() {
            return Ok(keys);
        }
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
    let coordinator = state.cache.coordinator().clone();
    let queued = tokio::task::spawn_blocking(move || {
        coordinator.enqueue(&keys, JobKind::Regenerate, QueuePriority::Regenerate, force)
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

/// Applies the provider's replication diffs every `interval`, on a task of its own: a check
/// of the sources follows at once when any were applied, so the tiles they change are queued
/// without waiting for the next one.
pub async fn watch_replication(state: AppState, interval: std::time::Duration) {
    let mut ticker = tokio::time::interval(interval);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        ticker.tick().await;
        let Ok(provider) = state.provider() else {
            continue;
        };
        let applied =
            tokio::task::spawn_blocking(move || provider.reloading().map_or(0, |r| r.catch_up()))
                .await;
        if matches!(applied, Ok(n) if n > 0) {
            if let Err(error) = check_sources(&state).await {
                tracing::error!(%error, "checking the sources failed; the tiles are still made from the sources loaded before");
            }
        }
    }
}

/// When the provider's inputs changed (an extract rewritten, an SRTM file added or
/// replaced, a diff applied to its store), puts a provider on the new ones in place, and
/// queues every stored tile it makes stale, most recently served first. Returns how many tiles
/// were queued. One check at a time: the replication task and the periodic check may both ask.
pub async fn check_sources(state: &AppState) -> Result<usize, String> {
    let _one_at_a_time = state.work.checking.lock().await;
    let current = state.provider().map_err(|e| e.message)?;
    let reopened = tokio::task::spawn_blocking(move || match current.reloading() {
        Some(reloading) => reloading.reopened(),
        None => Ok(None),
    })
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
