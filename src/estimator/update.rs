//! Online updates of a fitted FARMA model: recursive least squares (RLS) over new
//! samples, for every grid point's local coefficients and for the MA coefficients b,
//! with an optional forgetting factor lambda (0 < lambda <= 1).
//!
//! The state of a channel ([`ChannelState`], the file `state.parquet`) holds the
//! normal equations of the batch fit, so that any later combination is exact:
//! - per grid point u_g: the local Gram matrix S_g = sum_t K_t z_t z_t' (2p x 2p,
//!   z_t = (X_t, w_t X_t), w_t = (U_t - u_g)/h, K_t = K(w_t), the rows of
//!   [`super::direct::fit_grid`]), the cross moments C_g = sum_t K_t z_t r_t'
//!   (2p x (1+q)) with r_t = (x_t, e_{t-1}, ..., e_{t-q}), so that the right-hand side
//!   for any b is C_g (1, -b_1, ..., -b_q)', and S2_g = sum_t K_t^2 z_t z_t' for the
//!   sandwich standard errors;
//! - for b: S_b = sum_t phi_t phi_t' (phi_t = (e_{t-1}, ..., e_{t-q})) and
//!   r_b = S_b b_0, so that the RLS below starts from the fitted b_0 with the
//!   information of the fitted rows (the batch b comes from Gauss-Newton, not from a
//!   linear regression, so b_0 is carried as the prior mean);
//! - the mean removed at fit time (kept: new samples are centred with it), the grid,
//!   the bandwidth (held fixed), the last max(p,q,d) samples and residuals, n, and the
//!   (weighted) RSS and row count.
//!
//! The state stores the Gram form (not P = S^-1): a grid point whose system was
//! singular or empty at fit time keeps accumulating and gets a fit once its system is
//! solvable, and P never drifts across many updates. When an update starts,
//! P_g = S_g^-1 and Theta_g = P_g C_g are computed for every solvable grid point, and
//! the paper's online scheme runs over the new samples t, in order:
//! 1. f_m(U_t) from the current Theta (f at u_g is the first p entries of
//!    Theta_g (1, -b)'), linear between the solvable grid points, constant beyond;
//! 2. w_t = x_t - sum_m f_m(U_t) x_{t-m}; e_t = w_t - sum_m b_m e_{t-m} (the a priori
//!    residual of the current model, continuing the fit's residual recursion);
//! 3. b by RLS on (phi_t, w_t); every grid point whose Biweight support holds U_t by
//!    weighted rank-one RLS (Ljung and Soderstrom 1983, ch. 2; Haykin, Adaptive Filter
//!    Theory, 4th ed., 9.3): with weight k = K_t,
//!    P <- P / lambda, g = k P z / (1 + k z'P z), Theta <- Theta + g (r' - z'Theta),
//!    P <- P - g z'P; and S, C, S2 are discounted by lambda (S2 by lambda^2) and the new
//!    row added. Rows outside a support cost nothing: the discount lambda^a of the a
//!    samples a grid point did not see is applied when it next sees one.
//!
//! With lambda < 1 the P recursion amplifies its own rounding by 1 / lambda per step in
//! its antisymmetric part (Ljung and Ljung 1985): P is kept symmetric, and P and Theta
//! (P_b and b) are derived afresh from the discounted normal equations, which are plain
//! weighted sums, whenever the product of the discounts since the last derivation falls
//! below 1e-4 (`REDERIVE`); a point whose normal equations have become singular (it
//! has forgotten its samples) keeps its P and Theta until they are solvable again. The
//! f and slopes written are solved from the normal equations at the end (the RLS
//! estimate in exact arithmetic); Theta drives the a priori residuals of step 2
//! (tests/suite/estimator_update.rs: without both, 12,000 new rows at lambda = 0.99 end with
//! sigma^2 at 1.7e5 instead of 1.08).
//!
//! With lambda = 1 the result is the batch local fit on the concatenated data with the
//! residual sequence the update produced, at the same bandwidth; with lambda < 1 it
//! is the exponentially weighted least-squares fit
//! argmin lambda^n (theta-theta_0)' S_0 (theta-theta_0) + sum_t lambda^(n-1-t) K_t (y_t - z_t' theta)^2
//! over the n new rows (tests/suite/estimator_update.rs checks both, against a direct
//! KD-tree fit and a brute-force sum). sigma^2 = RSS / rows, both discounted the same
//! way (with lambda = 1: RSS / (N - max(p,q,d)) over all samples).

use rayon::prelude::*;

use super::fit::{FitPath, missing_se_note};
use super::kernel::biweight;
use super::linalg::spd_solve_inverse;
use super::moments::{Families, MomentTable, breakpoints, sandwich_diag};
use super::problem::{GridFit, PointStatus, VcProblem};
use crate::error::{Error, Result};
use crate::model::state::{ChannelState, LastTime};
use crate::model::{Coef, Farma, FitReport, Order, UpdateReport};

/// Fills `z` = (X_t, w X_t) and `r` = (x_t, e_{t-1}, ..., e_{t-q}) for row t of the
/// centred series `x` with residuals `e`, at grid point `ug`; returns the kernel weight.
#[inline]
#[allow(clippy::too_many_arguments)]
fn local_row(
    x: &[f64],
    e: &[f64],
    (p, q, d): (usize, usize, usize),
    t: usize,
    ug: f64,
    h: f64,
    z: &mut [f64],
    r: &mut [f64],
) -> f64 {
    let w = (x[t - d] - ug) / h;
    for m in 0..p {
        z[m] = x[t - 1 - m];
        z[p + m] = w * z[m];
    }
    r[0] = x[t];
    for j in 0..q {
        r[1 + j] = e[t - 1 - j];
    }
    biweight(w)
}

/// Amplification of the P recursions' rounding (1 / the product of the discounts since
/// P was last derived) beyond which P and Theta (and P_b and b) are derived afresh from
/// the discounted normal equations: the recursion's errors then stay below about
/// 1e4 times the rounding of one step.
const REDERIVE: f64 = 1e4;

/// P = (P + P') / 2 for an n x n matrix: the RLS recursion with forgetting amplifies
/// the antisymmetric part of its rounding by 1 / lambda per step (Ljung and Ljung,
/// "Error propagation properties of recursive least-squares adaptation algorithms",
/// Automatica 21, 1985); the symmetric part decays.
fn symmetrize(pm: &mut [f64], n: usize) {
    for i in 0..n {
        for j in i + 1..n {
            let v = 0.5 * (pm[i * n + j] + pm[j * n + i]);
            pm[i * n + j] = v;
            pm[j * n + i] = v;
        }
    }
}

/// P_g = S_g^-1 and Theta_g = P_g C_g from the state's normal equations at grid point
/// `g`; false (nothing changed) when S_g is singular.
fn rederive(st: &ChannelState, g: usize, pm: &mut [f64], theta: &mut [f64]) -> bool {
    let (n, nc) = (2 * st.p, 1 + st.q);
    // (the inverse alone is used: any right-hand side)
    let zero = vec![0.0; n];
    let Some((_, inv, _)) = spd_solve_inverse(&st.gram[g * n * n..(g + 1) * n * n], &zero, n)
    else {
        return false;
    };
    let cg = &st.cross[g * n * nc..(g + 1) * n * nc];
    for i in 0..n {
        for col in 0..nc {
            theta[g * n * nc + i * nc + col] =
                (0..n).map(|j| inv[i * n + j] * cg[j * nc + col]).sum();
        }
    }
    pm[g * n * n..(g + 1) * n * n].copy_from_slice(&inv);
    true
}

/// S <- lam S + k z z', C <- lam C + k z r', S2 <- lam2 S2 + k^2 z z'.
#[inline]
#[allow(clippy::too_many_arguments)]
fn accumulate(
    gram: &mut [f64],
    cross: &mut [f64],
    gram2: &mut [f64],
    z: &[f64],
    r: &[f64],
    k: f64,
    lam: f64,
    lam2: f64,
) {
    let n = z.len();
    let nc = r.len();
    for i in 0..n {
        let kz = k * z[i];
        for j in 0..n {
            gram[i * n + j] = lam * gram[i * n + j] + kz * z[j];
            gram2[i * n + j] = lam2 * gram2[i * n + j] + kz * k * z[j];
        }
        for c in 0..nc {
            cross[i * nc + c] = lam * cross[i * nc + c] + kz * r[c];
        }
    }
}

/// The grid points whose support [u_g - h, u_g + h) may hold `u` (check exactly).
#[inline]
fn candidates(grid: &[f64], u: f64, h: f64) -> std::ops::Range<usize> {
    let a = grid.partition_point(|v| *v < u - h * (1.0 + 1e-12));
    let b = grid.partition_point(|v| *v <= u + h * (1.0 + 1e-12));
    a..b
}

/// Normal equations of every grid point over rows `rows` (one pass, no discount).
struct Sums {
    gram: Vec<f64>,
    cross: Vec<f64>,
    gram2: Vec<f64>,
    mass: Vec<f64>,
    count: Vec<u64>,
}

impl Sums {
    fn zeros(g: usize, p: usize, q: usize) -> Sums {
        let n = 2 * p;
        Sums {
            gram: vec![0.0; g * n * n],
            cross: vec![0.0; g * n * (1 + q)],
            gram2: vec![0.0; g * n * n],
            mass: vec![0.0; g],
            count: vec![0; g],
        }
    }

    fn add(&mut self, o: &Sums) {
        let pairs = [
            (&mut self.gram, &o.gram),
            (&mut self.cross, &o.cross),
            (&mut self.gram2, &o.gram2),
            (&mut self.mass, &o.mass),
        ];
        for (a, b) in pairs {
            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        }
        self.count
            .iter_mut()
            .zip(&o.count)
            .for_each(|(x, y)| *x += y);
    }
}

/// The state of a fitted channel: its normal equations at the fit's final residuals
/// and b. On the fast path (`r.path` [`FitPath::Fast`]) the per-grid-point sums come
/// from one-pass moment tables (`sums_from_tables`); otherwise, and in
/// [`state_from_fit_direct`], its slow twin, from a pass that adds each row to every
/// grid point whose support holds it (`sums_direct`). Either way the result does not
/// depend on the number of threads.
///
/// A model at GCV's limit h -> infinity (bandwidth +inf) has no kernel windows: its
/// state holds zero sums, and [`update`] refuses it (`farma fit --save-state` keeps
/// the bandwidth finite).
pub fn state_from_fit(channel: &str, series: &[f64], m: &Farma, r: &FitReport) -> ChannelState {
    let x: Vec<f64> = series.iter().map(|v| v - m.mean).collect();
    let sums = match r.path {
        _ if m.bandwidth.is_infinite() => Sums::zeros(m.coef.grid.len(), m.p(), m.q()),
        FitPath::Fast => sums_from_tables(&x, m, r),
        FitPath::Direct => sums_direct(&x, m, r),
    };
    state_with(channel, x, m, r, sums)
}

/// [`state_from_fit`] by the direct pass whatever the fit's path: the slow twin the
/// tables' sums are tested against.
pub fn state_from_fit_direct(
    channel: &str,
    series: &[f64],
    m: &Farma,
    r: &FitReport,
) -> ChannelState {
    let x: Vec<f64> = series.iter().map(|v| v - m.mean).collect();
    let sums = if m.bandwidth.is_infinite() {
        Sums::zeros(m.coef.grid.len(), m.p(), m.q())
    } else {
        sums_direct(&x, m, r)
    };
    state_with(channel, x, m, r, sums)
}

/// The normal equations of every grid point by a direct pass over the centred series
/// `x`: each row is added to the grid points whose support holds it (the rows of
/// [`super::direct::fit_grid`]); rows are cut into fixed blocks (their size does not
/// depend on the threads), blocks run in parallel and are added in order. Its cost is
/// rows x grid points per support (about 1 s at 1e6 samples and 201 grid points).
fn sums_direct(x: &[f64], m: &Farma, r: &FitReport) -> Sums {
    const BLOCK: usize = 1 << 15;
    const GROUP: usize = 32;
    let (p, q, d) = (m.p(), m.q(), m.d());
    let lag = p.max(q).max(d);
    let e = &r.residuals;
    let h = m.bandwidth;
    let grid = &m.coef.grid;
    let n = 2 * p;
    let nc = 1 + q;
    let g = grid.len();
    let starts: Vec<usize> = (lag..x.len()).step_by(BLOCK).collect();
    let mut total = Sums::zeros(g, p, q);
    for group in starts.chunks(GROUP) {
        let parts: Vec<Sums> = group
            .par_iter()
            .map(|&s0| {
                let mut acc = Sums::zeros(g, p, q);
                let (mut z, mut r) = (vec![0.0; n], vec![0.0; nc]);
                for t in s0..(s0 + BLOCK).min(x.len()) {
                    let u = x[t - d];
                    for k in candidates(grid, u, h) {
                        let ug = grid[k];
                        if !(ug - h <= u && u < ug + h) {
                            continue;
                        }
                        let kw = local_row(x, e, (p, q, d), t, ug, h, &mut z, &mut r);
                        accumulate(
                            &mut acc.gram[k * n * n..(k + 1) * n * n],
                            &mut acc.cross[k * n * nc..(k + 1) * n * nc],
                            &mut acc.gram2[k * n * n..(k + 1) * n * n],
                            &z,
                            &r,
                            kw,
                            1.0,
                            1.0,
                        );
                        acc.mass[k] += kw;
                        acc.count[k] += 1;
                    }
                }
                acc
            })
            .collect();
        for part in &parts {
            total.add(part);
        }
    }
    total
}

/// The normal equations of every grid point from one-pass moment tables over the
/// breakpoints u_g and u_g -+ h ([`MomentTable`], the fast path's exact sums): the
/// design's families to degree 10 give S_g, S2_g, the kernel mass and the count
/// ([`MomentTable::state_design`]); for each column r_c of r_t = (x_t, e_{t-1}, ..,
/// e_{t-q}), a table of X_a r_c to degree 5 gives column c of C_g
/// ([`MomentTable::local_rhs_at`]). 1 + (q + 1) passes of p(p+1)/2 + 1 and p families
/// instead of a pass of rows x grid points per support: the same sums to rounding
/// (tests/suite/estimator_update.rs checks them against [`sums_direct`]).
fn sums_from_tables(x: &[f64], m: &Farma, r: &FitReport) -> Sums {
    let (p, q, d) = (m.p(), m.q(), m.d());
    let lag = p.max(q).max(d);
    let (h, grid) = (m.bandwidth, &m.coef.grid);
    let (n, nc, g) = (2 * p, 1 + q, grid.len());
    let e = &r.residuals;
    let (umin, umax) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let breaks = || breakpoints(grid, &[h]);
    // every row from max(p, q, d), as the direct pass; the response of column c
    fn problem<'a>(
        x: &'a [f64],
        (p, d, lag): (usize, usize, usize),
        resp: Option<(&'a [f64], usize)>,
    ) -> VcProblem<'a> {
        VcProblem {
            start: lag,
            resp,
            ..VcProblem::new(x, &[], &[], p, d)
        }
    }
    let design = MomentTable::build_families(
        &problem(x, (p, d, lag), None),
        breaks(),
        umin,
        umax,
        10,
        Families::Design,
    );
    let mut sums = Sums::zeros(g, p, q);
    for (k, (s, s2, count, mass)) in design.state_design(grid, h).into_iter().enumerate() {
        sums.gram[k * n * n..(k + 1) * n * n].copy_from_slice(&s);
        sums.gram2[k * n * n..(k + 1) * n * n].copy_from_slice(&s2);
        sums.count[k] = count;
        sums.mass[k] = mass;
    }
    for c in 0..nc {
        // column 0: x_t (the model's response with b = 0); column c: e_{t-c}
        let resp = (c > 0).then_some((&e[..], c));
        let table = MomentTable::build_families(
            &problem(x, (p, d, lag), resp),
            breaks(),
            umin,
            umax,
            5,
            Families::Response,
        );
        for (k, rhs) in table.local_rhs_at(grid, h).into_iter().enumerate() {
            for i in 0..n {
                sums.cross[k * n * nc + i * nc + c] = rhs[i];
            }
        }
    }
    sums
}

/// The state of a fitted channel from its centred series `x` and the grid points'
/// normal equations `sums`.
fn state_with(channel: &str, x: Vec<f64>, m: &Farma, r: &FitReport, total: Sums) -> ChannelState {
    let (p, q, d) = (m.p(), m.q(), m.d());
    let lag = p.max(q).max(d);
    let e = &r.residuals;
    let h = m.bandwidth;
    let grid = &m.coef.grid;
    let mut st = ChannelState {
        channel: channel.to_string(),
        p,
        q,
        d,
        mean: m.mean,
        bandwidth: h,
        grid: grid.clone(),
        gram: total.gram,
        cross: total.cross,
        gram2: total.gram2,
        kernel_mass: total.mass,
        n_support: total.count,
        b: m.b.clone(),
        b_gram: vec![0.0; q * q],
        b_rhs: vec![0.0; q],
        x_tail: x[x.len() - lag..].to_vec(),
        e_tail: e[e.len() - lag..].to_vec(),
        n: x.len() as u64,
        rss: (lag..x.len()).map(|t| e[t] * e[t]).sum(),
        rows: (x.len() - lag) as f64,
        forgetting: 1.0,
        linear_start: r.linear_start,
        t_last: LastTime::NoTimeColumn,
    };
    for t in lag..x.len() {
        for i in 0..q {
            for j in 0..q {
                st.b_gram[i * q + j] += e[t - 1 - i] * e[t - 1 - j];
            }
        }
    }
    for i in 0..q {
        st.b_rhs[i] = (0..q).map(|j| st.b_gram[i * q + j] * m.b[j]).sum();
    }
    st
}

/// Entry `row` of Theta (1, -b)' for one grid point's Theta (2p x (1+q), row-major):
/// rows 0..p are f_m(u_g), rows p..2p are h f_m'(u_g).
#[inline]
fn theta_coef(theta: &[f64], nc: usize, b: &[f64], row: usize) -> f64 {
    let mut v = theta[row * nc];
    for (j, bj) in b.iter().enumerate() {
        v -= bj * theta[row * nc + 1 + j];
    }
    v
}

/// Continues the recursion of `state` over `new` (raw samples, channel units) with
/// forgetting factor `forgetting` (1: none). See the module documentation.
pub fn update(
    state: &ChannelState,
    new: &[f64],
    forgetting: f64,
) -> Result<(Farma, ChannelState, UpdateReport)> {
    if !(forgetting > 0.0 && forgetting <= 1.0) {
        return Err(Error::Usage(format!(
            "--forgetting: {forgetting} is not in (0, 1]"
        )));
    }
    let linear_start_refused = || {
        Err(Error::Data(
            "its fit returned the linear ARMA start (the local fits ended above it in RSS), so the state holds no fitted local model to continue; fit the concatenated log instead".into(),
        ))
    };
    if state.bandwidth.is_infinite() {
        if state.linear_start {
            return linear_start_refused();
        }
        return Err(Error::Data(
            "its model is GCV's limit h -> infinity (the global fit, f_m linear in the index), which keeps no kernel windows to update; refit with `farma fit --save-state` (GCV then keeps a finite bandwidth) or a fixed --bandwidth".into(),
        ));
    }
    state
        .check()
        .and_then(|()| state.check_invertible())
        .and_then(|()| state.check_solvable())
        .map_err(Error::Data)?;
    if state.linear_start {
        return linear_start_refused();
    }
    if new.is_empty() {
        return Err(Error::Data("no new samples".into()));
    }
    if new.iter().any(|v| !v.is_finite()) {
        return Err(Error::Data(
            "the channel holds NaN or infinite values".into(),
        ));
    }
    let (p, q, d) = (state.p, state.q, state.d);
    let (n, nc, lag) = (2 * p, 1 + q, state.lag());
    let (nn, gl, h, lam) = (new.len(), state.n_grid(), state.bandwidth, forgetting);
    let mut st = state.clone();
    let mut xs = st.x_tail.clone();
    xs.extend(new.iter().map(|v| v - st.mean));
    if let Some(i) = xs.iter().position(|v| !v.is_finite()) {
        return Err(Error::Data(format!(
            "new sample {} ({:e}) minus the model's mean {:e} is not a finite number: the new samples do not fit the model's scale",
            i - lag,
            new[i - lag],
            st.mean
        )));
    }
    let mut es = st.e_tail.clone();
    es.resize(lag + nn, 0.0);
    let mut ws = vec![0.0; nn];

    // P and Theta of every solvable grid point
    let mut pm = vec![0.0; gl * n * n];
    let mut theta = vec![0.0; gl * n * nc];
    let mut tracked = vec![false; gl];
    for g in 0..gl {
        let c = st.n_support[g] as usize;
        if c == 0 || c < n {
            continue;
        }
        tracked[g] = rederive(&st, g, &mut pm, &mut theta);
    }
    let ti: Vec<usize> = (0..gl).filter(|g| tracked[*g]).collect();
    if ti.is_empty() {
        // (ChannelState::check_solvable, above, refuses such a state naming the field)
        return Err(Error::Internal(
            "the state has no grid point with a solvable local system, though check_solvable passed".into(),
        ));
    }
    let tg: Vec<f64> = ti.iter().map(|g| st.grid[*g]).collect();
    let mut pb = vec![0.0; q * q];
    if q > 0 {
        pb = spd_solve_inverse(&st.b_gram, &st.b_rhs, q)
            .ok_or_else(|| {
                Error::Internal(
                    "the state's MA normal equations are singular, though check_solvable passed"
                        .into(),
                )
            })?
            .1;
    }
    let mut b = st.b.clone();
    let mut sync = vec![0usize; gl];
    // the factor by which the P recursion has amplified its rounding since P was last
    // derived from the normal equations (1 / the discounts applied since): past
    // REDERIVE, P and Theta are derived afresh (module doc); with lambda = 1 it stays 1
    let mut amp = vec![1.0f64; gl];
    let mut amp_b = 1.0f64;
    let (mut f, mut fa, mut z, mut r) = (vec![0.0; p], vec![0.0; p], vec![0.0; n], vec![0.0; nc]);
    let (mut pz, mut phi, mut pphi) = (vec![0.0; n], vec![0.0; q], vec![0.0; q]);
    let mut resid = vec![0.0; nc];
    let f_at = |theta: &[f64], g: usize, b: &[f64], out: &mut [f64]| {
        let th = &theta[g * n * nc..(g + 1) * n * nc];
        for m in 0..p {
            out[m] = theta_coef(th, nc, b, m);
        }
    };
    for k in 0..nn {
        let t = lag + k;
        let u = xs[t - d];
        // 1. current f at U_t: linear between the tracked points, constant beyond
        // (written so that a NaN u takes this branch: never an index below 0)
        if u.is_nan() || u <= tg[0] {
            f_at(&theta, ti[0], &b, &mut f);
        } else if u >= tg[tg.len() - 1] {
            f_at(&theta, ti[ti.len() - 1], &b, &mut f);
        } else {
            let j = tg.partition_point(|v| *v <= u) - 1;
            let lamw = (u - tg[j]) / (tg[j + 1] - tg[j]);
            f_at(&theta, ti[j], &b, &mut fa);
            f_at(&theta, ti[j + 1], &b, &mut f);
            for m in 0..p {
                f[m] = fa[m] + lamw * (f[m] - fa[m]);
            }
        }
        // 2. a priori residuals
        let mut w = xs[t];
        for m in 0..p {
            w -= f[m] * xs[t - 1 - m];
        }
        let mut e = w;
        for j in 0..q {
            e -= b[j] * es[t - 1 - j];
        }
        es[t] = e;
        ws[k] = w;
        st.rss = lam * st.rss + e * e;
        st.rows = lam * st.rows + 1.0;
        // 3a. b by RLS on (phi_t, w_t)
        if q > 0 {
            for j in 0..q {
                phi[j] = es[t - 1 - j];
            }
            let mut denom = lam;
            for i in 0..q {
                pphi[i] = (0..q).map(|j| pb[i * q + j] * phi[j]).sum();
                denom += phi[i] * pphi[i];
            }
            let err = w - (0..q).map(|j| b[j] * phi[j]).sum::<f64>();
            for i in 0..q {
                b[i] += pphi[i] / denom * err;
            }
            for i in 0..q {
                for j in 0..q {
                    pb[i * q + j] = (pb[i * q + j] - pphi[i] * pphi[j] / denom) / lam;
                }
                for j in 0..q {
                    st.b_gram[i * q + j] = lam * st.b_gram[i * q + j] + phi[i] * phi[j];
                }
                st.b_rhs[i] = lam * st.b_rhs[i] + phi[i] * w;
            }
            if lam < 1.0 {
                amp_b /= lam;
                symmetrize(&mut pb, q);
                if amp_b > REDERIVE {
                    // b and P_b from the discounted normal equations (the RLS estimate
                    // in exact arithmetic); kept as they are if those are singular
                    if let Some((sol, inv, _)) = spd_solve_inverse(&st.b_gram, &st.b_rhs, q) {
                        b = sol;
                        pb = inv;
                    }
                    amp_b = 1.0;
                }
            }
        }
        // 3b. every grid point whose support [u_g - h, u_g + h) holds U_t
        for g in candidates(&st.grid, u, h) {
            let ug = st.grid[g];
            if !(ug - h <= u && u < ug + h) {
                continue;
            }
            let kw = local_row(&xs, &es, (p, q, d), t, ug, h, &mut z, &mut r);
            // discount for the samples this point did not see, then this one
            let fac = if lam == 1.0 {
                1.0
            } else {
                lam.powf((k - sync[g]) as f64) * lam
            };
            sync[g] = k + 1;
            accumulate(
                &mut st.gram[g * n * n..(g + 1) * n * n],
                &mut st.cross[g * n * nc..(g + 1) * n * nc],
                &mut st.gram2[g * n * n..(g + 1) * n * n],
                &z,
                &r,
                kw,
                fac,
                fac * fac,
            );
            st.kernel_mass[g] = fac * st.kernel_mass[g] + kw;
            st.n_support[g] += 1;
            if !tracked[g] {
                continue;
            }
            if lam < 1.0 {
                amp[g] /= fac;
                if amp[g] > REDERIVE {
                    // P and Theta from the discounted normal equations, which hold this
                    // row already; kept as they are while those are singular (a point
                    // that has forgotten its samples), tried again at its next row
                    if rederive(&st, g, &mut pm, &mut theta) {
                        amp[g] = 1.0;
                    }
                    continue;
                }
            }
            // weighted rank-one RLS: P <- P/fac, gain = k P z / (1 + k z'P z)
            let pg = &mut pm[g * n * n..(g + 1) * n * n];
            let th = &mut theta[g * n * nc..(g + 1) * n * nc];
            let mut zpz = 0.0;
            for i in 0..n {
                pz[i] = (0..n).map(|j| pg[i * n + j] * z[j]).sum::<f64>() / fac;
                zpz += z[i] * pz[i];
            }
            let denom = 1.0 + kw * zpz;
            for c in 0..nc {
                resid[c] = r[c] - (0..n).map(|i| z[i] * th[i * nc + c]).sum::<f64>();
            }
            for i in 0..n {
                let gi = kw * pz[i] / denom;
                for c in 0..nc {
                    th[i * nc + c] += gi * resid[c];
                }
                for j in 0..n {
                    pg[i * n + j] = pg[i * n + j] / fac - gi * pz[j];
                }
            }
            if lam < 1.0 {
                symmetrize(pg, n);
            }
        }
    }
    // discount what the last samples did not reach
    for g in 0..gl {
        if sync[g] < nn {
            let fac = lam.powf((nn - sync[g]) as f64);
            for v in &mut st.gram[g * n * n..(g + 1) * n * n] {
                *v *= fac;
            }
            for v in &mut st.cross[g * n * nc..(g + 1) * n * nc] {
                *v *= fac;
            }
            for v in &mut st.gram2[g * n * n..(g + 1) * n * n] {
                *v *= fac * fac;
            }
            st.kernel_mass[g] *= fac;
        }
    }
    st.b = b.clone();
    st.x_tail = xs[xs.len() - lag..].to_vec();
    st.e_tail = es[es.len() - lag..].to_vec();
    let first_t = st.n;
    st.n = st.n.checked_add(nn as u64).ok_or_else(|| {
        Error::Data(format!(
            "{nn} new samples after {} take the sample count past 2^64",
            st.n
        ))
    })?;
    st.forgetting = lam;

    // the model: status, conditioning and S^-1 from the accumulated normal equations,
    // f and slope from the RLS recursion where it ran
    let mut coef = GridFit::new(gl, p, h);
    for g in 0..gl {
        let rhs = st.right_hand_side(g, &b);
        coef.set_point(
            g,
            &st.gram[g * n * n..(g + 1) * n * n],
            &rhs,
            st.n_support[g],
            st.kernel_mass[g],
        );
    }
    let sigma2 = st.rss / st.rows;
    let mut se = vec![f64::NAN; gl * p];
    for g in 0..gl {
        if coef.status[g] == PointStatus::Ok {
            let fac = sandwich_diag(
                &coef.s_inv[g * n * n..(g + 1) * n * n],
                &st.gram2[g * n * n..(g + 1) * n * n],
                n,
                p,
            );
            for m in 0..p {
                se[g * p + m] = fac[m] * sigma2.sqrt();
            }
        }
    }
    check_result(&st, state, new, &coef, sigma2, &es)?;
    let filled = super::fit::fill_failed(&mut coef, &st.grid)
        .ok_or_else(|| Error::Data("no grid point has a local fit after the update".into()))?;
    let mut notes = Vec::new();
    let n_filled = filled.iter().filter(|v| **v).count();
    if n_filled > 0 {
        notes.push(format!(
            "{n_filled} grid point(s) without a local fit were filled from their neighbours (see status)"
        ));
    }
    let newly = (0..gl)
        .filter(|g| !tracked[*g] && coef.status[*g] == PointStatus::Ok)
        .count();
    if newly > 0 {
        notes.push(format!(
            "{newly} grid point(s) without a fit before the update have one now (solved from the accumulated normal equations)"
        ));
    }
    notes.extend(missing_se_note(&coef.status, &coef.cond, &se, p));
    notes.extend(update_notes(state, &st, &coef, sigma2, &xs[lag..]));
    let model = Farma {
        order: Order::new(p, q, d),
        mean: st.mean,
        b,
        sigma2,
        bandwidth: h,
        coef: Coef {
            grid: st.grid.clone(),
            grid_shift: 0.0,
            f: coef.f.clone(),
            se,
            filled,
            second: None,
        },
    };
    let report = UpdateReport {
        local: coef,
        rss: st.rss,
        n: st.n as usize,
        n_rows: st.n as usize - lag,
        residuals: es[lag..].to_vec(),
        w: ws,
        first_t,
        forgetting,
        notes,
    };
    Ok((model, st, report))
}

/// An error unless the update's results are finite numbers: b, sigma^2, f and slopes
/// of the fitted points (the others are filled from these; the standard errors follow
/// from them and sigma^2, NaN only where the sandwich form fails, which a note says),
/// the residuals and the new state (which is written to continue later, and which
/// [`read_state`](crate::model::folder::state_file::read_state) would reject). Non-finite numbers come from new samples far off the
/// model's scale (their squares leave f64's range), so the message gives their range
/// against the model's grid.
fn check_result(
    st: &ChannelState,
    before: &ChannelState,
    new: &[f64],
    coef: &GridFit,
    sigma2: f64,
    es: &[f64],
) -> Result<()> {
    let p = st.p;
    let all = |v: &[f64]| v.iter().all(|x| x.is_finite());
    let ok_points = |v: &[f64]| {
        (0..st.n_grid()).all(|g| coef.status[g] != PointStatus::Ok || all(&v[g * p..(g + 1) * p]))
    };
    let what = if !all(&st.b) {
        Some("MA coefficients b".to_string())
    } else if !(sigma2.is_finite() && sigma2 >= 0.0) {
        Some(format!("sigma2 ({sigma2})"))
    } else if !ok_points(&coef.f) {
        Some("coefficient functions f".to_string())
    } else if !ok_points(&coef.slope) {
        Some("slopes of f".to_string())
    } else if !all(es) {
        Some("residuals".to_string())
    } else {
        st.check().err().map(|m| format!("state ({m})"))
    };
    let Some(what) = what else {
        return Ok(());
    };
    let (lo, hi) = new
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let g = &before.grid;
    Err(Error::Data(format!(
        "the update produced non-finite {what}: the new samples do not fit the model's scale (they span [{lo:e}, {hi:e}], the model's grid spans [{:e}, {:e}] with bandwidth {:e}, channel units); refit on the new log",
        g[0] + before.mean,
        g[g.len() - 1] + before.mean,
        before.bandwidth
    )))
}

/// A share of new samples beyond the grid +- h above this gets a note.
const OUTSIDE_SHARE: f64 = 0.05;
/// sigma^2 after an update above this multiple of sigma^2 before it gets a note.
const SIGMA2_RISE: f64 = 10.0;
/// A grid point whose discounted kernel mass (its effective samples after forgetting)
/// is below this multiple of its 2p unknowns gets counted in the forgetting note.
const MASS_PER_UNKNOWN: f64 = 5.0;

/// Notes on an update whose result is suspect: too short a memory for the local fits
/// (forgetting), a large rise of sigma^2, a non-invertible b. Nothing here changes a
/// number of the model.
/// `xs` holds the new samples, centred.
fn update_notes(
    before: &ChannelState,
    st: &ChannelState,
    coef: &GridFit,
    sigma2: f64,
    xs: &[f64],
) -> Vec<String> {
    let mut notes = Vec::new();
    let (g, h) = (&st.grid, st.bandwidth);
    let (lo, hi) = (g[0] - h, g[g.len() - 1] + h);
    let out = xs.iter().filter(|v| !(lo <= **v && **v <= hi)).count();
    if out as f64 > OUTSIDE_SHARE * xs.len() as f64 {
        notes.push(format!(
            "{out} of {} new sample(s) lie outside the reach of the model's grid [{:e}, {:e}] (grid +- bandwidth, channel units): f is extrapolated as a constant there; a level or scale change?",
            xs.len(),
            lo + st.mean,
            hi + st.mean
        ));
    }
    let lam = st.forgetting;
    let unknowns = 2 * st.p;
    if lam < 1.0 {
        let need = MASS_PER_UNKNOWN * unknowns as f64;
        let low = (0..st.n_grid())
            .filter(|g| coef.status[*g] == PointStatus::Ok && st.kernel_mass[*g] < need)
            .count();
        if low > 0 {
            let ok = coef
                .status
                .iter()
                .filter(|s| **s == PointStatus::Ok)
                .count();
            let mut mass = st.kernel_mass.clone();
            mass.sort_by(f64::total_cmp);
            notes.push(format!(
                "forgetting factor {lam}: the effective memory 1/(1 - lambda) = {:.1} sample(s) leaves {low} of {ok} fitted grid point(s) with an effective kernel mass below {need} ({MASS_PER_UNKNOWN} per unknown of their {unknowns}-unknown local systems; median mass over the grid {:.3}): their f rest on too few samples and may be far off; use a forgetting factor closer to 1",
                1.0 / (1.0 - lam),
                mass[mass.len() / 2]
            ));
        }
    }
    let before_s2 = before.rss / before.rows;
    if before_s2 > 0.0 && sigma2 > SIGMA2_RISE * before_s2 {
        let why = if lam < 1.0 {
            "the new samples do not follow the model, or the forgetting factor leaves the local fits too few samples"
        } else {
            "the new samples do not follow the model (a level or scale change?); consider a refit"
        };
        notes.push(format!(
            "sigma2 rose from {before_s2:.6e} to {sigma2:.6e} ({:.3e} times) over the update: {why}",
            sigma2 / before_s2
        ));
    }
    if let Some(what) = super::arma::not_invertible(&st.b) {
        notes.push(format!(
            "the updated MA coefficients: {what}: the new samples do not follow the model (a level shift?); consider a refit"
        ));
    }
    notes
}
