//! Work spread over the available cores in a way that does not change the results.
//!
//! The work is cut into pieces whose boundaries depend only on the problem size, never on the
//! number of threads; each piece is computed by exactly one call and the pieces' results are
//! combined afterwards in their order. A sum over pieces therefore has the same rounding on one
//! core as on many, and a calibration gives bit-identical answers on any machine.

use std::ops::Range;

/// Number of threads to use for `pieces` pieces of work.
fn threads_for(pieces: usize) -> usize {
    std::thread::available_parallelism()
        .map_or(1, |t| t.get())
        .min(pieces)
}

/// Applies `f` to every item, contiguous groups of items on all available cores.
pub(crate) fn for_each<T: Send>(items: &mut [T], f: impl Fn(&mut T) + Sync) {
    for_each_on(threads_for(items.len()), items, f);
}

/// [`for_each`] on `threads` threads.
fn for_each_on<T: Send>(threads: usize, items: &mut [T], f: impl Fn(&mut T) + Sync) {
    if threads <= 1 {
        items.iter_mut().for_each(f);
        return;
    }
    let per_thread = items.len().div_ceil(threads);
    let f = &f;
    std::thread::scope(|scope| {
        for group in items.chunks_mut(per_thread) {
            scope.spawn(move || group.iter_mut().for_each(f));
        }
    });
}

/// The ranges `[0, piece)`, `[piece, 2 piece)`, ... covering `0..n`.
pub(crate) fn pieces(n: usize, piece: usize) -> Vec<Range<usize>> {
    let piece = piece.max(1);
    (0..n.div_ceil(piece))
        .map(|i| i * piece..((i + 1) * piece).min(n))
        .collect()
}

/// `f` of every range of [`pieces`]`(n, piece)`, in order.
pub(crate) fn map_pieces<R: Send>(
    n: usize,
    piece: usize,
    f: impl Fn(Range<usize>) -> R + Sync,
) -> Vec<R> {
    map_pieces_on(threads_for(n.div_ceil(piece.max(1))), n, piece, f)
}

fn map_pieces_on<R: Send>(
    threads: usize,
    n: usize,
    piece: usize,
    f: impl Fn(Range<usize>) -> R + Sync,
) -> Vec<R> {
    let mut work: Vec<(Range<usize>, Option<R>)> =
        pieces(n, piece).into_iter().map(|r| (r, None)).collect();
    for_each_on(threads, &mut work, |(r, out)| *out = Some(f(r.clone())));
    work.into_iter().filter_map(|(_, out)| out).collect()
}

/// `f` of every element of `0..n` in order, computed in pieces of `piece` on all cores.
pub(crate) fn map_indices<R: Send>(
    n: usize,
    piece: usize,
    f: impl Fn(usize) -> R + Sync,
) -> Vec<R> {
    map_pieces(n, piece, |r| r.map(&f).collect::<Vec<_>>())
        .into_iter()
        .flatten()
        .collect()
}

/// Worker threads per core at most: more only wait for a core (and each costs its stack).
pub const THREADS_PER_CORE: usize = 4;

/// Worker threads at most, however many cores.
pub const MAX_THREADS: usize = 256;

/// The most worker threads a run starts: [`THREADS_PER_CORE`] per core, at most
/// [`MAX_THREADS`].
pub fn thread_limit() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    cores.saturating_mul(THREADS_PER_CORE).clamp(1, MAX_THREADS)
}

/// The threads used when `requested` are asked for (by the option `option`): `requested`
/// within [`thread_limit`], with a note for the user when it was lowered. 0 (one per core, where
/// an option allows it) is kept.
pub fn capped_threads(option: &str, requested: usize) -> (usize, Option<String>) {
    let limit = thread_limit();
    if requested <= limit {
        return (requested, None);
    }
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    (
        limit,
        Some(format!(
            "{option} {requested} is more threads than this machine can use ({cores} cores): \
             {limit} are used ({THREADS_PER_CORE} per core, at most {MAX_THREADS})"
        )),
    )
}

/// A pool of `threads` worker threads (`None`: one per core), at most [`thread_limit`].
pub fn worker_pool(threads: Option<usize>) -> crate::error::Result<rayon::ThreadPool> {
    let n = threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let n = n.min(thread_limit());
    if n == 0 {
        return Err(crate::error::Error::option(
            "--threads",
            "must be at least 1",
        ));
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .map_err(|e| crate::error::Error::Input(format!("starting the worker threads: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pieces_cover_the_range_once() {
        assert!(pieces(0, 4).is_empty());
        assert_eq!(pieces(10, 4), vec![0..4, 4..8, 8..10]);
        assert_eq!(pieces(8, 4), vec![0..4, 4..8]);
    }

    #[test]
    fn sums_over_pieces_do_not_depend_on_the_thread_count() {
        // Terms of very different sizes, so that any change of the summation order shows.
        let term = |i: usize| ((i * 7919) % 1000) as f64 * 10f64.powi((i % 17) as i32 - 8);
        let sums: Vec<f64> = (1..=5)
            .map(|threads| {
                map_pieces_on(threads, 10_000, 333, |r| r.map(term).sum::<f64>())
                    .into_iter()
                    .sum()
            })
            .collect();
        assert!(sums.iter().all(|s| s.to_bits() == sums[0].to_bits()));
        let all = map_indices(1000, 64, |i| i * 2);
        assert_eq!(all, (0..1000).map(|i| i * 2).collect::<Vec<_>>());
    }

    #[test]
    fn thread_counts_are_capped_with_a_note() {
        let limit = thread_limit();
        assert!((1..=MAX_THREADS).contains(&limit));
        assert_eq!(capped_threads("--threads", 0), (0, None));
        assert_eq!(capped_threads("--threads", limit), (limit, None));
        let (n, note) = capped_threads("--threads", 100_000);
        assert_eq!(n, limit);
        assert!(note.is_some_and(
            |m| m.contains("--threads 100000") && m.contains(&format!("{limit} are used"))
        ));
    }
}
