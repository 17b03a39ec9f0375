//! How the processes sharing a store share the work on it: render claims, the queue of tiles
//! to make (again), and what one process tells the others. A [`Coordinator`] is chosen once,
//! when the store is opened: [`Local`] for a store one process owns (SQLite), the PostgreSQL
//! one ([`crate::cache::postgres::coordinator`]) for a store a cluster shares. The cache, the
//! server's background workers and the seed are written once, against the trait.
//!
//! Calls block, like the store's.

use std::collections::{BTreeSet, HashMap};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::cache::store::{StoreError, TileFilter};
use crate::format::{Format, TileKey};

/// Why a tile is in the work queue.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum JobKind {
    /// Made again: stale, asked for by an operator, or its sources changed. Servers take these.
    Regenerate,
    /// Seeded: `terrastitch seed` workers take these.
    Seed,
}

impl JobKind {
    pub fn as_str(self) -> &'static str {
        match self {
            JobKind::Regenerate => "regenerate",
            JobKind::Seed => "seed",
        }
    }
}

/// The order rows are taken in, lowest first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Priority {
    /// A stale tile a request met.
    Stale = 0,
    /// A tile to make again.
    Regenerate = 1,
    /// A tile to seed.
    Seed = 2,
}

/// A row of work taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Job {
    pub key: TileKey,
    /// Make it even if the tile stored is current.
    pub force: bool,
    /// How many times it was taken, this one included.
    pub attempts: i32,
}

/// What one process tells the others (and its own listeners, for [`Event::Work`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Event {
    /// New versions of these tiles are stored.
    Stored(Vec<TileKey>),
    /// The tiles the filter selects were removed.
    Purged(TileFilter),
    /// Work was queued.
    Work,
    /// Broadcasts may have been missed (the listening connection was lost): memory cannot be
    /// trusted to be current.
    Missed,
}

/// Called with each event heard.
pub type Listener = Arc<dyn Fn(Event) + Send + Sync>;

/// Claims, the work queue and broadcasts, for one process.
pub trait Coordinator: Send + Sync + std::fmt::Debug {
    /// This process's name among those sharing the store.
    fn holder(&self) -> &str;

    /// Whether this process is the only one working on the store: its claims are then always
    /// granted and nobody hears its broadcasts, so neither need be asked for.
    fn alone(&self) -> bool {
        false
    }

    /// Says this process takes part, as a `kind` (`serve`, `seed`), and keeps its claims and
    /// taken rows alive for as long as the coordinator is in use.
    fn join(&self, kind: &str) -> Result<(), StoreError>;

    /// Hands `on_event` what the other processes tell, and [`Event::Work`] when work is queued
    /// (by any process).
    fn listen(&self, on_event: Listener) -> Result<(), StoreError>;

    /// Claims `key` for a render: true when this process may make it now, false while another
    /// process makes it.
    fn claim(&self, key: &TileKey) -> Result<bool, StoreError>;

    /// Gives up the claim on `key`, if this process holds it.
    fn release(&self, key: &TileKey) -> Result<(), StoreError>;

    /// Queues tiles as `kind` work at `priority` (a tile already queued keeps its place, or
    /// moves up); returns how many were added or changed, and tells the listeners.
    fn enqueue(
        &self,
        keys: &[TileKey],
        kind: JobKind,
        priority: Priority,
        force: bool,
    ) -> Result<u64, StoreError>;

    /// Takes the next row of `kind` nobody holds, with the other rows of `kind` of its tile
    /// that wait (its other formats, which are made together cheaper than one by one); none
    /// when no row waits.
    fn take(&self, kind: JobKind) -> Result<Vec<Job>, StoreError>;

    /// Done with a taken row: it leaves the queue; `made` counts a tile made.
    fn finish(&self, key: &TileKey, made: bool) -> Result<(), StoreError>;

    /// Hands a taken row back, to be taken again after `after` (its tile is being made by
    /// another process).
    fn defer(&self, key: &TileKey, after: Duration) -> Result<(), StoreError>;

    /// A taken row whose tile failed: tried again later, or set aside; returns whether it was
    /// set aside.
    fn fail(&self, key: &TileKey, error: &str) -> Result<bool, StoreError>;

    /// Rows of `kind` waiting or taken, by any process.
    fn pending(&self, kind: JobKind) -> Result<u64, StoreError>;

    /// Rows this process has in hand, without asking anyone: every row queued here when work
    /// is not shared, the rows taken here when it is.
    fn in_hand(&self) -> usize;

    /// Takes the waiting rows `filter` selects out of the queue (their tiles were purged);
    /// returns how many. A queue shared with others keeps them: whoever takes one finds its
    /// tile gone and makes nothing.
    fn withdraw(&self, filter: &TileFilter) -> usize;

    /// Tells every other process.
    fn broadcast(&self, event: &Event) -> Result<(), StoreError>;
}

/// The coordinator of a store one process owns: claims always granted (the cache's own
/// single flight keeps one render a key), the queue in memory, nobody to tell.
#[derive(Default)]
pub struct Local {
    queue: Mutex<LocalQueue>,
    listeners: Mutex<Vec<Listener>>,
}

impl std::fmt::Debug for Local {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Local").finish_non_exhaustive()
    }
}

#[derive(Debug, Clone, Copy)]
struct Row {
    kind: JobKind,
    priority: Priority,
    force: bool,
    /// Its place in line (`None` once taken).
    place: Option<u64>,
    attempts: i32,
}

#[derive(Debug, Default)]
struct LocalQueue {
    rows: HashMap<TileKey, Row>,
    /// The rows waiting, by kind, in the order they are taken.
    waiting: HashMap<JobKind, BTreeSet<(Priority, u64, TileKey)>>,
    queued: u64,
}

impl LocalQueue {
    fn line(&mut self, kind: JobKind) -> &mut BTreeSet<(Priority, u64, TileKey)> {
        self.waiting.entry(kind).or_default()
    }

    /// Puts `key` in line at the back of its priority.
    fn place(&mut self, key: TileKey, row: &mut Row) {
        self.queued += 1;
        row.place = Some(self.queued);
        let entry = (row.priority, self.queued, key);
        self.line(row.kind).insert(entry);
    }

    fn queue(&mut self, key: TileKey, kind: JobKind, priority: Priority, force: bool) -> bool {
        match self.rows.get(&key).copied() {
            None => {
                let mut row = Row {
                    kind,
                    priority,
                    force,
                    place: None,
                    attempts: 0,
                };
                self.place(key, &mut row);
                self.rows.insert(key, row);
                true
            }
            Some(mut row) => {
                // Taken: the render under way serves.
                let Some(place) = row.place else { return false };
                if row.priority <= priority && (row.force || !force) {
                    return false;
                }
                self.line(row.kind).remove(&(row.priority, place, key));
                row.priority = row.priority.min(priority);
                row.force |= force;
                self.place(key, &mut row);
                self.rows.insert(key, row);
                true
            }
        }
    }

    fn take(&mut self, kind: JobKind) -> Vec<Job> {
        let Some((_, _, first)) = self.line(kind).pop_first() else {
            return Vec::new();
        };
        let mut jobs: Vec<Job> = self.taken(first).into_iter().collect();
        for format in Format::every().filter(|format| *format != first.format) {
            let key = TileKey {
                tile: first.tile,
                format,
            };
            let Some(row) = self.rows.get(&key).filter(|row| row.kind == kind) else {
                continue;
            };
            if let Some(place) = row.place {
                let entry = (row.priority, place, key);
                self.line(kind).remove(&entry);
                jobs.extend(self.taken(key));
            }
        }
        jobs
    }

    /// Marks the row of `key`, out of its line, as taken.
    fn taken(&mut self, key: TileKey) -> Option<Job> {
        let row = self.rows.get_mut(&key)?;
        row.place = None;
        row.attempts += 1;
        Some(Job {
            key,
            force: row.force,
            attempts: row.attempts,
        })
    }
}

impl Local {
    pub fn new() -> Local {
        Local::default()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, LocalQueue> {
        self.queue.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn tell_listeners(&self, event: &Event) {
        let listeners = self
            .listeners
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone();
        for listener in listeners {
            listener(event.clone());
        }
    }
}

impl Coordinator for Local {
    fn holder(&self) -> &str {
        "this process"
    }

    fn alone(&self) -> bool {
        true
    }

    fn join(&self, _kind: &str) -> Result<(), StoreError> {
        Ok(())
    }

    fn listen(&self, on_event: Listener) -> Result<(), StoreError> {
        self.listeners
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push(on_event);
        Ok(())
    }

    fn claim(&self, _key: &TileKey) -> Result<bool, StoreError> {
        Ok(true)
    }

    fn release(&self, _key: &TileKey) -> Result<(), StoreError> {
        Ok(())
    }

    fn enqueue(
        &self,
        keys: &[TileKey],
        kind: JobKind,
        priority: Priority,
        force: bool,
    ) -> Result<u64, StoreError> {
        let mut queue = self.lock();
        let queued = keys
            .iter()
            .filter(|&&key| queue.queue(key, kind, priority, force))
            .count() as u64;
        drop(queue);
        if queued > 0 {
            self.tell_listeners(&Event::Work);
        }
        Ok(queued)
    }

    fn take(&self, kind: JobKind) -> Result<Vec<Job>, StoreError> {
        Ok(self.lock().take(kind))
    }

    fn finish(&self, key: &TileKey, _made: bool) -> Result<(), StoreError> {
        let mut queue = self.lock();
        if queue.rows.get(key).is_some_and(|row| row.place.is_none()) {
            queue.rows.remove(key);
        }
        Ok(())
    }

    fn defer(&self, key: &TileKey, _after: Duration) -> Result<(), StoreError> {
        let mut queue = self.lock();
        if let Some(mut row) = queue.rows.get(key).copied().filter(|r| r.place.is_none()) {
            row.attempts -= 1;
            queue.place(*key, &mut row);
            queue.rows.insert(*key, row);
        }
        Ok(())
    }

    /// Set aside at once: the same sources make the same failure again.
    fn fail(&self, key: &TileKey, _error: &str) -> Result<bool, StoreError> {
        self.finish(key, false)?;
        Ok(true)
    }

    fn pending(&self, kind: JobKind) -> Result<u64, StoreError> {
        let queue = self.lock();
        Ok(queue.rows.values().filter(|row| row.kind == kind).count() as u64)
    }

    fn in_hand(&self) -> usize {
        self.lock().rows.len()
    }

    fn withdraw(&self, filter: &TileFilter) -> usize {
        let mut queue = self.lock();
        let LocalQueue { rows, waiting, .. } = &mut *queue;
        let mut withdrawn = 0;
        for line in waiting.values_mut() {
            line.retain(|(_, _, key)| {
                let keep = !filter.matches(key.tile);
                if !keep {
                    rows.remove(key);
                    withdrawn += 1;
                }
                keep
            });
        }
        withdrawn
    }

    fn broadcast(&self, _event: &Event) -> Result<(), StoreError> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::Variant;
    use crate::tile::TileId;

    fn key(x: u32) -> TileKey {
        TileKey {
            tile: TileId { z: 14, x, y: 5 },
            format: Format::Glb(Variant::default()),
        }
    }

    /// The one row taken, if any.
    fn one(taken: Result<Vec<Job>, StoreError>) -> Option<Job> {
        let mut jobs = taken.unwrap();
        assert!(jobs.len() <= 1, "one row a tile: {jobs:?}");
        jobs.pop()
    }

    #[test]
    fn a_tiles_waiting_formats_are_taken_with_it_and_no_other_tiles() {
        let local = Local::new();
        let in_format = |x, format| TileKey {
            tile: TileId { z: 14, x, y: 5 },
            format,
        };
        let terrain = Format::Terrain(Default::default());
        let meshopt = Format::Glb(Variant {
            meshopt: true,
            ..Variant::default()
        });
        let seeded = [key(1), in_format(1, terrain), key(2), in_format(1, meshopt)];
        local
            .enqueue(&seeded, JobKind::Seed, Priority::Seed, false)
            .unwrap();
        local
            .enqueue(&[key(3)], JobKind::Regenerate, Priority::Stale, false)
            .unwrap();
        let mut first: Vec<TileKey> = local
            .take(JobKind::Seed)
            .unwrap()
            .iter()
            .map(|job| job.key)
            .collect();
        first.sort();
        let mut tile_1 = vec![key(1), in_format(1, terrain), in_format(1, meshopt)];
        tile_1.sort();
        assert_eq!(first, tile_1);
        assert_eq!(one(local.take(JobKind::Seed)).unwrap().key, key(2));
        assert_eq!(local.take(JobKind::Seed).unwrap(), []);
        assert_eq!(
            local.pending(JobKind::Seed).unwrap(),
            4,
            "taken, not finished"
        );
    }

    #[test]
    fn rows_are_taken_by_priority_then_in_the_order_queued() {
        let local = Local::new();
        local
            .enqueue(
                &[key(1), key(2)],
                JobKind::Regenerate,
                Priority::Regenerate,
                false,
            )
            .unwrap();
        local
            .enqueue(&[key(3)], JobKind::Regenerate, Priority::Stale, false)
            .unwrap();
        let order: Vec<u32> = std::iter::from_fn(|| one(local.take(JobKind::Regenerate)))
            .map(|job| job.key.tile.x)
            .collect();
        assert_eq!(order, [3, 1, 2]);
        assert_eq!(local.take(JobKind::Seed).unwrap(), []);
    }

    #[test]
    fn a_tile_queued_twice_is_made_once_and_moves_up() {
        let local = Local::new();
        let queue = |keys: &[TileKey], priority| {
            local
                .enqueue(keys, JobKind::Regenerate, priority, false)
                .unwrap()
        };
        assert_eq!(queue(&[key(1), key(2)], Priority::Regenerate), 2);
        assert_eq!(queue(&[key(2)], Priority::Regenerate), 0);
        assert_eq!(queue(&[key(2)], Priority::Stale), 1);
        assert_eq!(one(local.take(JobKind::Regenerate)).unwrap().key, key(2));
        // Taken: queued again, it is not made twice.
        assert_eq!(queue(&[key(2)], Priority::Stale), 0);
        assert_eq!(local.pending(JobKind::Regenerate).unwrap(), 2);
        local.finish(&key(2), true).unwrap();
        assert_eq!(local.pending(JobKind::Regenerate).unwrap(), 1);
        assert_eq!(local.in_hand(), 1);
    }

    #[test]
    fn queued_work_is_told_to_the_listeners_and_purged_work_withdrawn() {
        let local = Local::new();
        let heard = Arc::new(Mutex::new(Vec::new()));
        let hearing = heard.clone();
        local
            .listen(Arc::new(move |event| hearing.lock().unwrap().push(event)))
            .unwrap();
        local
            .enqueue(&[key(1), key(2)], JobKind::Seed, Priority::Seed, false)
            .unwrap();
        assert_eq!(*heard.lock().unwrap(), [Event::Work]);
        let taken = one(local.take(JobKind::Seed)).unwrap();
        let all = TileFilter::All;
        assert_eq!(local.withdraw(&all), 1, "the taken row stays");
        assert_eq!(local.pending(JobKind::Seed).unwrap(), 1);
        assert!(local.fail(&taken.key, "no").unwrap());
        assert_eq!(local.pending(JobKind::Seed).unwrap(), 0);
    }

    #[test]
    fn a_deferred_row_goes_back_in_line() {
        let local = Local::new();
        local
            .enqueue(&[key(1)], JobKind::Seed, Priority::Seed, true)
            .unwrap();
        let job = one(local.take(JobKind::Seed)).unwrap();
        assert!(job.force);
        assert_eq!(local.take(JobKind::Seed).unwrap(), []);
        local.defer(&job.key, Duration::ZERO).unwrap();
        let again = one(local.take(JobKind::Seed)).unwrap();
        assert_eq!((again.key, again.attempts), (key(1), 1));
    }
}
