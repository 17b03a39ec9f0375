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
    let total = cluster.pending(JobKind::Seed)? as usize;
    let left = AtomicUsize::new(total);
    let report = Mutex::new(SeedReport::default());
    let stop: Mutex<Option<StoreError>> = Mutex::new(None);
    let stopped = || stop.lock().map_or(true, |s| s.is_some());
    std::thread::scope(|scope| {
        for _ in 0..threads.max(1) {
            scope.spawn(|| {
                let worked = work(
                    provider,
                    store,
                    cluster,
                    render_limit,
                    &stopped,
                    |outcome| {
                        let mut r = report.lock().unwrap_or_else(|p| p.into_inner());
                        match outcome {
                            (_, Outcome::Made(bytes)) => {
                                r.made += 1;
                                r.stored_bytes += bytes;
                            }
                            (key, Outcome::Failed(error, true)) => r.failed.push((key, error)),
                            _ => {}
                        }
                        drop(r);
                        if let Ok(pending) = cluster.pending(JobKind::Seed) {
                            left.store(pending as usize, Ordering::Relaxed);
                        }
                        progress(Progress {
                            done: total.saturating_sub(left.load(Ordering::Relaxed)),
                            total,
                        });
                    },
                );
                if let Err(error) = worked {
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
    let mut report = report.into_inner().unwrap_or_else(|p| p.into_inner());
    report.elapsed = started.elapsed();
    report.failed.sort_by_key(|(key, _)| *key);
    Ok(report)
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
