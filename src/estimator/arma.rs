//! Linear ARMA(p,q) by conditional least squares: the start of the FARMA alternation
//! and the linear baseline a user would fit instead.
//!
//! Model: x_t = sum_{m=1..p} a_m x_{t-m} + e_t + sum_{m=1..q} b_m e_{t-m}, residuals
//! by the recursion with zeros before the first sample. Start: Hannan and Rissanen
//! (1982): a long AR(k) by least squares (k = ceil(10 log10 N), at most 40) gives
//! residual estimates, then x_t is regressed on its p lags and q lagged residuals.
//! Refinement: Gauss-Newton on sum e_t^2 (t >= max(p,q)), the derivatives following
//! d e_t/d a_m = -x_{t-m} - sum_k b_k d e_{t-k}/d a_m and
//! d e_t/d b_m = -e_{t-m} - sum_k b_k d e_{t-k}/d b_m (Box, Jenkins and Reinsel, 7.2),
//! with step halving; an MA part outside the invertible region is rejected.

use super::linalg::normal_equations;
use super::series::Centred;

/// A fitted linear ARMA model.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearArma {
    pub ar: Vec<f64>,
    pub ma: Vec<f64>,
    /// Sum of squared residuals over t >= max(p, q).
    pub rss: f64,
    pub iterations: usize,
}

/// Residuals of a linear ARMA by the recursion (zeros before the first sample).
pub fn arma_residuals(x: &[f64], ar: &[f64], ma: &[f64], e: &mut [f64]) {
    for t in 0..x.len() {
        let mut s = x[t];
        for (m, a) in ar.iter().enumerate() {
            if t > m {
                s -= a * x[t - m - 1];
            }
        }
        for (m, b) in ma.iter().enumerate() {
            if t > m {
                s -= b * e[t - m - 1];
            }
        }
        e[t] = s;
    }
}

/// Least squares of y_t on columns of lagged series, rows t in `rows`.
/// `cols` gives for each regressor (series, lag).
fn lagged_ls(
    y: &[f64],
    series: &[&[f64]],
    cols: &[(usize, usize)],
    rows: std::ops::Range<usize>,
) -> Option<Vec<f64>> {
    let k = cols.len();
    if k > 2 && cols.iter().enumerate().all(|(i, c)| *c == (0, i + 1)) {
        return lagged_ls_one_series(y, series[0], k, rows);
    }
    let series: Vec<Centred> = series.iter().map(|s| Centred::plain(s)).collect();
    let (ata, aty) = lagged_normal(Centred::plain(y), &series, cols, rows);
    normal_equations(&ata, &aty, k)
}

/// The normal equations (A'A row-major, A'y) of `lagged_ls`'s regression, summed
/// over rows t in `rows` in order.
pub fn lagged_normal(
    y: Centred,
    series: &[Centred],
    cols: &[(usize, usize)],
    rows: std::ops::Range<usize>,
) -> (Vec<f64>, Vec<f64>) {
    let k = cols.len();
    let mut ata = vec![0.0; k * k];
    let mut aty = vec![0.0; k];
    let mut v = vec![0.0; k];
    for t in rows {
        for (i, (s, lag)) in cols.iter().enumerate() {
            v[i] = series[*s].at(t - lag);
        }
        // the upper triangle only (v_i v_j = v_j v_i exactly: the mirrored sums are
        // the same bits)
        for i in 0..k {
            let vi = v[i];
            for (a, vj) in ata[i * k + i..(i + 1) * k].iter_mut().zip(&v[i..]) {
                *a += vi * vj;
            }
            aty[i] += vi * y.at(t);
        }
    }
    for i in 0..k {
        for j in 0..i {
            ata[i * k + j] = ata[j * k + i];
        }
    }
    (ata, aty)
}

/// [`lagged_ls`] on the lags 1..=k of one series x (the long autoregression of
/// Hannan-Rissanen): the Gram matrix of lagged x is Toeplitz up to its ends, so only
/// its first row is summed over the rows (O(N k) instead of O(N k^2)); along each
/// diagonal, G[i+1][j+1] = G[i][j] + x[r0-2-i] x[r0-2-j] - x[r1-2-i] x[r1-2-j] for
/// rows r0..r1 (the window of products moved back by one sample). Each step adds one
/// product to a sum of N, so the rounding stays at the level of the direct sums (the
/// results differ from them in the last bits only). Twin-tested against the direct
/// sums below.
fn lagged_ls_one_series(
    y: &[f64],
    x: &[f64],
    k: usize,
    rows: std::ops::Range<usize>,
) -> Option<Vec<f64>> {
    let (r0, r1) = (rows.start, rows.end);
    if r1 <= r0 {
        return None;
    }
    let mut ata = vec![0.0; k * k];
    let mut aty = vec![0.0; k];
    // first row: G[0][j] = sum_t x[t-1] x[t-1-j]; aty[i] = sum_t x[t-1-i] y[t]
    for t in rows {
        let x1 = x[t - 1];
        for (j, a) in ata[..k].iter_mut().enumerate() {
            *a += x1 * x[t - 1 - j];
        }
        for (i, a) in aty.iter_mut().enumerate() {
            *a += x[t - 1 - i] * y[t];
        }
    }
    for i in 0..k - 1 {
        for j in i..k - 1 {
            let v = ata[i * k + j] + x[r0 - 2 - i] * x[r0 - 2 - j] - x[r1 - 2 - i] * x[r1 - 2 - j];
            ata[(i + 1) * k + j + 1] = v;
        }
    }
    for i in 0..k {
        for j in 0..i {
            ata[i * k + j] = ata[j * k + i];
        }
    }
    normal_equations(&ata, &aty, k)
}

/// None when b is invertible ([`ma_invertible`]), else what is wrong with it, for a
/// message: "b = [..] is not invertible (a root of ... on or inside the unit circle)".
pub fn not_invertible(b: &[f64]) -> Option<String> {
    (!ma_invertible(b)).then(|| {
        format!(
            "b = {b:?} is not invertible (a root of 1 + b_1 z + ... + b_q z^q on or inside the unit circle)"
        )
    })
}

/// True when the MA polynomial 1 + b_1 z + ... has all roots outside the unit circle
/// (checked by the Schur-Cohn / Jury recursion on the reversed coefficients).
pub fn ma_invertible(b: &[f64]) -> bool {
    // Step-down (Levinson) recursion: invertible iff every reflection coefficient |k| < 1.
    let mut a: Vec<f64> = b.to_vec();
    while let Some(&k) = a.last() {
        if k.abs() >= 1.0 {
            return false;
        }
        let n = a.len();
        let denom = 1.0 - k * k;
        let next: Vec<f64> = (0..n - 1)
            .map(|i| (a[i] - k * a[n - 2 - i]) / denom)
            .collect();
        a = next;
    }
    true
}

/// The largest modulus of the roots of z^q + b_1 z^(q-1) + ... + b_q (the inverses of
/// the roots of the MA polynomial 1 + b_1 B + ... + b_q B^q): below 1 exactly when b is
/// invertible. By bisection on r with [`ma_invertible`] of b_k / r^k, whose roots are
/// those of b divided by r (all inside the unit circle iff every root of b has modulus
/// below r); 0 for q = 0, to about 1e-15 otherwise.
pub fn ma_root_modulus(b: &[f64]) -> f64 {
    if b.is_empty() {
        return 0.0;
    }
    let inside = |r: f64| {
        let scaled: Vec<f64> = b
            .iter()
            .enumerate()
            .map(|(k, v)| v / r.powi(k as i32 + 1))
            .collect();
        ma_invertible(&scaled)
    };
    // an upper bound: 1 + max |b_k| (Cauchy's bound)
    let (mut lo, mut hi) = (0.0f64, 1.0 + b.iter().fold(0.0f64, |m, v| m.max(v.abs())));
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if inside(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// One streaming pass of the ARMA(p,q) recursion e_t = x_t - sum a_m x_{t-m} -
/// sum b_m e_{t-m} (zeros before the first sample) with its derivatives
/// d e_t / d a_j = -x_{t-j} - sum_k b_k d e_{t-k} / d a_j and
/// d e_t / d b_j = -e_{t-j} - sum_k b_k d e_{t-k} / d b_j (Box, Jenkins and Reinsel,
/// 7.2): returns the RSS over t >= `start` and the Gauss-Newton normal equations J'J
/// and -J'e (k = p + q unknowns, row-major). The recursions keep only the last q
/// values of e and of the derivatives: nothing N-long is allocated.
pub fn arma_pass<'a>(
    x: impl Into<Centred<'a>>,
    start: usize,
    a: &[f64],
    b: &[f64],
) -> (f64, Vec<f64>, Vec<f64>) {
    let x = x.into();
    arma_pass_fixed_orders(x, start, a, b, None).unwrap_or_else(|| arma_pass_any(x, start, a, b))
}

/// [`arma_pass`] that also writes every e_t to `e` (as long as `x`): the residuals at
/// (a, b), the values of [`arma_residuals`] bit for bit (the same operations, tested).
/// None, with nothing written, for orders without a kernel of their own (p <= 3 and
/// q <= 2 have one).
pub fn arma_pass_into<'a>(
    x: impl Into<Centred<'a>>,
    start: usize,
    a: &[f64],
    b: &[f64],
    e: &mut [f64],
) -> Option<(f64, Vec<f64>, Vec<f64>)> {
    let x = x.into();
    assert_eq!(e.len(), x.len());
    arma_pass_fixed_orders(x, start, a, b, Some(e))
}

/// [`arma_pass_fixed`] for the orders that have a kernel; None for the others.
fn arma_pass_fixed_orders(
    x: Centred,
    start: usize,
    a: &[f64],
    b: &[f64],
    e: Option<&mut [f64]>,
) -> Option<(f64, Vec<f64>, Vec<f64>)> {
    macro_rules! fixed {
        ($(($p:literal, $q:literal)),*) => {
            match (a.len(), b.len()) {
                $(($p, $q) => Some(arma_pass_fixed::<$p, $q, { $p + $q }>(x, start, a, b, e)),)*
                _ => None,
            }
        };
    }
    fixed!(
        (0, 1),
        (0, 2),
        (1, 1),
        (2, 1),
        (3, 1),
        (1, 2),
        (2, 2),
        (3, 2)
    )
}

/// Where the pass of one chunk of rows reads x_t and writes e_t: the chunk of the
/// series, and the chunk of the residual buffer when one is filled.
struct ReadWrite<'a> {
    x: Centred<'a>,
    e: &'a mut [f64],
}

impl RowIo for ReadWrite<'_> {
    #[inline]
    fn get(&self, i: usize) -> f64 {
        self.x.at(i)
    }
    #[inline]
    fn put(&mut self, i: usize, e: f64) {
        self.e[i] = e;
    }
}

/// [`arma_pass`] for orders known at compile time: the last p values of x, q of e and
/// of the derivatives kept in registers, zeros before the first sample (subtracting
/// a zero term leaves every sum as the general version's, bit for bit).
///
/// Long series run in fixed chunks, in parallel, with every e_t and derivative exact
/// (the values of the one-loop recursion, bit for bit): each chunk first runs from a
/// zero MA state (its x lags are known) and records its state after `lead` rows and
/// at its end; then, chunk after chunk, the recursion re-runs the first `lead` rows
/// from the true state (the previous chunk's end). The zero-start state's error
/// decays like rho^t (rho the largest root of the MA polynomial), and once the two
/// states agree to the bit every later row is the same computation: the chunk's
/// recorded sums and end state are then exact; if they do not agree (rho near 1) the
/// rest of the chunk re-runs from the true state. The sums are added per chunk
/// (first `lead` rows, then the rest) in chunk order, in both cases: the result
/// depends on N and b, not on the threads.
fn arma_pass_fixed<const P: usize, const Q: usize, const K: usize>(
    x: Centred,
    start: usize,
    a: &[f64],
    b: &[f64],
    out: Option<&mut [f64]>,
) -> (f64, Vec<f64>, Vec<f64>) {
    use rayon::prelude::*;
    debug_assert_eq!(P + Q, K);
    let mut aa = [0.0f64; P];
    aa.copy_from_slice(a);
    let mut bb = [0.0f64; Q];
    bb.copy_from_slice(b);
    let n = x.len();
    let chunk = (n / 32).max(PASS_CHUNK_MIN);
    // rows `rows` of the chunk `r` (indices from its start), writing e_t to `es` (the
    // chunk's part of `out`) when there is one
    let run = |r: &std::ops::Range<usize>,
               rows: std::ops::Range<usize>,
               es: Option<&mut [f64]>,
               st: &mut PassState<P, Q, K>,
               sums: &mut PassSums<K>| {
        let xs = x.range(r.clone());
        match es {
            Some(e) => pass_rows(
                ReadWrite { x: xs, e },
                rows,
                r.start,
                start,
                &aa,
                &bb,
                st,
                sums,
            ),
            None => pass_rows(xs, rows, r.start, start, &aa, &bb, st, sums),
        }
    };
    let finish = |s: PassSums<K>| {
        let jtj: Vec<f64> = (0..K * K).map(|i| s.jtj[i / K][i % K]).collect();
        (s.rss, jtj, s.jte.to_vec())
    };
    if n < 2 * chunk || Q == 0 {
        let mut st = PassState::at(x, 0);
        let mut sums = PassSums::zero();
        run(&(0..n), 0..n, out, &mut st, &mut sums);
        return finish(sums);
    }
    let lead = lead_rows(b, chunk);
    let chunks: Vec<std::ops::Range<usize>> = (0..n)
        .step_by(chunk)
        .map(|s| s..(s + chunk).min(n))
        .collect();
    // each chunk's part of the residual buffer, when one is filled
    let mut slots: Vec<Option<&mut [f64]>> = match out {
        Some(e) => e.chunks_mut(chunk).map(Some).collect(),
        None => chunks.iter().map(|_| None).collect(),
    };
    // each chunk from a zero MA state: (state after the lead, end state, sums after it)
    type Part<const P: usize, const Q: usize, const K: usize> = (
        PassState<P, Q, K>,
        PassState<P, Q, K>,
        PassSums<K>,
        PassSums<K>,
    );
    let parts: Vec<Part<P, Q, K>> = chunks
        .par_iter()
        .zip(slots.par_iter_mut())
        .map(|(r, slot)| {
            let mid = lead.min(r.len());
            let mut st = PassState::at(x, r.start);
            let mut head = PassSums::zero();
            run(r, 0..mid, slot.as_deref_mut(), &mut st, &mut head);
            let at_lead = st;
            let mut rest = PassSums::zero();
            run(r, mid..r.len(), slot.as_deref_mut(), &mut st, &mut rest);
            (at_lead, st, head, rest)
        })
        .collect();
    // the first chunk started from the true state; the others re-run their lead (and
    // write its true e_t over the zero-start ones)
    let mut total = parts[0].2;
    total.add(&parts[0].3);
    let mut state = parts[0].1;
    for ((r, part), slot) in chunks.iter().zip(&parts).zip(slots.iter_mut()).skip(1) {
        let mid = lead.min(r.len());
        let mut st = state;
        let mut head = PassSums::zero();
        run(r, 0..mid, slot.as_deref_mut(), &mut st, &mut head);
        total.add(&head);
        if st.same(&part.0) {
            total.add(&part.3);
            state = part.1;
        } else {
            let mut rest = PassSums::zero();
            run(r, mid..r.len(), slot.as_deref_mut(), &mut st, &mut rest);
            total.add(&rest);
            state = st;
        }
    }
    finish(total)
}

/// Rows per chunk of [`arma_pass_fixed`] at least (shorter series run in one).
const PASS_CHUNK_MIN: usize = 1 << 17;

/// Rows a chunk re-runs from the true state: enough for rho^t to fall below 2^-80
/// (rho the largest modulus of a root of z^q + b_1 z^(q-1) + ... + b_q), plus a
/// margin; the whole chunk when rho is not below 1.
fn lead_rows(b: &[f64], chunk: usize) -> usize {
    let rho = match b {
        [b1] => b1.abs(),
        [b1, b2] => {
            let disc = b1 * b1 - 4.0 * b2;
            if disc >= 0.0 {
                ((-b1 + disc.sqrt()) / 2.0)
                    .abs()
                    .max(((-b1 - disc.sqrt()) / 2.0).abs())
            } else {
                b2.abs().sqrt()
            }
        }
        _ => 1.0,
    };
    if rho < 1.0 && rho.is_finite() {
        let rows = (-80.0 / rho.max(1e-300).log2()).ceil() + 256.0;
        (rows as usize).min(chunk)
    } else {
        chunk
    }
}

/// The recursion's state before a row: the last p values of x, q of e and q of the
/// derivative vectors.
#[derive(Clone, Copy)]
pub(super) struct PassState<const P: usize, const Q: usize, const K: usize> {
    pub(super) xh: [f64; P],
    pub(super) eh: [f64; Q],
    pub(super) dh: [[f64; K]; Q],
}

impl<const P: usize, const Q: usize, const K: usize> PassState<P, Q, K> {
    /// Before row t: the x lags from the series (zeros before the first sample), a
    /// zero MA state.
    pub(super) fn at(x: Centred, t: usize) -> Self {
        let mut xh = [0.0f64; P];
        for (m, v) in xh.iter_mut().enumerate() {
            if t > m {
                *v = x.at(t - m - 1);
            }
        }
        PassState {
            xh,
            eh: [0.0; Q],
            dh: [[0.0; K]; Q],
        }
    }

    /// The same state to the bit.
    pub(super) fn same(&self, o: &Self) -> bool {
        let bits = |v: &f64| v.to_bits();
        self.xh.iter().map(bits).eq(o.xh.iter().map(bits))
            && self.eh.iter().map(bits).eq(o.eh.iter().map(bits))
            && self
                .dh
                .iter()
                .flatten()
                .map(bits)
                .eq(o.dh.iter().flatten().map(bits))
    }
}

/// RSS and normal equations summed over some rows.
#[derive(Clone, Copy)]
pub(super) struct PassSums<const K: usize> {
    pub(super) rss: f64,
    pub(super) jtj: [[f64; K]; K],
    pub(super) jte: [f64; K],
}

impl<const K: usize> PassSums<K> {
    pub(super) fn zero() -> Self {
        PassSums {
            rss: 0.0,
            jtj: [[0.0; K]; K],
            jte: [0.0; K],
        }
    }

    fn add(&mut self, o: &Self) {
        self.rss += o.rss;
        for i in 0..K {
            for j in 0..K {
                self.jtj[i][j] += o.jtj[i][j];
            }
            self.jte[i] += o.jte[i];
        }
    }

    /// self += (head + rest), every sum grouped so (the grouping the MA filters sum
    /// their RSS in, `fit::rss_groups`).
    pub(super) fn add_group(&mut self, head: &Self, rest: &Self) {
        self.rss += head.rss + rest.rss;
        for i in 0..K {
            for j in 0..K {
                self.jtj[i][j] += head.jtj[i][j] + rest.jtj[i][j];
            }
            self.jte[i] += head.jte[i] + rest.jte[i];
        }
    }
}

/// Where [`pass_rows`] reads x_t: a series (`&[f64]`), or a buffer whose values
/// it turns into the residuals e_t in place (`&mut [f64]`, the MA filter of the
/// alternation's one-pass b-step, `fit::gn_rows`).
pub(super) trait RowIo {
    fn get(&self, i: usize) -> f64;
    fn put(&mut self, i: usize, e: f64);
}

impl RowIo for &[f64] {
    #[inline]
    fn get(&self, i: usize) -> f64 {
        self[i]
    }
    #[inline]
    fn put(&mut self, _i: usize, _e: f64) {}
}

impl RowIo for Centred<'_> {
    #[inline]
    fn get(&self, i: usize) -> f64 {
        self.at(i)
    }
    #[inline]
    fn put(&mut self, _i: usize, _e: f64) {}
}

impl RowIo for &mut [f64] {
    #[inline]
    fn get(&self, i: usize) -> f64 {
        self[i]
    }
    #[inline]
    fn put(&mut self, i: usize, e: f64) {
        self[i] = e;
    }
}

/// The recursion over `rows` (indices into `io`; row t = `t0` + index) from state
/// `st` (left at the state after them), adding rows t >= `start` to `sums`.
#[inline]
#[allow(clippy::too_many_arguments)]
pub(super) fn pass_rows<const P: usize, const Q: usize, const K: usize, IO: RowIo>(
    mut io: IO,
    rows: std::ops::Range<usize>,
    t0: usize,
    start: usize,
    aa: &[f64; P],
    bb: &[f64; Q],
    st: &mut PassState<P, Q, K>,
    sums: &mut PassSums<K>,
) {
    let PassState { xh, eh, dh } = st;
    // the sums in locals (registers), J'J's upper triangle only: its lower one is the
    // same products in the same order (de_i de_j = de_j de_i), mirrored at the end
    let (mut rss, mut jtj, mut jte) = (sums.rss, sums.jtj, sums.jte);
    for i in rows {
        let t = t0 + i;
        let xt = io.get(i);
        let mut s = xt;
        for m in 0..P {
            s -= aa[m] * xh[m];
        }
        for m in 0..Q {
            s -= bb[m] * eh[m];
        }
        io.put(i, s);
        let mut de = [0.0f64; K];
        for j in 0..K {
            let mut v = if j < P { -xh[j] } else { -eh[j - P] };
            for kk in 0..Q {
                v -= bb[kk] * dh[kk][j];
            }
            de[j] = v;
        }
        if t >= start {
            rss += s * s;
            for i in 0..K {
                for j in i..K {
                    jtj[i][j] += de[i] * de[j];
                }
                jte[i] -= de[i] * s;
            }
        }
        for m in (1..P).rev() {
            xh[m] = xh[m - 1];
        }
        if P > 0 {
            xh[0] = xt;
        }
        for kk in (1..Q).rev() {
            eh[kk] = eh[kk - 1];
            dh[kk] = dh[kk - 1];
        }
        if Q > 0 {
            eh[0] = s;
            dh[0] = de;
        }
    }
    for i in 0..K {
        for j in 0..i {
            jtj[i][j] = jtj[j][i];
        }
    }
    (sums.rss, sums.jtj, sums.jte) = (rss, jtj, jte);
}

/// [`arma_pass`] for any order.
fn arma_pass_any(x: Centred, start: usize, a: &[f64], b: &[f64]) -> (f64, Vec<f64>, Vec<f64>) {
    let (p, q) = (a.len(), b.len());
    let k = p + q;
    let n = x.len();
    let mut ehist = [0.0f64; 8];
    // dhist[kk * k + j] = d e_{t-kk-1} / d theta_j, theta = (a, b)
    let mut dhist = [0.0f64; 8 * 16];
    let mut de = [0.0f64; 16];
    let mut jtj = vec![0.0; k * k];
    let mut jte = vec![0.0; k];
    let mut rss = 0.0;
    for t in 0..n {
        let mut s = x.at(t);
        for (m, am) in a.iter().enumerate() {
            if t > m {
                s -= am * x.at(t - m - 1);
            }
        }
        for (m, bm) in b.iter().enumerate() {
            if t > m {
                s -= bm * ehist[m];
            }
        }
        for j in 0..k {
            let mut v = if j < p {
                if t > j { -x.at(t - j - 1) } else { 0.0 }
            } else if t > j - p {
                -ehist[j - p]
            } else {
                0.0
            };
            for (kk, bk) in b.iter().enumerate() {
                if t > kk {
                    v -= bk * dhist[kk * k + j];
                }
            }
            de[j] = v;
        }
        if t >= start {
            rss += s * s;
            for i in 0..k {
                for j in 0..k {
                    jtj[i * k + j] += de[i] * de[j];
                }
                jte[i] -= de[i] * s;
            }
        }
        for kk in (1..q).rev() {
            ehist[kk] = ehist[kk - 1];
            for j in 0..k {
                dhist[kk * k + j] = dhist[(kk - 1) * k + j];
            }
        }
        ehist[0] = s;
        dhist[..k].copy_from_slice(&de[..k]);
    }
    (rss, jtj, jte)
}

/// Hannan-Rissanen start, then conditional least squares.
pub fn fit_arma(x: &[f64], p: usize, q: usize) -> Option<LinearArma> {
    let n = x.len();
    let pq = p.max(q);
    if n < 10 * (p + q + 1) {
        return None;
    }
    let (mut ar, mut ma) = if q == 0 {
        let cols: Vec<(usize, usize)> = (1..=p).map(|l| (0, l)).collect();
        (lagged_ls(x, &[x], &cols, p..n)?, vec![])
    } else {
        let k = ((10.0 * (n as f64).log10()).ceil() as usize)
            .clamp(p + q, 40)
            .min(n / 5);
        let cols: Vec<(usize, usize)> = (1..=k).map(|l| (0, l)).collect();
        let long = lagged_ls(x, &[x], &cols, k..n)?;
        let mut eh = vec![0.0; n];
        for t in k..n {
            eh[t] = x[t] - (1..=k).map(|l| long[l - 1] * x[t - l]).sum::<f64>();
        }
        let mut cols: Vec<(usize, usize)> = (1..=p).map(|l| (0, l)).collect();
        cols.extend((1..=q).map(|l| (1, l)));
        let c = lagged_ls(x, &[x, &eh], &cols, k + q..n)?;
        let mut ma = c[p..].to_vec();
        if !ma_invertible(&ma) {
            ma = vec![0.0; q];
        }
        (c[..p].to_vec(), ma)
    };
    // Gauss-Newton: each pass gives the RSS and the normal equations at its point
    // (the derivative recursion above, summed over t >= max(p, q)), so an accepted
    // step costs one pass
    let k = p + q;
    let (mut rss, mut jtj, mut jte) = arma_pass(x, pq, &ar, &ma);
    let mut iterations = 0;
    for _ in 0..50 {
        iterations += 1;
        let Some(step) = normal_equations(&jtj, &jte, k) else {
            break;
        };
        let mut scale = 1.0;
        let mut improved = false;
        for _ in 0..20 {
            let ar_try: Vec<f64> = (0..p).map(|i| ar[i] + scale * step[i]).collect();
            let ma_try: Vec<f64> = (0..q).map(|i| ma[i] + scale * step[p + i]).collect();
            if ma_invertible(&ma_try) {
                let (r, jt, je) = arma_pass(x, pq, &ar_try, &ma_try);
                if r <= rss {
                    let done = rss - r <= 1e-12 * rss;
                    (ar, ma, rss, jtj, jte) = (ar_try, ma_try, r, jt, je);
                    improved = !done;
                    break;
                }
            }
            scale *= 0.5;
        }
        if !improved {
            break;
        }
    }
    Some(LinearArma {
        ar,
        ma,
        rss,
        iterations,
    })
}

#[cfg(test)]
mod tests {

    #[test]
    fn the_ma_root_modulus_is_that_of_the_roots() {
        assert_eq!(ma_root_modulus(&[]), 0.0);
        // q = 1: z + b, root -b
        for b in [-0.5, 0.9, -0.9999999992, 1.5] {
            assert!((ma_root_modulus(&[b]) - b.abs()).abs() < 1e-12, "{b}");
        }
        // q = 2 with roots 0.8 and -0.3: z^2 - 0.5 z - 0.24
        assert!((ma_root_modulus(&[-0.5, -0.24]) - 0.8).abs() < 1e-12);
        // complex pair 0.6 +- 0.7i, modulus sqrt(0.85): z^2 - 1.2 z + 0.85
        assert!((ma_root_modulus(&[-1.2, 0.85]) - 0.85f64.sqrt()).abs() < 1e-12);
    }

    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    /// n values uniform on [-0.5, 0.5) from a 64-bit LCG seeded with `seed`.
    fn uniform_lcg(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect()
    }

    #[test]
    fn chunked_pass_equals_the_one_loop_recursion() {
        // N of several chunks: the chunked pass (parallel, re-run leads) against one
        // run over all rows (the one-loop recursion): the e_t and derivatives are the
        // same to the bit, so the sums differ only by their grouping; with 1 and 2
        // threads the bits are the same; b near the unit circle takes the fallback
        let x = uniform_lcg(5 * PASS_CHUNK_MIN + 123, 3);
        let cases: [(&[f64], &[f64]); 5] = [
            (&[], &[-0.5]),
            (&[0.4, -0.2], &[-0.5]),
            (&[0.3], &[0.6, 0.2]),
            (&[], &[-0.9999]),
            (&[0.2], &[1.2, 0.5]),
        ];
        for (a, b) in cases {
            let chunked = arma_pass(&x, 2, a, b);
            let one = arma_pass_any(Centred::plain(&x), 2, a, b);
            let close = |u: f64, v: f64| (u - v).abs() <= 1e-12 * v.abs().max(1.0);
            assert!(
                close(chunked.0, one.0),
                "{a:?} {b:?}: {} vs {}",
                chunked.0,
                one.0
            );
            for (u, v) in chunked
                .1
                .iter()
                .chain(&chunked.2)
                .zip(one.1.iter().chain(&one.2))
            {
                assert!(close(*u, *v), "{a:?} {b:?}: {u} vs {v}");
            }
            // the same bits on 1 and on 3 threads (explicit pools: on a one-core
            // runner the global pool has one thread)
            for threads in [1, 3] {
                let other = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap()
                    .install(|| arma_pass(&x, 2, a, b));
                assert_eq!(other.0.to_bits(), chunked.0.to_bits());
                assert_eq!(other.1, chunked.1);
                assert_eq!(other.2, chunked.2);
            }
        }
    }

    #[test]
    fn a_pass_writes_the_residuals_of_the_one_loop_recursion() {
        // arma_pass_into on several chunks (parallel, re-run leads, the fallback near
        // the unit circle), one chunk and a short series: e equal to arma_residuals
        // bit for bit, the sums those of arma_pass, on 1 and 3 threads
        let long = uniform_lcg(5 * PASS_CHUNK_MIN + 77, 5);
        let cases: [(&[f64], &[f64]); 5] = [
            (&[], &[-0.5]),
            (&[0.4, -0.2], &[-0.5]),
            (&[0.3], &[0.6, 0.2]),
            (&[0.1, 0.2, -0.1], &[-0.9999]),
            (&[0.2], &[1.2, 0.5]),
        ];
        for x in [&long[..], &long[..1000]] {
            for (a, b) in cases {
                let mut want = vec![0.0; x.len()];
                arma_residuals(x, a, b, &mut want);
                let sums = arma_pass(x, 2, a, b);
                for threads in [1, 3] {
                    let mut e = vec![f64::NAN; x.len()];
                    let got = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap()
                        .install(|| arma_pass_into(x, 2, a, b, &mut e))
                        .expect("a fixed order");
                    assert!(
                        e.iter().zip(&want).all(|(u, v)| u.to_bits() == v.to_bits()),
                        "{a:?} {b:?}, n = {}, {threads} threads",
                        x.len()
                    );
                    assert_eq!(got.0.to_bits(), sums.0.to_bits());
                    assert_eq!((got.1, got.2), (sums.1.clone(), sums.2.clone()));
                }
            }
        }
        // an order without a kernel of its own: nothing written
        let mut e = vec![7.0; 1000];
        assert!(arma_pass_into(&long[..1000], 4, &[0.1; 4], &[0.2], &mut e).is_none());
        assert!(e.iter().all(|v| *v == 7.0));
    }

    #[test]
    fn fixed_order_pass_equals_the_general_pass() {
        // arma_pass_fixed (registers, zeros before the first sample) against
        // arma_pass_any (explicit checks), every specialised order, to the bit
        let mut s: u64 = 7;
        let x: Vec<f64> = (0..3000)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        let a_all = [0.4, -0.2, 0.1];
        let b_all = [-0.5, 0.2];
        for (p, q) in [
            (0, 1),
            (0, 2),
            (1, 1),
            (2, 1),
            (3, 1),
            (1, 2),
            (2, 2),
            (3, 2),
        ] {
            let (a, b) = (&a_all[..p], &b_all[..q]);
            for start in [p.max(q), 5] {
                let fast = arma_pass(&x, start, a, b);
                let slow = arma_pass_any(Centred::plain(&x), start, a, b);
                assert_eq!(fast.0.to_bits(), slow.0.to_bits(), "({p},{q}) rss");
                for (u, v) in fast
                    .1
                    .iter()
                    .chain(&fast.2)
                    .zip(slow.1.iter().chain(&slow.2))
                {
                    assert_eq!(u.to_bits(), v.to_bits(), "({p},{q}) normal equations");
                }
            }
        }
    }

    #[test]
    fn one_series_gram_equals_the_direct_sums() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let x: Vec<f64> = (0..5000)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut rng);
                0.3 + z
            })
            .collect();
        for k in [3, 12, 40] {
            let cols: Vec<(usize, usize)> = (1..=k).map(|l| (0, l)).collect();
            let fast = lagged_ls(&x, &[&x], &cols, k + 1..x.len()).unwrap();
            // the direct sums: the general path, reached by listing the columns reversed
            let rev: Vec<(usize, usize)> = cols.iter().rev().copied().collect();
            let mut slow = lagged_ls(&x, &[&x], &rev, k + 1..x.len()).unwrap();
            slow.reverse();
            for (a, b) in fast.iter().zip(&slow) {
                assert!(
                    (a - b).abs() <= 1e-12 * (1.0 + b.abs()),
                    "k {k}: {a} vs {b}"
                );
            }
        }
    }

    #[test]
    fn recovers_an_arma21() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let n = 50_000;
        let mut x = vec![0.0; n];
        let mut u = vec![0.0; n];
        for t in 0..n {
            u[t] = StandardNormal.sample(&mut rng);
            x[t] = u[t];
            if t >= 2 {
                x[t] += 0.5 * x[t - 1] - 0.3 * x[t - 2] + 0.4 * u[t - 1];
            }
        }
        let m = fit_arma(&x, 2, 1).unwrap();
        assert!(
            (m.ar[0] - 0.5).abs() < 0.03 && (m.ar[1] + 0.3).abs() < 0.03,
            "{m:?}"
        );
        assert!((m.ma[0] - 0.4).abs() < 0.03, "{m:?}");
        assert!(
            ma_invertible(&[0.5])
                && !ma_invertible(&[1.2])
                && ma_invertible(&[0.5, 0.2])
                && !ma_invertible(&[0.0, 1.5])
        );
    }
}
