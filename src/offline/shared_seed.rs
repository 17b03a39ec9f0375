//! `terrastitch seed` on a store shared by a cluster: the tiles to make are rows of the
//! cluster's work queue, and every seed worker, on any machine, takes rows from it until none is
//! left. No shares to compute: a worker started later helps with what is left, a worker killed
//! leaves its rows to lapse and be taken by the others, and the queue survives every worker, so
//! a seed started again goes on where it stopped. A tile is claimed before it is made (the same
//! claim servers take), so a seed and a server never make one tile twice.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use super::seed::{make_tile, Progress, SeedReport};
use crate::cache::postgres::cluster::{Cluster, Event, Job, JobKind, Priority};
use crate::cache::{StoreError, TileFilter, TileStore};
use crate::format::TileKey;
use crate::provider::TileProvider;

/// How long a row whose tile another process is making waits before it is taken again.
const CLAIMED_ELSEWHERE: Duration = Duration::from_secs(1);

/// How often the progress shown counts what is left in the whole queue.
const COUNT_EVERY: Duration = Duration::from_secs(2);

/// How often a worker with nothing to take looks whether rows others hold came back.
const IDLE_LOOK: Duration = Duration::from_millis(500);

/// What became of one row.
enum Outcome {
    Made(u64),
    /// Current in the store already.
    Current,
    /// Another process is making it: handed back.
    Deferred,
    /// Failed; `true` when it was set aside for good.
    Failed(String, bool),
}

/// Queues `keys` in the cluster and works on its seed queue with `threads` threads until the
/// queue is empty (rows other workers hold included: a worker that dies leaves them to this
/// one). A store error stops the seed; a tile that fails is tried again by whoever takes it
/// next, and reported when it has failed too often.
pub fn seed(
    provider: &dyn TileProvider,
    store: &dyn TileStore,
    cluster: &Arc<Cluster>,
    keys: &[TileKey],
    threads: usize,
    render_limit: Option<Duration>,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<SeedReport, StoreError> {
    let started = Instant::now();
    cluster.register("seed")?;
    cluster
        .start_heartbeat()
        .map_err(|e| StoreError::Panicked(format!("starting the heartbeat: {e}")))?;
    if let Err(error) = crate::provider::load_solutions(store) {
        tracing::warn!(%error, "reading solved elevation components failed");
    }
    cluster.enqueue(keys, JobKind::Seed, Priority::Seed, false)?;
    let tally = Tally {
        total: cluster.pending(JobKind::Seed)? as usize,
        ..Tally::default()
    };
    tally.left.store(tally.total, Ordering::Relaxed);
    let stop: Mutex<Option<StoreError>> = Mutex::new(None);
    let stopped = || stop.lock().map_or(true, |s| s.is_some());
    std::thread::scope(|scope| {
        for _ in 0..threads.max(1) {
            scope.spawn(|| {
                let tell = |done| tally.record(cluster, done, progress);
                if let Err(error) = work(provider, store, cluster, render_limit, &stopped, tell) {
                    if let Ok(mut s) = stop.lock() {
                        s.get_or_insert(error);
                    }
                }
            });
        }
    });
    if let Some(error) = stop.into_inner().unwrap_or_else(|p| p.into_inner()) {
        return Err(error);
    }
    let mut report = tally.report.into_inner().unwrap_or_else(|p| p.into_inner());
    report.elapsed = started.elapsed();
    report.failed.sort_by_key(|(key, _)| *key);
    Ok(report)
}

/// What this worker made, and how much of the queue is left.
#[derive(Default)]
struct Tally {
    report: Mutex<SeedReport>,
    /// Rows in the queue when this worker began.
    total: usize,
    /// Rows left: counted down as this worker finishes them, and set from the queue now and
    /// then (the others' work shows there; a count of a long queue is not free).
    left: AtomicUsize,
    last_count: Mutex<Option<Instant>>,
}

impl Tally {
    fn record(
        &self,
        cluster: &Cluster,
        (key, outcome): (TileKey, Outcome),
        progress: &(dyn Fn(Progress) + Sync),
    ) {
        let mut report = self.report.lock().unwrap_or_else(|p| p.into_inner());
        match outcome {
            Outcome::Made(bytes) => {
                report.made += 1;
                report.stored_bytes += bytes;
            }
            Outcome::Failed(error, true) => report.failed.push((key, error)),
            Outcome::Current => {}
            // Still in the queue.
            Outcome::Failed(_, false) | Outcome::Deferred => return,
        }
        drop(report);
        let _ = self
            .left
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |n| {
                Some(n.saturating_sub(1))
            });
        let mut counted = self.last_count.lock().unwrap_or_else(|p| p.into_inner());
        if counted.is_none_or(|at| at.elapsed() >= COUNT_EVERY) {
            *counted = Some(Instant::now());
            if let Ok(pending) = cluster.pending(JobKind::Seed) {
                self.left.store(pending as usize, Ordering::Relaxed);
            }
        }
        drop(counted);
        progress(Progress {
            done: self.total.saturating_sub(self.left.load(Ordering::Relaxed)),
            total: self.total,
        });
    }
}

/// One thread's loop: takes rows until the queue is empty or the seed stops.
fn work(
    provider: &dyn TileProvider,
    store: &dyn TileStore,
    cluster: &Cluster,
    render_limit: Option<Duration>,
    stopped: &dyn Fn() -> bool,
    tell: impl Fn((TileKey, Outcome)),
) -> Result<(), StoreError> {
    while !stopped() {
        let Some(job) = cluster.take(JobKind::Seed)? else {
            if cluster.pending(JobKind::Seed)? == 0 {
                return Ok(());
            }
            std::thread::sleep(IDLE_LOOK);
            continue;
        };
        let outcome = make_row(provider, store, cluster, job, render_limit)?;
        tell((job.key, outcome));
    }
    Ok(())
}

/// Makes the tile of a row taken, and finishes, defers or fails the row.
fn make_row(
    provider: &dyn TileProvider,
    store: &dyn TileStore,
    cluster: &Cluster,
    job: Job,
    render_limit: Option<Duration>,
) -> Result<Outcome, StoreError> {
    let key = job.key;
    let wanted = provider.provenance(key.tile);
    let current = store
        .list(&TileFilter::Tiles(vec![key.tile]))?
        .into_iter()
        .any(|entry| entry.key == key && Some(&entry.made_by) == wanted.as_ref());
    if current && !job.force {
        cluster.finish(&key, false)?;
        return Ok(Outcome::Current);
    }
    if !cluster.try_lease(&key)? {
        cluster.defer(&key, CLAIMED_ELSEWHERE)?;
        return Ok(Outcome::Deferred);
    }
    let made = make_tile(provider, key, render_limit);
    let outcome = match made {
        Ok(tile) => {
            // Whole or not at all: the row is replaced in one transaction.
            store.put(&key, &tile)?;
            if let Err(error) = crate::provider::save_solutions(store) {
                tracing::warn!(%error, "keeping solved elevation components failed");
            }
            // Servers holding an older version in memory drop it.
            cluster.broadcast(&Event::Stored(vec![key]))?;
            cluster.finish(&key, true)?;
            Outcome::Made(tile.bodies.stored_len() as u64)
        }
        Err(error) => {
            tracing::error!(tile = %key.tile, format = key.format.as_str(), %error, "tile failed");
            let set_aside = cluster.fail(&key, &error)?;
            Outcome::Failed(error, set_aside)
        }
    };
    cluster.release(&key)?;
    Ok(outcome)
}
