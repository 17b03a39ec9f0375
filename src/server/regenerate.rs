//! Making tiles again in the background: stale tiles a request met (first in line), tiles an
//! operator asked for (`POST /admin/regenerate`), and tiles whose sources changed (found by
//! the periodic source check), hottest first. Workers take one render slot each at background
//! priority, so live requests always go first.

use std::collections::{HashSet, VecDeque};
use std::sync::{Arc, Mutex};

use tokio::sync::Notify;

use super::metrics::Metrics;
use super::tiles::{render_job, Priority};
use super::AppState;
use crate::cache::{Remade, StoredEntry, TileFilter};
use crate::format::TileKey;
use crate::provider::Availability;

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
#[derive(Debug, Default)]
pub struct Regenerator {
    queue: Mutex<Queue>,
    wake: Notify,
}

impl Regenerator {
    fn lock(&self) -> std::sync::MutexGuard<'_, Queue> {
        self.queue.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// A stale tile a request just met: made next, unless it is already in line.
    pub fn stale(&self, key: TileKey) {
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
    let queue = state.work.regenerator.clone();
    loop {
        let job = queue.next().await;
        remake(&state, job).await;
        queue.done(&job.key);
    }
}

async fn remake(state: &AppState, job: Job) {
    let Ok(provider) = state.provider() else {
        return;
    };
    let key = job.key;
    if provider.availability(key) != Availability::Ready {
        tracing::warn!(tile = %key.tile, "not made again: the sources no longer cover it");
        return;
    }
    // A provider that makes no tiles has none to make again.
    let Some(wanted) = provider.provenance(key.tile) else {
        return;
    };
    if !job.force {
        if let Some(held) = state.cache.peek(&key).await {
            if held.made_by == wanted {
                return;
            }
        }
    }
    // A tile purged since it was queued is not brought back, nor one purged while it is made.
    let purges_so_far = state.cache.purges_so_far();
    let store = state.cache.store().clone();
    let still_stored = tokio::task::spawn_blocking(move || {
        store
            .list(&TileFilter::Tiles(vec![key.tile]))
            .map(|entries| entries.iter().any(|e| e.key == key))
    })
    .await;
    if !matches!(still_stored, Ok(Ok(true))) {
        return;
    }
    let render = render_job(state, provider, key, Priority::Background);
    match state.cache.remake(key, wanted, purges_so_far, render).await {
        Ok(Remade::Stored) => Metrics::count(&state.metrics.regenerations),
        Ok(Remade::Unstored) => {
            Metrics::count(&state.metrics.regenerations);
            Metrics::count(&state.metrics.tiles_unstored);
        }
        Ok(Remade::Purged) => {
            tracing::info!(tile = %key.tile, "made again but purged meanwhile: not stored");
        }
        Err(error) => {
            Metrics::count(&state.metrics.regeneration_failures);
            tracing::warn!(tile = %key.tile, format = key.format.as_str(), %error, "a tile could not be made again; the old one stays");
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
    let store = state.cache.store().clone();
    let entries: Vec<StoredEntry> = tokio::task::spawn_blocking(move || store.list(&filter))
        .await
        .map_err(|e| e.to_string())?
        .map_err(|e| e.to_string())?;
    let provider = state.provider().map_err(|e| e.message)?;
    let keys: Vec<TileKey> = entries
        .into_iter()
        .filter(|entry| {
            !only_stale
                || provider
                    .provenance(entry.key.tile)
                    .is_some_and(|wanted| entry.made_by != wanted)
        })
        .map(|entry| entry.key)
        .collect();
    Ok(state.work.regenerator.enqueue(keys, !only_stale))
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
