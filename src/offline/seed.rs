//! `terrastitch seed`: renders every tile of a box into the cache.
//!
//! Resumable: a tile the cache already holds, made by this pipeline from these sources, is not
//! made again, and every tile is stored in one transaction as soon as it is made, so a seed
//! killed at any moment leaves a sound cache with whole tiles only. `--shard i/n` takes the
//! tiles whose place in the box's row-major order is `i − 1` modulo `n`: the shares depend on
//! the box alone, so jobs on several machines split a region without talking to each other.
//!
//! The tiles to make are rows of the coordinator's queue, and every thread takes rows until
//! none is left. With a store shared by a cluster that queue is the cluster's: no shares to
//! compute, a worker started later helps with what is left, a worker killed leaves its rows to
//! lapse and be taken by the others, and the queue survives every worker, so a seed started
//! again goes on where it stopped. A tile is claimed before it is made (the same claim servers
//! take), so a seed and a server never make one tile twice.

use std::collections::HashMap;
use std::str::FromStr;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex};
use std::time::{Duration, Instant};

use crate::cache::coordinator::{Coordinator, Event, Job, JobKind, Priority};
use crate::cache::encoding::Bodies;
use crate::cache::{
    etag_of, unix_now, Provenance, StoreError, StoredTile, TileFilter, TileReader, TileStore,
};
use crate::format::{Format, TileKey};
use crate::provider::{Availability, Deadline, Offer, Solutions, StageTimings, TileProvider};
use crate::tile::{LonLatBounds, TileId, TileRange};

/// The `i`-th of `n` shares of a box's tiles (`1 ≤ i ≤ n`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: u64,
    pub count: u64,
}

impl Default for Shard {
    fn default() -> Self {
        Shard { index: 1, count: 1 }
    }
}

impl FromStr for Shard {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || format!("shard '{s}' is not i/n with 1 ≤ i ≤ n, e.g. 2/4");
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let index: u64 = i.trim().parse().map_err(|_| bad())?;
        let count: u64 = n.trim().parse().map_err(|_| bad())?;
        if index == 0 || index > count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

impl Shard {
    /// Whether the tile at `position` in the box's order is in this share.
    pub fn takes(&self, position: u64) -> bool {
        position % self.count == self.index - 1
    }
}

/// The tiles a seed will make.
#[derive(Debug, Clone, Default)]
pub struct Plan {
    /// In this shard, covered by the sources, and not already in the cache as they would be
    /// made now.
    pub to_make: Vec<TileKey>,
    /// In this shard and already in the cache, current.
    pub already: usize,
    /// In this shard but outside the data (no SRTM file for them, nor one to download).
    pub uncovered: usize,
    /// The box's tiles in all shards, times the formats.
    pub in_box: u64,
}

/// The tiles of one zoom, in some formats.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Layer {
    pub range: TileRange,
    pub formats: Vec<Format>,
}

/// The layers of `bbox` in `formats`: the served zoom in every format and, with `coarser`, the
/// coarser zooms the viewers ask for as well — the far views' for glb, every zoom from 0 for
/// terrain (Cesium's terrain starts from the whole world).
pub fn layers(offer: &Offer, bbox: &LonLatBounds, formats: &[Format], coarser: bool) -> Vec<Layer> {
    let held_at = |z: u8, format: &Format| {
        z == offer.zoom
            || coarser
                && match format {
                    Format::Glb(_) => offer.far_zooms.contains(&z),
                    Format::Terrain(_) => z < offer.zoom,
                }
    };
    (0..=offer.zoom)
        .rev()
        .filter_map(|z| {
            let formats: Vec<Format> = formats.iter().copied().filter(|f| held_at(z, f)).collect();
            (!formats.is_empty()).then(|| Layer {
                range: TileRange::covering(z, bbox),
                formats,
            })
        })
        .collect()
}

/// Plans a seed of `layers`: this shard's tiles that the cache lacks, or holds as `provider`
/// would not make them now. Shards split the tiles in the layers' order, row by row.
pub fn plan(
    provider: &dyn TileProvider,
    store: &dyn TileReader,
    layers: &[Layer],
    shard: Shard,
) -> Result<Plan, StoreError> {
    let mut plan = Plan::default();
    let mut position = 0u64;
    for layer in layers {
        let held: HashMap<TileKey, Provenance> = store
            .list(&TileFilter::Range(layer.range))?
            .into_iter()
            .map(|entry| (entry.key, entry.made_by))
            .collect();
        plan.in_box += layer.range.len() * layer.formats.len() as u64;
        for tile in layer.range.tiles() {
            position += 1;
            if !shard.takes(position - 1) {
                continue;
            }
            plan_tile(provider, &held, tile, &layer.formats, &mut plan);
        }
    }
    Ok(plan)
}

/// Puts `tile` in `formats` into `plan`.
fn plan_tile(
    provider: &dyn TileProvider,
    held: &HashMap<TileKey, Provenance>,
    tile: TileId,
    formats: &[Format],
    plan: &mut Plan,
) {
    let wanted = provider.provenance(tile);
    for &format in formats {
        let Some(key) = available(provider, tile, format) else {
            plan.uncovered += 1;
            continue;
        };
        match (held.get(&key), &wanted) {
            (Some(made_by), Some(wanted)) if made_by == wanted => plan.already += 1,
            // A provider that makes nothing keeps what the store holds.
            (Some(_), None) => plan.already += 1,
            _ => plan.to_make.push(key),
        }
    }
}

/// The key of the tile if `provider` can have it, downloading what it lacks if it can.
pub fn available(provider: &dyn TileProvider, tile: TileId, format: Format) -> Option<TileKey> {
    let key = provider.resolve(tile, format).ok()?;
    match provider.availability(key) {
        Availability::Ready => Some(key),
        Availability::AfterFetch => match crate::provider::capabilities::fetch(provider, tile) {
            Ok(()) => Some(key),
            Err(error) => {
                tracing::info!(%error, "tile left out");
                None
            }
        },
        Availability::Missing(_) => None,
    }
}

/// How a seed went.
#[derive(Debug, Clone, Default)]
pub struct SeedReport {
    pub made: usize,
    /// Tiles that failed, with why.
    pub failed: Vec<(TileKey, String)>,
    /// Bytes stored (compressed as kept).
    pub stored_bytes: u64,
    pub elapsed: Duration,
    /// The time the tiles made spent in each stage of their renders, summed over the tiles
    /// (over all threads: it may exceed `elapsed`).
    pub stages: StageTimings,
    /// The time spent compressing the tiles made, summed likewise.
    pub compressing: Duration,
}

impl SeedReport {
    pub fn tiles_per_second(&self) -> f64 {
        self.made as f64 / self.elapsed.as_secs_f64().max(1e-9)
    }
}

/// What the seed tells its progress display after each tile.
#[derive(Debug, Clone, Copy)]
pub struct Progress {
    pub done: usize,
    pub total: usize,
}

/// How long a row whose tile another process is making waits before it is taken again.
const CLAIMED_ELSEWHERE: Duration = Duration::from_secs(1);

/// How often the progress shown counts what is left in the whole queue.
const COUNT_EVERY: Duration = Duration::from_secs(2);

/// How long a thread with nothing to take waits for rows others hold to come back.
const IDLE_LOOK: Duration = Duration::from_millis(500);

/// What became of one row.
enum Outcome {
    /// Made and stored: its bytes stored, and the work it took (given with one format of a
    /// tile made in several).
    Made(u64, Work),
    /// Current in the store already.
    Current,
    /// Another process is making it: handed back.
    Deferred,
    /// Failed; `true` when it was set aside for good.
    Failed(String, bool),
}

/// Queues `keys` with the coordinator and works on its seed queue with `threads` threads (each
/// render given `render_limit`), `provider` rendering with the memo `solutions`, until
/// the queue is empty (rows other workers hold included: a worker that dies leaves them to
/// this one), storing each tile as soon as it is made. A store error stops the seed; a tile
/// that fails is tried again by whoever takes it next, and reported when it is set aside.
pub fn seed(
    (provider, solutions): (&dyn TileProvider, &Solutions),
    store: &dyn TileStore,
    coordinator: &dyn Coordinator,
    keys: &[TileKey],
    (threads, render_limit): (usize, Option<Duration>),
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<SeedReport, StoreError> {
    let started = Instant::now();
    coordinator.join("seed")?;
    // Components a render before this one solved are found, not solved again.
    if let Err(error) = crate::provider::load_solutions(store, solutions) {
        tracing::warn!(%error, "reading solved elevation components failed");
    }
    coordinator.enqueue(keys, JobKind::Seed, Priority::Seed, false)?;
    let tally = Tally {
        total: coordinator.pending(JobKind::Seed)? as usize,
        ..Tally::default()
    };
    tally.left.store(tally.total, Ordering::Relaxed);
    let stop: Mutex<Option<StoreError>> = Mutex::new(None);
    let stopped = || stop.lock().map_or(true, |s| s.is_some());
    let workers = Workers {
        provider,
        solutions,
        store,
        coordinator,
        render_limit,
        finished: (Mutex::new(0), Condvar::new()),
    };
    std::thread::scope(|scope| {
        for _ in 0..threads.max(1) {
            scope.spawn(|| {
                let tell = |done| tally.record(coordinator, done, progress);
                if let Err(error) = workers.work(&stopped, tell) {
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
        coordinator: &dyn Coordinator,
        (key, outcome): (TileKey, Outcome),
        progress: &(dyn Fn(Progress) + Sync),
    ) {
        let mut report = self.report.lock().unwrap_or_else(|p| p.into_inner());
        match outcome {
            Outcome::Made(bytes, work) => {
                report.made += 1;
                report.stored_bytes += bytes;
                report.stages += work.stages;
                report.compressing += work.compressing;
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
            if let Ok(pending) = coordinator.pending(JobKind::Seed) {
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

/// What the seed's threads share.
struct Workers<'a> {
    provider: &'a dyn TileProvider,
    /// The memo the provider's renders fill, kept in the store as tiles are stored.
    solutions: &'a Solutions,
    store: &'a dyn TileStore,
    coordinator: &'a dyn Coordinator,
    render_limit: Option<Duration>,
    /// Rows the threads finished, and a signal each time: a thread with nothing to take waits
    /// on it (or on [`IDLE_LOOK`], for rows held elsewhere) before it looks again.
    finished: (Mutex<u64>, Condvar),
}

impl Workers<'_> {
    /// One thread's loop: takes a tile's rows until the queue is empty or the seed stops.
    fn work(
        &self,
        stopped: &dyn Fn() -> bool,
        tell: impl Fn((TileKey, Outcome)),
    ) -> Result<(), StoreError> {
        let (count, signal) = &self.finished;
        while !stopped() {
            let seen = *count.lock().unwrap_or_else(|p| p.into_inner());
            let jobs = self.coordinator.take(JobKind::Seed)?;
            if jobs.is_empty() {
                if self.coordinator.pending(JobKind::Seed)? == 0 {
                    return Ok(());
                }
                let guard = count.lock().unwrap_or_else(|p| p.into_inner());
                let _ = signal
                    .wait_timeout_while(guard, IDLE_LOOK, |now| *now == seen)
                    .map_err(|p| p.into_inner());
                continue;
            }
            let outcomes = self.make_rows(&jobs);
            *count.lock().unwrap_or_else(|p| p.into_inner()) += jobs.len() as u64;
            signal.notify_all();
            for outcome in outcomes? {
                tell(outcome);
            }
        }
        Ok(())
    }

    /// Makes the tile of the rows taken (one tile's formats), together, and finishes, defers
    /// or fails each row.
    fn make_rows(&self, jobs: &[Job]) -> Result<Vec<(TileKey, Outcome)>, StoreError> {
        let (store, coordinator) = (self.store, self.coordinator);
        let mut outcomes = Vec::with_capacity(jobs.len());
        let mut claimed = Vec::with_capacity(jobs.len());
        let Some(tile) = jobs.first().map(|job| job.key.tile) else {
            return Ok(outcomes);
        };
        let held = store.list(&TileFilter::Tiles(vec![tile]))?;
        let wanted = self.provider.provenance(tile);
        for job in jobs {
            let key = job.key;
            let current = held
                .iter()
                .any(|entry| entry.key == key && Some(&entry.made_by) == wanted.as_ref());
            if current && !job.force {
                coordinator.finish(&key, false)?;
                outcomes.push((key, Outcome::Current));
            } else if coordinator.claim(&key)? {
                claimed.push(key);
            } else {
                coordinator.defer(&key, CLAIMED_ELSEWHERE)?;
                outcomes.push((key, Outcome::Deferred));
            }
        }
        if claimed.is_empty() {
            return Ok(outcomes);
        }
        let made_by = wanted.unwrap_or_default();
        let made = make_tiles(self.provider, (&claimed, made_by), self.render_limit);
        let result = self.keep(&claimed, made, &mut outcomes);
        for key in &claimed {
            coordinator.release(key)?;
        }
        result.map(|()| outcomes)
    }

    /// Stores the tiles made, or fails their rows.
    fn keep(
        &self,
        keys: &[TileKey],
        made: Result<(Vec<StoredTile>, Work), String>,
        outcomes: &mut Vec<(TileKey, Outcome)>,
    ) -> Result<(), StoreError> {
        let (store, coordinator) = (self.store, self.coordinator);
        let (tiles, work) = match made {
            Ok(made) => made,
            Err(error) => {
                let tile = keys[0].tile;
                tracing::error!(%tile, %error, "tile failed");
                for key in keys {
                    let set_aside = coordinator.fail(key, &error)?;
                    outcomes.push((*key, Outcome::Failed(error.clone(), set_aside)));
                }
                return Ok(());
            }
        };
        for (key, tile) in keys.iter().zip(&tiles) {
            // Whole or not at all: the row is replaced in one transaction.
            store.put(key, tile)?;
        }
        // Kept for later renders when they can be: a tile stored without them is still
        // whole.
        if let Err(error) = crate::provider::save_solutions(store, self.solutions) {
            tracing::warn!(%error, "keeping solved elevation components failed");
        }
        // Servers holding an older version in memory drop it.
        coordinator.broadcast(&Event::Stored(keys.to_vec()))?;
        for (k, (key, tile)) in keys.iter().zip(&tiles).enumerate() {
            coordinator.finish(key, true)?;
            let work = if k == 0 { work } else { Work::default() };
            outcomes.push((*key, Outcome::Made(tile.bodies.stored_len() as u64, work)));
        }
        Ok(())
    }
}

/// The work that made a tile: its render's stages and its compression.
#[derive(Debug, Clone, Copy, Default)]
struct Work {
    stages: StageTimings,
    compressing: Duration,
}

/// Makes one tile in the formats of `keys`, together, as the store keeps them (compressed,
/// with their validators and the provenance `made_by`), with the work it took.
fn make_tiles(
    provider: &dyn TileProvider,
    (keys, made_by): (&[TileKey], Provenance),
    render_limit: Option<Duration>,
) -> Result<(Vec<StoredTile>, Work), String> {
    let deadline = render_limit.map_or(Deadline::none(), Deadline::after);
    let made = provider
        .make_together(keys, deadline)
        .map_err(|e| e.to_string())?;
    let mut work = Work::default();
    let mut tiles = Vec::with_capacity(made.len());
    // The stages of the renders, each counted once however many formats it made.
    let mut render = StageTimings::default();
    for made in made {
        if !made.shared {
            work.stages += render;
            render = StageTimings::default();
        }
        render.add_shared(made.timings);
        let started = Instant::now();
        tiles.push(StoredTile {
            etag: etag_of(&made.bytes),
            bodies: Bodies::compress(made.bytes).map_err(|e| e.to_string())?,
            made_by: made_by.clone(),
            created_at: unix_now(),
        });
        work.compressing += started.elapsed();
    }
    work.stages += render;
    Ok((tiles, work))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_split_the_tiles_without_overlap_or_gap() {
        let shards: Vec<Shard> = ["1/3", "2/3", "3/3"]
            .iter()
            .map(|s| s.parse().unwrap())
            .collect();
        for position in 0..100u64 {
            let takers = shards.iter().filter(|s| s.takes(position)).count();
            assert_eq!(takers, 1, "tile {position}");
        }
        for bad in ["0/3", "4/3", "3", "a/b", "1/0"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }
}
