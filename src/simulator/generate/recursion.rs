//! ARMA and FARMA components: x_t = sum_m f_m(x_{t-d}) x_{t-m} + e_t +
//! sum_m b_m e_{t-m}, with f_m constant for a linear ARMA.
//!
//! The innovations e_t = sigma w_t are drawn by fixed chunks in parallel; the
//! recursion itself runs **sequentially** in one pass (FARMA is nonlinear, so no carry
//! fix-up exists; ARMA shares the same code path, a few multiply-adds per sample).
//! The recursion starts after a burn-in from a zero state, driven by the
//! initial-state stream, so that the first sample is (close to) stationary:
//! for ARMA the burn-in lasts until the AR impulse response has decayed below 1e-12
//! (at least 100, at most 1,000,000 samples); for FARMA 10,000 samples.

use super::streams::{StreamKey, for_chunks_from, normals};
use crate::error::{Error, Result};
use crate::model::Farma;

/// The coefficient functions f_1..f_p of a recursion.
pub enum Coefs<'a> {
    /// Constant (linear ARMA).
    Constant(&'a [f64]),
    /// Polynomials in ascending powers (inline FARMA).
    Poly(&'a [Vec<f64>]),
    /// A fitted model: f_m at the centred x_{t-d} ([`Farma::f`]).
    Fitted(&'a Farma),
}

impl Coefs<'_> {
    #[inline]
    fn eval(&self, u: f64, out: &mut [f64]) {
        match self {
            Coefs::Constant(a) => out.copy_from_slice(a),
            Coefs::Poly(f) => {
                for (o, poly) in out.iter_mut().zip(f.iter()) {
                    *o = poly.iter().rev().fold(0.0, |acc, c| acc * u + c);
                }
            }
            Coefs::Fitted(m) => m.f(u, out),
        }
    }
}

/// A recursion's order and MA part.
pub struct Recursion<'a> {
    pub p: usize,
    pub d: usize,
    pub coefs: Coefs<'a>,
    pub ma: &'a [f64],
    pub sigma: f64,
}

/// Burn-in for a linear AR part: samples until the impulse response of
/// 1 / (1 - sum ar_m z^m) stays below 1e-12 over p consecutive lags.
pub fn arma_burn_in(ar: &[f64], q: usize) -> usize {
    let p = ar.len();
    if p == 0 {
        return 100.max(q);
    }
    let mut h = vec![0.0; p];
    h[0] = 1.0; // h[0] is the newest
    let mut quiet = 0;
    for j in 1..1_000_000 {
        let v: f64 = ar.iter().zip(&h).map(|(a, x)| a * x).sum();
        h.rotate_right(1);
        h[0] = v;
        quiet = if v.abs() < 1e-12 { quiet + 1 } else { 0 };
        if quiet >= p {
            return (j + q).max(100);
        }
    }
    1_000_000
}

/// FARMA burn-in, samples.
pub const FARMA_BURN_IN: usize = 10_000;

/// Runs the recursion over `buf` in place: `buf` holds e_t on entry and x_t on exit.
/// `xs` (newest first, length max(p, d)) and `es` (newest first, length q) hold the
/// state and are updated. Errors when the recursion leaves |x| < 1e150.
fn recurse(buf: &mut [f64], r: &Recursion, xs: &mut [f64], es: &mut [f64]) -> Result<(), usize> {
    let p = r.p;
    let mut fv = vec![0.0; p];
    for (t, slot) in buf.iter_mut().enumerate() {
        let e = *slot;
        r.coefs.eval(xs[r.d - 1], &mut fv);
        let mut x = e;
        for m in 0..p {
            x += fv[m] * xs[m];
        }
        for (b, ep) in r.ma.iter().zip(es.iter()) {
            x += b * ep;
        }
        if x.is_nan() || x.abs() >= 1e150 {
            return Err(t);
        }
        if !xs.is_empty() {
            xs.rotate_right(1);
            xs[0] = x;
        }
        if !es.is_empty() {
            es.rotate_right(1);
            es[0] = e;
        }
        *slot = x;
    }
    Ok(())
}

/// The state of a recursion carried from block to block: the last x (newest first)
/// and e, and whether the burn-in has run.
#[derive(Debug, Clone, Default)]
pub struct RecState {
    xs: Vec<f64>,
    es: Vec<f64>,
    started: bool,
}

/// Adds the recursion's output to `out`. `what` names the component in errors.
pub fn add_recursion(
    out: &mut [f64],
    r: &Recursion,
    burn_in: usize,
    offset: f64,
    key: &StreamKey,
    what: &str,
) -> Result<()> {
    add_recursion_from(
        out,
        r,
        burn_in,
        offset,
        key,
        what,
        0,
        &mut RecState::default(),
    )
}

/// [`add_recursion`] for a block starting at sample `c0 * CHUNK` of the series, the
/// recursion's state carried in `state` (a default one for the first block, which
/// runs the burn-in).
#[allow(clippy::too_many_arguments)]
pub fn add_recursion_from(
    out: &mut [f64],
    r: &Recursion,
    burn_in: usize,
    offset: f64,
    key: &StreamKey,
    what: &str,
    c0: u64,
    state: &mut RecState,
) -> Result<()> {
    use rand_distr::{Distribution, StandardNormal};
    let sigma = r.sigma;
    let mut buf = vec![0.0; out.len()];
    for_chunks_from(&mut buf, c0, |c, s| {
        let mut rng = key.rng(0, c);
        for v in s.iter_mut() {
            let w: f64 = StandardNormal.sample(&mut rng);
            *v = sigma * w;
        }
    });
    let diverged = |t: usize, during: &str| {
        Error::Usage(format!(
            "{what}: the recursion diverged {during} sample {t} (|x| reached 1e150); the AR part or the f_m make it unstable"
        ))
    };
    if !state.started {
        state.xs = vec![0.0; r.p.max(r.d)];
        state.es = vec![0.0; r.ma.len()];
        let mut burn: Vec<f64> = normals(&mut key.init_rng(0), burn_in);
        burn.iter_mut().for_each(|v| *v *= sigma);
        recurse(&mut burn, r, &mut state.xs, &mut state.es)
            .map_err(|t| diverged(t, "in the burn-in, at"))?;
        state.started = true;
    }
    let start = c0 as usize * super::streams::CHUNK;
    recurse(&mut buf, r, &mut state.xs, &mut state.es).map_err(|t| diverged(start + t, "at"))?;
    for (o, x) in out.iter_mut().zip(&buf) {
        *o += x + offset;
    }
    Ok(())
}
