//! Memory a piece of work may take: a render, say, runs [`within`] a [`Budget`], and every
//! allocation its threads make is counted against it by the [`Counting`] allocator (when the
//! program installs it as its global allocator). Crossing the budget does not stop an
//! allocation (an allocator cannot fail one without aborting the process); it marks the
//! budget [`exceeded`], and the work gives up at its next check, as it does at a deadline.
//!
//! A thread runs under at most one budget; threads a piece of work shares itself out over
//! ([`crate::parallel`]) run under the budget of the thread that started them. Memory freed
//! by a thread is taken off the budget it runs under, if any: what a render hands on (its
//! bytes) is charged to it and freed elsewhere.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicBool, AtomicIsize, AtomicUsize, Ordering};

/// How much memory a piece of work may hold at once.
#[derive(Debug)]
pub struct Budget {
    limit: usize,
    live: AtomicIsize,
    peak: AtomicUsize,
    exceeded: AtomicBool,
}

impl Budget {
    /// A budget of `limit` bytes.
    pub fn new(limit: usize) -> Budget {
        Budget {
            limit,
            live: AtomicIsize::new(0),
            peak: AtomicUsize::new(0),
            exceeded: AtomicBool::new(false),
        }
    }

    pub fn limit(&self) -> usize {
        self.limit
    }

    /// The most the work held at once, bytes.
    pub fn peak(&self) -> usize {
        self.peak.load(Ordering::Relaxed)
    }

    /// Whether the work has held more than its limit at some point.
    pub fn is_exceeded(&self) -> bool {
        self.exceeded.load(Ordering::Relaxed)
    }

    fn charge(&self, bytes: isize) {
        let live = self.live.fetch_add(bytes, Ordering::Relaxed) + bytes;
        if bytes > 0 {
            let live = live.max(0) as usize;
            self.peak.fetch_max(live, Ordering::Relaxed);
            if live > self.limit {
                self.exceeded.store(true, Ordering::Relaxed);
            }
        }
    }
}

thread_local! {
    /// The budget the thread runs under. Const-initialised and without a destructor, so that
    /// reading it never allocates (it is read inside the allocator).
    static CURRENT: Cell<*const Budget> = const { Cell::new(std::ptr::null()) };
}

/// Runs `f` on this thread under `budget` (and the threads it shares its work out over).
pub fn within<R>(budget: &Budget, f: impl FnOnce() -> R) -> R {
    under(budget as *const Budget, f)
}

/// Runs `f` with `budget` as this thread's, the one before restored after, however `f` ends.
fn under<R>(budget: *const Budget, f: impl FnOnce() -> R) -> R {
    struct Restore(*const Budget);
    impl Drop for Restore {
        fn drop(&mut self) {
            let _ = CURRENT.try_with(|c| c.set(self.0));
        }
    }
    let _restore = Restore(CURRENT.with(|c| c.replace(budget)));
    f()
}

/// Whether the work this thread runs under a budget has exceeded it (never, under none).
pub fn exceeded() -> Option<usize> {
    CURRENT.with(|c| {
        let budget = c.get();
        // SAFETY: the pointer is set only by `within` (or `Inherited::run`, under a `within`
        // of the thread that made it) for as long as that budget is borrowed, and restored
        // before the borrow ends.
        let budget = unsafe { budget.as_ref() }?;
        budget.is_exceeded().then_some(budget.limit)
    })
}

/// The budget of this thread, to run threads it starts under it: see [`Inherited::run`].
#[derive(Clone, Copy)]
pub struct Inherited(*const Budget);

// SAFETY: a budget is only atomics; the pointer is dereferenced only while the `within` that
// set it is running, which `Inherited::here`'s contract (scoped threads) guarantees.
unsafe impl Send for Inherited {}
unsafe impl Sync for Inherited {}

impl Inherited {
    /// This thread's budget, for threads started in a [`std::thread::scope`] that ends before
    /// this thread leaves its [`within`].
    pub fn here() -> Inherited {
        Inherited(CURRENT.with(Cell::get))
    }

    /// Runs `f` on this thread under the budget it was taken from.
    pub fn run<R>(self, f: impl FnOnce() -> R) -> R {
        under(self.0, f)
    }
}

fn charge(bytes: isize) {
    // `try_with`: a thread being torn down has no budget left to charge.
    let _ = CURRENT.try_with(|c| {
        // SAFETY: as in `exceeded`.
        if let Some(budget) = unsafe { c.get().as_ref() } {
            budget.charge(bytes);
        }
    });
}

/// The system allocator, counting what each thread running under a [`Budget`] allocates and
/// frees against it.
pub struct Counting;

// SAFETY: every call is passed to the system allocator as it is; counting allocates nothing.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract is passed on.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            charge(layout.size() as isize);
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract is passed on.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            charge(layout.size() as isize);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract is passed on.
        unsafe { System.dealloc(ptr, layout) };
        charge(-(layout.size() as isize));
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller's contract is passed on.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            charge(new_size as isize - layout.size() as isize);
        }
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn work_within_a_budget_is_charged_and_told_when_it_exceeds() {
        let budget = Budget::new(1 << 20);
        within(&budget, || {
            // Charged by hand: unit tests run without the counting allocator.
            charge(600 << 10);
            assert_eq!(exceeded(), None);
            charge(600 << 10);
            assert_eq!(exceeded(), Some(1 << 20));
            charge(-(1200 << 10));
        });
        assert!(budget.is_exceeded());
        assert_eq!(budget.peak(), 1200 << 10);
        // Outside it, nothing is charged and nothing is exceeded.
        charge(10 << 20);
        assert_eq!(exceeded(), None);
        assert_eq!(budget.peak(), 1200 << 10);
    }

    #[test]
    fn threads_started_within_a_budget_charge_it() {
        let budget = Budget::new(1000);
        within(&budget, || {
            let inherited = Inherited::here();
            std::thread::scope(|scope| {
                scope.spawn(move || inherited.run(|| charge(2000)));
            });
            assert_eq!(exceeded(), Some(1000));
        });
        assert!(budget.is_exceeded());
    }
}
