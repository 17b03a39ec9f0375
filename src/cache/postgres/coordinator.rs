//! The coordinator of a store shared by a cluster: claims, the queue and broadcasts are the
//! cluster's ([`Cluster`]), so every process sees the same ones.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use super::cluster::Cluster;
use crate::cache::coordinator::{Coordinator, Event, Job, JobKind, Listener, Priority};
use crate::cache::store::{StoreError, TileFilter};
use crate::format::TileKey;

/// How long a stale tile queued in the cluster is not queued again by this process (each
/// request meeting it would otherwise write the row again).
const STALE_REQUEUE: Duration = Duration::from_secs(30);

pub struct Shared {
    cluster: Arc<Cluster>,
    /// Told what is heard from the others, and work queued here.
    listeners: Arc<Mutex<Vec<Listener>>>,
    listening: std::sync::Once,
    /// Rows this process has taken and not finished.
    taken: AtomicUsize,
    /// Stale tiles lately queued by this process.
    told_stale: moka::sync::Cache<TileKey, ()>,
}

impl std::fmt::Debug for Shared {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Shared")
            .field("cluster", &self.cluster)
            .finish_non_exhaustive()
    }
}

impl Shared {
    pub fn new(cluster: Cluster) -> Shared {
        Shared {
            cluster: Arc::new(cluster),
            listeners: Arc::default(),
            listening: std::sync::Once::new(),
            taken: AtomicUsize::new(0),
            told_stale: moka::sync::Cache::builder()
                .max_capacity(100_000)
                .time_to_live(STALE_REQUEUE)
                .build(),
        }
    }

    fn tell_listeners(listeners: &Mutex<Vec<Listener>>, event: &Event) {
        let listeners = listeners.lock().unwrap_or_else(|p| p.into_inner()).clone();
        for listener in listeners {
            listener(event.clone());
        }
    }

    /// One row fewer in hand.
    fn put_down(&self) {
        let _ = self
            .taken
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |n| {
                Some(n.saturating_sub(1))
            });
    }
}

impl Coordinator for Shared {
    fn holder(&self) -> &str {
        self.cluster.holder()
    }

    fn join(&self, kind: &str) -> Result<(), StoreError> {
        self.cluster.register(kind)?;
        self.cluster
            .start_heartbeat()
            .map_err(|e| StoreError::Panicked(format!("starting the heartbeat: {e}")))
    }

    fn listen(&self, on_event: Listener) -> Result<(), StoreError> {
        self.listeners
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push(on_event);
        let mut started = Ok(());
        self.listening.call_once(|| {
            let listeners = self.listeners.clone();
            started = self
                .cluster
                .listen(move |event| Shared::tell_listeners(&listeners, &event))
                .map_err(|e| StoreError::Panicked(format!("listening to the cluster: {e}")));
        });
        started
    }

    fn claim(&self, key: &TileKey) -> Result<bool, StoreError> {
        self.cluster.try_lease(key)
    }

    fn release(&self, key: &TileKey) -> Result<(), StoreError> {
        self.cluster.release(key)
    }

    fn enqueue(
        &self,
        keys: &[TileKey],
        kind: JobKind,
        priority: Priority,
        force: bool,
    ) -> Result<u64, StoreError> {
        let fresh: Vec<TileKey>;
        let keys = if priority == Priority::Stale {
            fresh = keys
                .iter()
                .copied()
                .filter(|key| !self.told_stale.contains_key(key))
                .collect();
            for key in &fresh {
                self.told_stale.insert(*key, ());
            }
            &fresh[..]
        } else {
            keys
        };
        if keys.is_empty() {
            return Ok(0);
        }
        let queued = self.cluster.enqueue(keys, kind, priority, force)?;
        if queued > 0 {
            // The cluster's broadcast reaches the others; this process's workers are woken here.
            Shared::tell_listeners(&self.listeners, &Event::Work);
        }
        Ok(queued)
    }

    fn take(&self, kind: JobKind) -> Result<Vec<Job>, StoreError> {
        let jobs = self.cluster.take(kind)?;
        self.taken.fetch_add(jobs.len(), Ordering::Relaxed);
        Ok(jobs)
    }

    fn finish(&self, key: &TileKey, made: bool) -> Result<(), StoreError> {
        self.put_down();
        self.cluster.finish(key, made)
    }

    fn defer(&self, key: &TileKey, after: Duration) -> Result<(), StoreError> {
        self.put_down();
        self.cluster.defer(key, after)
    }

    fn fail(&self, key: &TileKey, error: &str) -> Result<bool, StoreError> {
        self.put_down();
        self.cluster.fail(key, error)
    }

    fn pending(&self, kind: JobKind) -> Result<u64, StoreError> {
        self.cluster.pending(kind)
    }

    fn in_hand(&self) -> usize {
        self.taken.load(Ordering::Relaxed)
    }

    fn withdraw(&self, _filter: &TileFilter) -> usize {
        0
    }

    fn broadcast(&self, event: &Event) -> Result<(), StoreError> {
        self.cluster.broadcast(event)
    }
}
