//! The render slots: a fixed number of renders run at once; a bounded number of requests may
//! wait for a slot, and past that a request is turned away at once (the server answers `503`
//! with `Retry-After`) instead of queueing without bound. Background work (stale tiles made
//! again, regeneration) takes a slot only when no request is waiting, and holds at most a set
//! number of slots, so it never starves live requests.
//!
//! The calls block: they run on the blocking pool, next to the render itself.

use std::sync::{Condvar, Mutex};

#[derive(Debug, Default)]
struct Slots {
    free: usize,
    running: usize,
    waiting: usize,
    background_running: usize,
    background_waiting: usize,
    /// No slot is handed out any more.
    closed: bool,
}

#[derive(Debug)]
pub struct RenderPool {
    slots: Mutex<Slots>,
    freed: Condvar,
    /// Requests that may wait for a slot.
    queue_limit: usize,
    /// Slots background work may hold at once.
    background_limit: usize,
}

/// Why no slot was given.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum Refused {
    #[error("{waiting} renders are already waiting for one of {slots} render slots")]
    Busy { waiting: usize, slots: usize },
    #[error("the server is shutting down")]
    Closed,
}

/// A held slot; dropping it frees the slot.
#[derive(Debug)]
pub struct Slot<'a> {
    pool: &'a RenderPool,
    background: bool,
}

impl Drop for Slot<'_> {
    fn drop(&mut self) {
        let mut slots = self.pool.lock();
        slots.free += 1;
        slots.running -= 1;
        if self.background {
            slots.background_running -= 1;
        }
        drop(slots);
        self.pool.freed.notify_all();
    }
}

impl RenderPool {
    pub fn new(threads: usize, queue_limit: usize, background_limit: usize) -> RenderPool {
        RenderPool {
            slots: Mutex::new(Slots {
                free: threads.max(1),
                ..Slots::default()
            }),
            freed: Condvar::new(),
            queue_limit,
            background_limit: background_limit.clamp(1, threads.max(1)),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Slots> {
        self.slots.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// A slot for a request: at once if one is free, else after waiting in the queue; refused
    /// when the queue is full.
    pub fn acquire(&self) -> Result<Slot<'_>, Refused> {
        let mut slots = self.lock();
        if slots.closed {
            return Err(Refused::Closed);
        }
        if slots.free == 0 {
            if slots.waiting >= self.queue_limit {
                return Err(Refused::Busy {
                    waiting: slots.waiting,
                    slots: slots.running,
                });
            }
            slots.waiting += 1;
            while slots.free == 0 && !slots.closed {
                slots = self.freed.wait(slots).unwrap_or_else(|p| p.into_inner());
            }
            slots.waiting -= 1;
            if slots.closed {
                return Err(Refused::Closed);
            }
        }
        slots.free -= 1;
        slots.running += 1;
        if slots.free > 0 {
            // A background waiter woken with this request found it waiting and slept again;
            // a slot is still free for it.
            self.freed.notify_all();
        }
        Ok(Slot {
            pool: self,
            background: false,
        })
    }

    /// A slot for background work: waits until a slot is free, no request is waiting, and
    /// background work holds fewer than its share.
    pub fn acquire_background(&self) -> Result<Slot<'_>, Refused> {
        let mut slots = self.lock();
        slots.background_waiting += 1;
        while !slots.closed
            && (slots.free == 0
                || slots.waiting > 0
                || slots.background_running >= self.background_limit)
        {
            slots = self.freed.wait(slots).unwrap_or_else(|p| p.into_inner());
        }
        slots.background_waiting -= 1;
        if slots.closed {
            return Err(Refused::Closed);
        }
        slots.free -= 1;
        slots.running += 1;
        slots.background_running += 1;
        Ok(Slot {
            pool: self,
            background: true,
        })
    }

    /// Hands out no more slots; waiters are refused. Running renders finish.
    pub fn close(&self) {
        self.lock().closed = true;
        self.freed.notify_all();
    }

    /// Renders running, requests waiting, background work waiting.
    pub fn gauges(&self) -> (usize, usize, usize) {
        let slots = self.lock();
        (slots.running, slots.waiting, slots.background_waiting)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;
    use std::time::Duration;

    #[test]
    fn past_the_queue_a_request_is_refused_at_once() {
        let pool = Arc::new(RenderPool::new(1, 1, 1));
        let held = pool.acquire().unwrap();
        let waiter = {
            let pool = pool.clone();
            std::thread::spawn(move || pool.acquire().map(|_| ()))
        };
        while pool.gauges().1 == 0 {
            std::thread::sleep(Duration::from_millis(1));
        }
        assert!(matches!(
            pool.acquire(),
            Err(Refused::Busy { waiting: 1, .. })
        ));
        drop(held);
        assert_eq!(waiter.join().unwrap(), Ok(()));
        assert!(pool.acquire().is_ok());
    }

    #[test]
    fn background_work_waits_while_a_request_waits() {
        let pool = Arc::new(RenderPool::new(1, 4, 1));
        let held = pool.acquire().unwrap();
        let order = Arc::new(Mutex::new(Vec::new()));
        let background = {
            let (pool, order) = (pool.clone(), order.clone());
            std::thread::spawn(move || {
                let _slot = pool.acquire_background().unwrap();
                order.lock().unwrap().push("background");
            })
        };
        while pool.gauges().2 == 0 {
            std::thread::sleep(Duration::from_millis(1));
        }
        let live = {
            let (pool, order) = (pool.clone(), order.clone());
            std::thread::spawn(move || {
                let _slot = pool.acquire().unwrap();
                order.lock().unwrap().push("request");
                std::thread::sleep(Duration::from_millis(20));
            })
        };
        while pool.gauges().1 == 0 {
            std::thread::sleep(Duration::from_millis(1));
        }
        drop(held);
        live.join().unwrap();
        background.join().unwrap();
        assert_eq!(*order.lock().unwrap(), vec!["request", "background"]);
    }

    #[test]
    fn closing_refuses_the_waiters() {
        let pool = Arc::new(RenderPool::new(1, 4, 1));
        let _held = pool.acquire().unwrap();
        let waiter = {
            let pool = pool.clone();
            std::thread::spawn(move || pool.acquire().map(|_| ()))
        };
        while pool.gauges().1 == 0 {
            std::thread::sleep(Duration::from_millis(1));
        }
        pool.close();
        assert_eq!(waiter.join().unwrap(), Err(Refused::Closed));
    }
}
