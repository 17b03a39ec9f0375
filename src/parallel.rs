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
