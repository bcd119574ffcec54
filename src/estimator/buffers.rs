//! N-long work arrays of a fit (the centred series, the residuals, the interval of
//! every row), first written in parallel chunks.
//!
//! A fresh allocation of 800 MB (a 1e8-sample channel) is mapped lazily: every 4 KiB
//! page faults on its first write, about 200,000 faults. Written by one thread, the
//! centred copy of a 1e8-sample channel took 0.42 s on the bench machine, four passes
//! over the data (BENCHMARKS.md, 2026-11-25); the faults of a parallel first write
//! are taken on every thread. (Transparent huge pages, `madvise(MADV_HUGEPAGE)`, were
//! tried: an 800 MB vector first written in 0.07 s in two tries of three and 0.57 s in
//! the third, against 0.15-0.17 s with 4 KiB pages: too variable to use.)

use rayon::prelude::*;

/// Rows per parallel chunk when a buffer is first written.
pub const FILL_CHUNK: usize = 1 << 16;

/// A vector of `n` values written by `fill`: `fill(at, chunk)` is given each chunk of
/// the vector (in parallel; the chunk holds values at..at + chunk.len(), set to
/// `T::default()`) and writes it; its results are returned in chunk order.
pub fn filled<T, R, F>(n: usize, fill: F) -> (Vec<T>, Vec<R>)
where
    T: Copy + Default + Send + Sync,
    R: Send,
    F: Fn(usize, &mut [T]) -> R + Sync,
{
    let mut v: Vec<T> = Vec::with_capacity(n);
    let parts = v
        .spare_capacity_mut()
        .par_chunks_mut(FILL_CHUNK)
        .enumerate()
        .map(|(c, chunk)| {
            for slot in chunk.iter_mut() {
                slot.write(T::default());
            }
            // SAFETY: every slot of the chunk was just initialised, and
            // MaybeUninit<T> has T's layout.
            let chunk: &mut [T] = unsafe {
                std::slice::from_raw_parts_mut(chunk.as_mut_ptr().cast::<T>(), chunk.len())
            };
            fill(c * FILL_CHUNK, chunk)
        })
        .collect();
    // SAFETY: the chunks cover the n slots of the capacity, each initialised above.
    unsafe { v.set_len(n) };
    (v, parts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filled_writes_every_value_and_returns_the_chunks_results_in_order() {
        // empty, one short chunk, several with a short last one
        for n in [0, 10, 3 * FILL_CHUNK + 17] {
            let (v, parts): (Vec<f64>, Vec<(usize, usize)>) = filled(n, |at, c: &mut [f64]| {
                assert!(c.iter().all(|x| *x == 0.0));
                for (i, x) in c.iter_mut().enumerate() {
                    *x = (at + i) as f64 * 0.5;
                }
                (at, c.len())
            });
            assert_eq!(v.len(), n);
            assert!(v.iter().enumerate().all(|(i, x)| *x == i as f64 * 0.5));
            let mut next = 0;
            for (at, len) in parts {
                assert_eq!(at, next);
                next += len;
            }
            assert_eq!(next, n);
        }
    }
}
