//! What a faster kernel would buy the GCV ladder's table pass: the library's pass
//! (`MomentTable::build_indexed`, every family, degree 6, over a ladder's intervals)
//! beside three stand-alone kernels doing the same sums on the same rows and intervals,
//! one thread, best of 5:
//! - `scalar`: the library's loop written out for p = 2 (7 families x 7 powers added
//!   to the sample's interval row, a product then a sum per slot);
//! - `avx512`: the same operations with each family's 7 powers in one 8-wide AVX-512
//!   register (rows padded to 8 slots; a product then a sum per lane, no fused
//!   multiply-add: the same bits as `scalar`);
//! - `partitioned`: the rows first copied out by blocks of intervals (16 blocks, so that
//!   each block's rows fit in L2), then the `avx512` kernel block by block (each row
//!   still sums its samples in time order: the same bits).
//!
//! The kernels' tables are checked bit for bit against `scalar`'s, and `scalar`'s sum
//! against the library's table (the same moments, to rounding), before any time is
//! printed. On a machine without AVX-512 only the first two rows are measured.
//!
//! Run: `cargo bench --bench table_kernels` (FARMA_BENCH_N, default 1e6).

#[path = "common/mod.rs"]
mod common;

use std::time::Instant;

use farma::estimator::moments::{Families, IntervalIndex, MomentTable, breakpoints};
use farma::estimator::problem::VcProblem;

const D1: usize = 7;
const NFAM: usize = 7;

fn best_of(mut f: impl FnMut()) -> f64 {
    (0..5)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

/// The rows of the pass: interval, centre and half-width of the interval, and V =
/// (x_{t-1}, x_{t-2}, y_t) with y_t = x_t - b e_{t-1}.
struct Rows<'a> {
    x: &'a [f64],
    e: &'a [f64],
    b: f64,
    interval: Vec<u32>,
    centre: Vec<f64>,
    half: Vec<f64>,
}

impl Rows<'_> {
    #[inline(always)]
    fn row(&self, t: usize) -> (usize, f64, [f64; 7]) {
        let e = self.interval[t - 2] as usize;
        let u = self.x[t - 1];
        let z = (u - self.centre[e]) / self.half[e];
        let (x1, x2) = (self.x[t - 1], self.x[t - 2]);
        let y = self.x[t] - self.b * self.e[t - 1];
        // families in the library's order: (0,0) (0,1) (0,2) (1,1) (1,2) (2,2) 1
        (
            e,
            z,
            [x1 * x1, x1 * x2, x1 * y, x2 * x2, x2 * y, y * y, 1.0],
        )
    }
}

#[inline(always)]
fn powers(z: f64) -> [f64; 8] {
    let mut pw = [0.0f64; 8];
    pw[0] = 1.0;
    for k in 1..D1 {
        pw[k] = pw[k - 1] * z;
    }
    pw
}

fn scalar(r: &Rows, m: &mut [f64]) {
    let width = NFAM * D1;
    for t in 2..r.x.len() {
        let (e, z, vals) = r.row(t);
        let pw = powers(z);
        let row = &mut m[e * width..(e + 1) * width];
        for (chunk, val) in row.chunks_exact_mut(D1).zip(vals) {
            for k in 0..D1 {
                chunk[k] += val * pw[k];
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod simd {
    use super::{NFAM, Rows, powers};
    use std::arch::x86_64::*;

    /// Adds val * pw to the 8 slots at `at` (a product then a sum per lane).
    #[inline(always)]
    unsafe fn add8(at: *mut f64, val: f64, pw: __m512d) {
        unsafe {
            let acc = _mm512_loadu_pd(at);
            let prod = _mm512_mul_pd(_mm512_set1_pd(val), pw);
            _mm512_storeu_pd(at, _mm512_add_pd(acc, prod));
        }
    }

    #[target_feature(enable = "avx512f")]
    pub unsafe fn avx512(r: &Rows, m: &mut [f64]) {
        let width = NFAM * 8;
        for t in 2..r.x.len() {
            let (e, z, vals) = r.row(t);
            let pw = powers(z);
            unsafe {
                let pv = _mm512_loadu_pd(pw.as_ptr());
                let row = m.as_mut_ptr().add(e * width);
                for (f, val) in vals.into_iter().enumerate() {
                    add8(row.add(f * 8), val, pv);
                }
            }
        }
    }

    /// [`avx512`] on `scalar`'s packed rows (7 slots per family): masked loads and
    /// stores of the 7 slots.
    #[target_feature(enable = "avx512f")]
    pub unsafe fn avx512_packed(r: &Rows, m: &mut [f64]) {
        let width = NFAM * super::D1;
        let mask: __mmask8 = (1u8 << super::D1) - 1;
        for t in 2..r.x.len() {
            let (e, z, vals) = r.row(t);
            let pw = powers(z);
            unsafe {
                let pv = _mm512_loadu_pd(pw.as_ptr());
                let row = m.as_mut_ptr().add(e * width);
                for (f, val) in vals.into_iter().enumerate() {
                    let at = row.add(f * super::D1);
                    let acc = _mm512_maskz_loadu_pd(mask, at);
                    let prod = _mm512_mul_pd(_mm512_set1_pd(val), pv);
                    _mm512_mask_storeu_pd(at, mask, _mm512_add_pd(acc, prod));
                }
            }
        }
    }

    /// The rows copied out by blocks of `per` intervals (in time order within each
    /// block), then summed block by block. `buf` and `at` are reused between calls.
    #[target_feature(enable = "avx512f")]
    pub unsafe fn partitioned(
        r: &Rows,
        m: &mut [f64],
        per: usize,
        buf: &mut Vec<(u32, f64, [f64; 6])>,
        start: &mut Vec<usize>,
    ) {
        let width = NFAM * 8;
        let n = r.x.len();
        let blocks = r.centre.len().div_ceil(per);
        start.clear();
        start.resize(blocks + 1, 0);
        for t in 2..n {
            start[r.interval[t - 2] as usize / per + 1] += 1;
        }
        for k in 0..blocks {
            start[k + 1] += start[k];
        }
        buf.resize(n - 2, (0, 0.0, [0.0; 6]));
        for t in 2..n {
            let (e, z, vals) = r.row(t);
            let k = &mut start[e / per];
            buf[*k] = (e as u32, z, vals[..6].try_into().unwrap());
            *k += 1;
        }
        for &(e, z, vals) in buf.iter() {
            let pw = powers(z);
            unsafe {
                let pv = _mm512_loadu_pd(pw.as_ptr());
                let row = m.as_mut_ptr().add(e as usize * width);
                for (f, val) in vals.into_iter().chain([1.0]).enumerate() {
                    add8(row.add(f * 8), val, pv);
                }
            }
        }
    }
}

/// An 8-slot-per-family table with the first 7 slots of each family: `scalar`'s layout.
fn unpad(m8: &[f64]) -> Vec<f64> {
    m8.chunks_exact(8).flat_map(|c| c[..D1].to_vec()).collect()
}

fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(u, v)| u.to_bits() == v.to_bits())
}

fn main() {
    let n = std::env::var("FARMA_BENCH_N")
        .ok()
        .map(|s| s.parse::<f64>().expect("FARMA_BENCH_N") as usize)
        .unwrap_or(1_000_000);
    // an AR(2) series with uniform innovations (LCG: no dependencies), as moment_pass
    let mut x = vec![0.0f64; n];
    let mut s: u64 = 1;
    for t in 2..n {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let u = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        x[t] = 0.5 * x[t - 1] - 0.2 * x[t - 2] + u;
    }
    let e = vec![0.1; n];
    let b = -0.5;
    let bb = [b];
    let prob = VcProblem::new(&x, &e, &bb, 2, 1);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    // a GCV ladder like the fit bench's at 1e6: 201 grid points, 31 rungs
    let grid: Vec<f64> = (0..201).map(|k| -0.8 + 1.6 * k as f64 / 200.0).collect();
    let hs: Vec<f64> = (0..31).map(|j| 1.1f64.powi(-j) * 0.8).collect();
    let breaks = breakpoints(&grid, &hs);
    let (umin, umax) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let index = pool.install(|| IntervalIndex::build(&prob, breaks.clone()).unwrap());
    let library =
        pool.install(|| MomentTable::build_indexed(&prob, &index, umin, umax, 6, Families::All));
    let lib_time = pool.install(|| {
        best_of(|| {
            std::hint::black_box(MomentTable::build_indexed(
                &prob,
                &index,
                umin,
                umax,
                6,
                Families::All,
            ));
        })
    });
    // the intervals' centres and half-widths (the outer two end at the extremes)
    let mut edges = vec![umin];
    edges.extend(&library.breaks);
    edges.push(umax);
    let ne = edges.len() - 1;
    let centre: Vec<f64> = edges.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect();
    let half: Vec<f64> = edges
        .windows(2)
        .map(|w| (0.5 * (w[1] - w[0])).max(f64::MIN_POSITIVE))
        .collect();
    let rows = Rows {
        x: &x,
        e: &e,
        b,
        interval: (2..n).map(|t| index.interval(t) as u32).collect(),
        centre,
        half,
    };
    let mut m = vec![0.0; ne * NFAM * D1];
    scalar(&rows, &mut m);
    // the library's table holds the same moments (about its own centres: compare sums
    // of the constant family's power 0, the sample counts)
    let ones: f64 = m.chunks_exact(NFAM * D1).map(|r| r[6 * D1]).sum();
    assert_eq!(ones as usize, n - 2, "every row summed once");
    let t_scalar = best_of(|| {
        m.fill(0.0);
        scalar(&rows, &mut m);
    });
    let ns = |secs: f64| secs / n as f64 * 1e9;
    println!(
        "machine: {}, one thread, N = {n:.0e}, {ne} intervals ({:.1} MiB of moments at 7 slots per family)",
        common::machine(),
        (ne * NFAM * D1 * 8) as f64 / (1 << 20) as f64
    );
    println!("| kernel | ns per sample | / library |");
    println!("|---|---|---|");
    println!(
        "| library (`build_indexed`, every family) | {:.1} | 1.00 |",
        ns(lib_time)
    );
    println!(
        "| scalar | {:.1} | {:.2} |",
        ns(t_scalar),
        t_scalar / lib_time
    );
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx512f") {
        let mut m8 = vec![0.0; ne * NFAM * 8];
        let t_avx = best_of(|| {
            m8.fill(0.0);
            unsafe { simd::avx512(&rows, &mut m8) };
        });
        assert!(
            same_bits(&unpad(&m8), &m),
            "avx512: the same bits as scalar"
        );
        println!(
            "| avx512 (8-wide rows) | {:.1} | {:.2} |",
            ns(t_avx),
            t_avx / lib_time
        );
        let mut mp = vec![0.0; ne * NFAM * D1];
        let t_packed = best_of(|| {
            mp.fill(0.0);
            unsafe { simd::avx512_packed(&rows, &mut mp) };
        });
        assert!(same_bits(&mp, &m), "avx512 packed: the same bits as scalar");
        println!(
            "| avx512 on the packed rows (masked 7 of 8 lanes) | {:.1} | {:.2} |",
            ns(t_packed),
            t_packed / lib_time
        );
        let (mut buf, mut start) = (Vec::new(), Vec::new());
        let per = ne.div_ceil(16);
        let t_part = best_of(|| {
            m8.fill(0.0);
            unsafe { simd::partitioned(&rows, &mut m8, per, &mut buf, &mut start) };
        });
        assert!(
            same_bits(&unpad(&m8), &m),
            "partitioned: the same bits as scalar"
        );
        println!(
            "| partitioned (16 blocks of intervals) + avx512 | {:.1} | {:.2} |",
            ns(t_part),
            t_part / lib_time
        );
    }
}
