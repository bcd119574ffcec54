//! How many FARMA fits run at once. A fit of N samples holds about
//! [`FIT_BYTES_PER_SAMPLE`] N bytes while it runs (its centred series, residuals, the
//! linear start's work arrays and the moment tables), and the fits in flight share one
//! memory budget, `FARMA_MEMORY_GB` (default [`DEFAULT_BUDGET_GB`]): on a machine of
//! many threads the order table's fits, and the channels of `farma analyze`, run in
//! waves of at most [`fits_in_flight`] instead of one fit per thread at once. Where the
//! threads are fewer than that, nothing changes: the threads bound the fits in flight.
//!
//! The figure per sample is measured: `farma analyze` of ADIS16405 run 1's three gyro
//! axes (1e6 samples each, eight orders) peaked at 322 MB with 2 threads and 864 MB with
//! 8 (2026-11-27, BENCHMARKS.md): 542 MB for 6 more fits in flight, 90 bytes per
//! sample each; one `farma fit` of one such channel peaks at 116 MB, the process and
//! the mapped channel included.
//!
//! Two notions, one module: `FARMA_MEMORY_GB` **schedules** (how many fits run at once;
//! it never refuses work), while the memory limit ([`memory_limit_bytes`], the global
//! `--memory-limit GB`, default [`DEFAULT_MEMORY_SHARE`] of the physical memory read
//! from `/proc/meminfo`) **refuses**: every command that allocates by a user-given size
//! (`simulate --duration`, grids, `--bootstrap`, `gap --replicas`, `--max-lag`,
//! `--segment`, an inline farma spec's `d`) plans the bytes first and stops with exit 2
//! naming the flag and the bytes when they exceed the limit ([`check_memory`]), rather
//! than being killed by the allocator. The fits' budget is capped by the limit.

use std::sync::OnceLock;

use rayon::prelude::*;

use crate::error::{Error, Result};

/// The share of the physical memory a request may plan when `--memory-limit` is not
/// given.
pub const DEFAULT_MEMORY_SHARE: f64 = 0.5;
/// The limit when the physical memory cannot be read (not Linux), GB.
pub const FALLBACK_LIMIT_GB: f64 = 8.0;

static LIMIT_GB: OnceLock<f64> = OnceLock::new();

/// Sets the memory limit from `--memory-limit GB` (once per process; the binary's
/// command line). A usage error unless a positive finite number.
pub fn set_memory_limit_gb(gb: f64) -> Result<()> {
    if !(gb.is_finite() && gb > 0.0) {
        return Err(Error::Usage(format!(
            "--memory-limit must be a positive number of GB, found {}",
            crate::fmt::num(gb)
        )));
    }
    let _ = LIMIT_GB.set(gb);
    Ok(())
}

/// The machine's physical memory in bytes (`MemTotal` of `/proc/meminfo`).
pub fn physical_memory_bytes() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024.0)
}

/// The memory one request may plan, bytes: `--memory-limit`, else
/// [`DEFAULT_MEMORY_SHARE`] of the physical memory, else [`FALLBACK_LIMIT_GB`].
pub fn memory_limit_bytes() -> f64 {
    match LIMIT_GB.get() {
        Some(gb) => gb * 1e9,
        None => physical_memory_bytes()
            .map(|b| b * DEFAULT_MEMORY_SHARE)
            .unwrap_or(FALLBACK_LIMIT_GB * 1e9),
    }
}

/// Bytes as GB for messages: `12.3 GB`, `8e+12 bytes` beyond.
fn gb(bytes: f64) -> String {
    format!(
        "{} GB",
        crate::fmt::num((bytes / 1e9 * 1000.0).round() / 1000.0)
    )
}

/// Refuses (a usage error, exit 2) a request whose planned memory `bytes` exceeds the
/// limit: `flag` names what the user gave (`--bootstrap 1e9`), `what` what it would
/// allocate.
pub fn check_memory(flag: &str, what: &str, bytes: f64) -> Result<()> {
    let limit = memory_limit_bytes();
    if bytes.is_finite() && bytes <= limit {
        return Ok(());
    }
    let default = match LIMIT_GB.get() {
        Some(_) => String::new(),
        None => format!(
            " (the default: {} % of this machine's {})",
            (DEFAULT_MEMORY_SHARE * 100.0).round(),
            physical_memory_bytes().map_or_else(|| "memory".to_string(), gb)
        ),
    };
    Err(Error::Usage(format!(
        "{flag}: {what} would need about {} bytes ({}) of memory, more than the memory limit of {}{default}; ask for less, or raise --memory-limit GB",
        crate::fmt::num(bytes.round()),
        gb(bytes),
        gb(limit)
    )))
}

/// Bytes a running fit holds per sample of its series (module doc).
pub const FIT_BYTES_PER_SAMPLE: f64 = 96.0;

/// The memory the fits in flight may hold when `FARMA_MEMORY_GB` is not set, in GB
/// (1e9 bytes).
pub const DEFAULT_BUDGET_GB: f64 = 0.75;

/// The budget in bytes: `FARMA_MEMORY_GB` (a positive number of GB) or the default.
/// Never above the memory limit ([`memory_limit_bytes`]).
pub fn budget_bytes() -> f64 {
    (std::env::var("FARMA_MEMORY_GB")
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
        .filter(|g| g.is_finite() && *g > 0.0)
        .unwrap_or(DEFAULT_BUDGET_GB)
        * 1e9)
        .min(memory_limit_bytes())
}

/// Fits of `n` samples that may run at once within the budget: at least 1.
pub fn fits_in_flight(n: usize) -> usize {
    let per_fit = (n as f64 * FIT_BYTES_PER_SAMPLE).max(1.0);
    ((budget_bytes() / per_fit).floor() as usize).max(1)
}

/// `f` over `items` in parallel, at most `k` at once (in waves of equal size, none
/// above `k`, when `k` is below both the items and the pool's threads; else all at
/// once), results in the items' order.
pub fn par_map_waves<T: Sync, R: Send>(
    items: &[T],
    k: usize,
    f: impl Fn(&T) -> R + Sync + Send,
) -> Vec<R> {
    let k = k.max(1);
    if k >= items.len() || k >= rayon::current_num_threads() {
        return items.par_iter().map(&f).collect();
    }
    // waves of equal size: 8 items at k = 7 are two waves of 4, not 7 and 1
    let waves = items.len().div_ceil(k);
    let size = items.len().div_ceil(waves);
    let mut out = Vec::with_capacity(items.len());
    for wave in items.chunks(size) {
        out.extend(wave.par_iter().map(&f).collect::<Vec<R>>());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn waves_keep_the_order_and_bound_the_work_in_flight() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(8)
            .build()
            .unwrap();
        let items: Vec<usize> = (0..20).collect();
        let now = AtomicUsize::new(0);
        let most = AtomicUsize::new(0);
        let out = pool.install(|| {
            par_map_waves(&items, 3, |i| {
                let k = now.fetch_add(1, Ordering::SeqCst) + 1;
                most.fetch_max(k, Ordering::SeqCst);
                std::thread::sleep(std::time::Duration::from_millis(5));
                now.fetch_sub(1, Ordering::SeqCst);
                i * 2
            })
        });
        assert_eq!(out, items.iter().map(|i| i * 2).collect::<Vec<_>>());
        assert!(most.load(Ordering::SeqCst) <= 3, "{most:?}");
    }

    #[test]
    fn a_budget_allows_at_least_one_fit() {
        assert!(fits_in_flight(usize::MAX / 1024) >= 1);
        assert!(fits_in_flight(1_000_000) >= 1);
    }
}
