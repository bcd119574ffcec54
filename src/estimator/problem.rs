//! The varying-coefficient regression every local fit solves, and what a fit returns.
//!
//! For rows t = start .. N-1 of a series x: index U_t = x_{t-d}; regressors
//! X_t = (x_{t-1}, ..., x_{t-p}); response y_t = x_t - sum_{m=1..q} b_m e_{t-m}, with
//! e the current residuals (zero before the first sample). At a grid point u_g with
//! bandwidth h the local-linear fit minimises
//! sum_t K((U_t - u_g)/h) (y_t - X_t' (a + c (U_t - u_g)/h))^2,
//! so f(u_g) = a and f'(u_g) = c / h (Fan and Gijbels 1996, ch. 3; Cai, Fan and Yao 2000).

use super::series::Centred;

/// The regression data (borrowed; nothing is copied).
#[derive(Clone, Copy, Debug)]
pub struct VcProblem<'a> {
    /// The series (read with its mean taken out when it is a store's column).
    pub x: Centred<'a>,
    /// Residuals for the MA part (empty when q = 0).
    pub e: &'a [f64],
    /// MA coefficients b_1..b_q.
    pub b: &'a [f64],
    pub p: usize,
    pub d: usize,
    /// First row used: max(p, q, d).
    pub start: usize,
    /// Another response: y_t = r[t - lag] for `Some((r, lag))` (the online state's
    /// cross moments, which hold x_t and each e_{t-j} apart); None for the model's
    /// y_t = x_t - sum b_m e_{t-m}.
    pub resp: Option<(&'a [f64], usize)>,
}

impl<'a> VcProblem<'a> {
    /// The problem of series `x` with residuals `e`, MA coefficients `b` (q of them),
    /// order p and delay d, from its first usable row max(p, q, d).
    pub fn new(x: impl Into<Centred<'a>>, e: &'a [f64], b: &'a [f64], p: usize, d: usize) -> Self {
        VcProblem {
            x: x.into(),
            e,
            b,
            p,
            d,
            start: p.max(b.len()).max(d),
            resp: None,
        }
    }

    /// Rows used.
    pub fn n_rows(&self) -> usize {
        self.x.len().saturating_sub(self.start)
    }

    /// Index U_t.
    #[inline]
    pub fn u(&self, t: usize) -> f64 {
        self.x.at(t - self.d)
    }

    /// Response y_t.
    #[inline]
    pub fn y(&self, t: usize) -> f64 {
        if let Some((r, lag)) = self.resp {
            return r[t - lag];
        }
        let mut y = self.x.at(t);
        for (m, bm) in self.b.iter().enumerate() {
            y -= bm * self.e[t - m - 1];
        }
        y
    }

    /// Regressor m (0-based: x_{t-1-m}).
    #[inline]
    pub fn xr(&self, t: usize, m: usize) -> f64 {
        self.x.at(t - 1 - m)
    }

    /// Fills `v` with (X_t, y_t): p + 1 values.
    #[inline]
    pub fn row(&self, t: usize, v: &mut [f64]) {
        for m in 0..self.p {
            v[m] = self.xr(t, m);
        }
        v[self.p] = self.y(t);
    }
}

/// Why a grid point has no fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PointStatus {
    Ok,
    /// No sample inside the kernel's support.
    EmptySupport,
    /// Fewer samples inside the support than the 2p unknowns.
    TooFewSamples,
    /// The local normal equations are singular or their condition number exceeds
    /// `linalg::MAX_COND` (collinear regressors in the support).
    Singular,
}

impl PointStatus {
    pub fn as_str(&self) -> &'static str {
        match self {
            PointStatus::Ok => "ok",
            PointStatus::EmptySupport => "empty_support",
            PointStatus::TooFewSamples => "too_few_samples",
            PointStatus::Singular => "singular",
        }
    }
}

/// Local-linear fits at every grid point for one bandwidth.
#[derive(Clone, Debug)]
pub struct GridFit {
    pub bandwidth: f64,
    pub p: usize,
    /// f_m(u_g), row-major G x p; NaN where the status is not Ok.
    pub f: Vec<f64>,
    /// f_m'(u_g), G x p.
    pub slope: Vec<f64>,
    /// Inverse of the local normal matrix S_g (G x 2p x 2p), for traces and errors.
    pub s_inv: Vec<f64>,
    /// Samples inside each support.
    pub n_support: Vec<u64>,
    /// Kernel mass sum_t K((U_t - u_g)/h).
    pub kernel_mass: Vec<f64>,
    /// Condition number of the equilibrated local system (see `linalg`).
    pub cond: Vec<f64>,
    pub status: Vec<PointStatus>,
}

impl GridFit {
    pub fn new(g: usize, p: usize, bandwidth: f64) -> GridFit {
        GridFit {
            bandwidth,
            p,
            f: vec![f64::NAN; g * p],
            slope: vec![f64::NAN; g * p],
            s_inv: vec![f64::NAN; g * 4 * p * p],
            n_support: vec![0; g],
            kernel_mass: vec![0.0; g],
            cond: vec![f64::NAN; g],
            status: vec![PointStatus::EmptySupport; g],
        }
    }

    pub fn n_grid(&self) -> usize {
        self.status.len()
    }

    pub fn all_ok(&self) -> bool {
        self.status.iter().all(|s| *s == PointStatus::Ok)
    }

    /// Stores the solution of grid point `g` from its normal equations (row-major
    /// `s`, 2p x 2p, and `rhs`, 2p), setting the status.
    pub fn set_point(
        &mut self,
        g: usize,
        s: &[f64],
        rhs: &[f64],
        n_support: u64,
        kernel_mass: f64,
    ) {
        if !self.set_support(g, n_support, kernel_mass) {
            return;
        }
        match super::linalg::spd_solve_inverse(s, rhs, 2 * self.p) {
            None => self.status[g] = PointStatus::Singular,
            Some((sol, inv, cond)) => self.set_solved(g, &sol, &inv, cond),
        }
    }

    /// Stores point g's support count and kernel mass; with fewer than 2p samples
    /// sets its status (empty support or too few samples) and returns false.
    fn set_support(&mut self, g: usize, n_support: u64, kernel_mass: f64) -> bool {
        self.n_support[g] = n_support;
        self.kernel_mass[g] = kernel_mass;
        if n_support == 0 {
            self.status[g] = PointStatus::EmptySupport;
            false
        } else if (n_support as usize) < 2 * self.p {
            self.status[g] = PointStatus::TooFewSamples;
            false
        } else {
            true
        }
    }

    /// [`GridFit::set_point`] with the system factored beforehand (`factor`: None
    /// when it is singular; [`super::linalg::small_spd_factor`]): the same status,
    /// values and bits.
    pub fn set_point_factored(
        &mut self,
        g: usize,
        factor: Option<&super::linalg::SpdFactor>,
        rhs: &[f64],
        n_support: u64,
        kernel_mass: f64,
    ) {
        if !self.set_support(g, n_support, kernel_mass) {
            return;
        }
        match factor {
            None => self.status[g] = PointStatus::Singular,
            Some(f) => self.set_solved(g, &f.solve(rhs), &f.inv, f.cond),
        }
    }

    fn set_solved(&mut self, g: usize, sol: &[f64], inv: &[f64], cond: f64) {
        let p = self.p;
        self.status[g] = PointStatus::Ok;
        self.cond[g] = cond;
        for m in 0..p {
            self.f[g * p + m] = sol[m];
            self.slope[g * p + m] = sol[p + m] / self.bandwidth;
        }
        self.s_inv[g * 4 * p * p..(g + 1) * 4 * p * p].copy_from_slice(inv);
    }

    /// f at `u` by linear interpolation between grid values, constant beyond the ends.
    /// `grid` ascending; all points must be Ok.
    #[inline]
    pub fn eval(&self, grid: &[f64], u: f64, out: &mut [f64]) {
        let p = self.p;
        let g = grid.len();
        if u <= grid[0] {
            out.copy_from_slice(&self.f[..p]);
        } else if u >= grid[g - 1] {
            out.copy_from_slice(&self.f[(g - 1) * p..g * p]);
        } else {
            let k = grid.partition_point(|v| *v <= u) - 1;
            let lam = (u - grid[k]) / (grid[k + 1] - grid[k]);
            for m in 0..p {
                let a = self.f[k * p + m];
                out[m] = a + lam * (self.f[(k + 1) * p + m] - a);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::linalg::small_spd_factor;
    use super::*;

    fn field_bits(f: &GridFit) -> Vec<u64> {
        let b = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
        let mut out = b(&f.f);
        out.extend(b(&f.slope));
        out.extend(b(&f.s_inv));
        out.extend(b(&f.cond));
        out.extend(b(&f.kernel_mass));
        out.extend(&f.n_support);
        out
    }

    #[test]
    fn a_point_set_from_its_factor_is_the_point_solved_afresh() {
        // (p, S, count): well posed, too few samples, empty, singular, indefinite
        let spd = |p: usize, seed: f64| {
            let n = 2 * p;
            let a: Vec<f64> = (0..n * n)
                .map(|k| ((k as f64 + seed) * 0.7).sin())
                .collect();
            let mut s = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..n {
                    s[i * n + j] = (0..n).map(|k| a[i * n + k] * a[j * n + k]).sum::<f64>()
                        + if i == j { 0.1 } else { 0.0 };
                }
            }
            s
        };
        for p in [1, 2, 3, 4] {
            let n = 2 * p;
            let rhs: Vec<f64> = (0..n).map(|k| 1.0 - 0.3 * k as f64).collect();
            let singular = vec![1.0; n * n];
            let mut indefinite = spd(p, 2.0);
            indefinite[0] = -1.0;
            let cases: Vec<(Vec<f64>, u64)> = vec![
                (spd(p, 0.0), 100),
                (spd(p, 1.0), n as u64 - 1),
                (spd(p, 1.0), 0),
                (singular, 100),
                (indefinite, 100),
            ];
            let mut fresh = GridFit::new(cases.len(), p, 0.25);
            let mut factored = GridFit::new(cases.len(), p, 0.25);
            for (g, (s, count)) in cases.iter().enumerate() {
                fresh.set_point(g, s, &rhs, *count, 3.5);
                let factor = small_spd_factor(s, n);
                factored.set_point_factored(g, factor.as_ref(), &rhs, *count, 3.5);
            }
            assert_eq!(fresh.status, factored.status, "p = {p}");
            assert_eq!(field_bits(&fresh), field_bits(&factored), "p = {p}");
            assert_eq!(fresh.status[0], PointStatus::Ok);
            assert_eq!(fresh.status[1], PointStatus::TooFewSamples);
            assert_eq!(fresh.status[2], PointStatus::EmptySupport);
            assert_eq!(fresh.status[3], PointStatus::Singular);
            assert_eq!(fresh.status[4], PointStatus::Singular);
        }
    }
}
