//! One lookup-or-render of a key at a time, whoever waits for it: the work runs as a task of
//! its own, and every request for the key while it runs waits for that task, even when the
//! request that started it has gone away (a client that drops its request cannot make the
//! next one start a second render).

use std::any::Any;
use std::collections::HashMap;
use std::future::Future;
use std::sync::{Arc, Mutex};

use tokio::sync::watch;

use super::{CacheError, CachedTile};
use crate::format::TileKey;

/// What a flight ends with, shared by everyone waiting for it.
type Outcome<E> = Result<Arc<CachedTile>, Arc<CacheError<E>>>;

/// The flights under way: for each key, where its outcome will be told (a
/// `watch::Receiver<Option<Outcome<E>>>`, kept as `Any` since the error type is the caller's).
#[derive(Default)]
pub struct Flights {
    under_way: Mutex<HashMap<TileKey, Box<dyn Any + Send + Sync>>>,
}

impl std::fmt::Debug for Flights {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Flights")
            .field("under_way", &self.len())
            .finish()
    }
}

impl Flights {
    /// Waits for the flight of `key`, starting `work` as one when none is under way.
    pub async fn join_or_start<E, W>(self: Arc<Self>, key: TileKey, work: W) -> Outcome<E>
    where
        E: std::error::Error + Send + Sync + 'static,
        W: Future<Output = Result<Arc<CachedTile>, CacheError<E>>> + Send + 'static,
    {
        let mut receiver = self.join_or_start_receiver(key, work);
        let told = receiver.wait_for(Option::is_some).await;
        match told.as_deref() {
            Ok(Some(outcome)) => outcome.clone(),
            // The task went away without telling (it panicked past its own guard).
            _ => Err(Arc::new(CacheError::Panicked(format!(
                "the work on {key:?} ended without an outcome"
            )))),
        }
    }

    fn join_or_start_receiver<E, W>(
        self: &Arc<Self>,
        key: TileKey,
        work: W,
    ) -> watch::Receiver<Option<Outcome<E>>>
    where
        E: std::error::Error + Send + Sync + 'static,
        W: Future<Output = Result<Arc<CachedTile>, CacheError<E>>> + Send + 'static,
    {
        let mut under_way = self.lock();
        if let Some(receiver) = under_way
            .get(&key)
            .and_then(|r| r.downcast_ref::<watch::Receiver<Option<Outcome<E>>>>())
        {
            return receiver.clone();
        }
        let (sender, receiver) = watch::channel(None);
        under_way.insert(key, Box::new(receiver.clone()));
        drop(under_way);
        let flights = self.clone();
        tokio::spawn(async move {
            let outcome = match tokio::spawn(work).await {
                Ok(result) => result.map_err(Arc::new),
                Err(error) => Err(Arc::new(CacheError::Panicked(super::panic_message(error)))),
            };
            // Gone from the list before it is told: a request coming after finds the tile in
            // the store, or starts anew after a failure.
            flights.lock().remove(&key);
            let _ = sender.send(Some(outcome));
        });
        receiver
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<TileKey, Box<dyn Any + Send + Sync>>> {
        self.under_way.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Flights under way.
    pub fn len(&self) -> usize {
        self.lock().len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cache::encoding::Bodies;
    use crate::cache::{Origin, Provenance};
    use std::sync::atomic::{AtomicUsize, Ordering};

    fn tile() -> Arc<CachedTile> {
        Arc::new(CachedTile {
            bodies: Bodies::compress(b"tile".to_vec()).unwrap(),
            etag: "\"e\"".to_string(),
            made_by: Provenance::default(),
            loaded_from: Origin::Rendered,
            stored: true,
        })
    }

    #[tokio::test]
    async fn a_flight_whose_first_waiter_went_away_is_joined_not_started_again() {
        let flights = Arc::new(Flights::default());
        let key = TileKey {
            tile: crate::tile::TileId { z: 14, x: 1, y: 2 },
            format: crate::format::Format::GLB,
        };
        let started = Arc::new(AtomicUsize::new(0));
        // The work waits at a gate the test opens.
        let (open, gate) = tokio::sync::watch::channel(false);
        let work = |started: Arc<AtomicUsize>| {
            let mut gate = gate.clone();
            async move {
                started.fetch_add(1, Ordering::SeqCst);
                let _ = gate.wait_for(|open| *open).await;
                Ok::<_, CacheError<std::io::Error>>(tile())
            }
        };
        // The first waiter is dropped once its work has begun; the second and third join its
        // flight before the gate opens.
        let first = tokio::spawn(flights.clone().join_or_start(key, work(started.clone())));
        while started.load(Ordering::SeqCst) == 0 {
            tokio::task::yield_now().await;
        }
        first.abort();
        assert!(first.await.is_err(), "the first waiter was dropped");
        let second = flights.clone().join_or_start(key, work(started.clone()));
        let third = flights.clone().join_or_start(key, work(started.clone()));
        let opening = async {
            open.send_replace(true);
        };
        let (second, third, ()) = tokio::join!(second, third, opening);
        assert!(second.is_ok() && third.is_ok());
        assert_eq!(started.load(Ordering::SeqCst), 1, "one flight for the key");
        assert_eq!(flights.len(), 0, "a landed flight is gone from the list");
        // After it landed, a new flight starts.
        flights
            .clone()
            .join_or_start(key, work(started.clone()))
            .await
            .unwrap();
        assert_eq!(started.load(Ordering::SeqCst), 2);
    }
}
