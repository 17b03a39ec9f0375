//! Work over a tile's many vertices or triangles shared out over threads in contiguous
//! chunks, the results put back in order: for work whose every item is its own, the result is
//! the one a single thread gives.

/// `f` over `items` in up to `threads` contiguous chunks, each on a thread of its own, the
/// chunks' results concatenated in order.
pub fn map_chunks<T: Sync, R: Send>(
    items: &[T],
    threads: usize,
    f: &(dyn Fn(&[T]) -> Vec<R> + Sync),
) -> Vec<R> {
    let share = items.len().div_ceil(threads.max(1)).max(1);
    // The threads charge their memory to the work that started them.
    let budget = crate::budget::Inherited::here();
    std::thread::scope(|scope| {
        let handles: Vec<_> = items
            .chunks(share)
            .map(|chunk| scope.spawn(move || budget.run(|| f(chunk))))
            .collect();
        handles
            .into_iter()
            .flat_map(|h| {
                h.join()
                    .unwrap_or_else(|payload| std::panic::resume_unwind(payload))
            })
            .collect()
    })
}

/// Threads for `items` items of which `per_thread` are worth a thread, at most `most` and the
/// cores there are.
pub fn threads_for(items: usize, per_thread: usize, most: usize) -> usize {
    std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(most)
        .min(items / per_thread.max(1))
        .max(1)
}

/// `a` and `b` at once, `a` on a thread of its own when there is more than one core: for two
/// pieces of a tile's work that share nothing they write. A panic in either is passed on.
pub fn join<A: Send, B>(a: impl FnOnce() -> A + Send, b: impl FnOnce() -> B) -> (A, B) {
    if threads_for(2, 1, 2) < 2 {
        return (a(), b());
    }
    let budget = crate::budget::Inherited::here();
    std::thread::scope(|scope| {
        let first = scope.spawn(move || budget.run(a));
        let second = b();
        let first = first
            .join()
            .unwrap_or_else(|payload| std::panic::resume_unwind(payload));
        (first, second)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn join_gives_both_results_and_passes_a_panic_on() {
        let items: Vec<u64> = (0..10_000).collect();
        let (sum, count) = join(|| items.iter().sum::<u64>(), || items.len());
        assert_eq!((sum, count), (49_995_000, 10_000));
        let panicked = std::panic::catch_unwind(|| join(|| panic!("in the other thread"), || 1));
        assert!(panicked.is_err());
    }
}
