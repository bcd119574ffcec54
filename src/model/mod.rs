//! The fitted FARMA(p,q,d) model, what fitting makes and every later verb reads:
//! x_t - mean = y_t, y_t = sum_m f_m(U_t) y_{t-m} + e_t + sum_m b_m e_{t-m},
//! e_t ~ (0, sigma^2), on the lag index U_t = y_{t-d} or on a 2-D index
//! U_t = (y_{t-d}, z_{t-d2}) with another channel z of the log.
//!
//! - [`Farma`]: the order, the mean, b, sigma^2, the bandwidth and the coefficient
//!   functions on their grid ([`coef`], which also names a 2-D index's channel z and
//!   its delay d2); its residual recursion ([`Farma::residuals`], with z
//!   [`Farma::residuals2`]) and, on the lag index, k-step prediction
//!   ([`Farma::kstep`]) are the ones `check`, `analyze` and the simulator use (they
//!   take the lag index alone).
//! - [`order`]: FARMA(p,q,d), parsed and bounded once.
//! - [`folder`]: the model folder on disk (`farma fit -o DIR`): its file names, and
//!   reading a channel's model back.
//!
//! Residual recursion (zeros before the series): e_t = y_t - yhat_t,
//! yhat_t = sum_{m <= min(p,t)} f_m(U_t) y_{t-m} + sum_{m <= min(q,t)} b_m e_{t-m},
//! with y_{t-d} = 0 for t < d and, on a 2-D index, z_{t-d2} = z_0 for t < d2.
//!
//! k-step prediction from origin s (data known up to s): the model is iterated with
//! the unknown future innovations set to 0 and the predicted values standing in for
//! unobserved y, in the index too:
//! ytilde_{s+j} = sum_m f_m(ytilde_{s+j-d}) ytilde_{s+j-m} + sum_m b_m etilde_{s+j-m},
//! ytilde = y and etilde = e up to s, etilde = 0 after (Box, Jenkins and Reinsel,
//! Time Series Analysis, 4th ed., 5.1, for the linear case).

pub mod coef;
pub mod folder;
pub mod order;
pub mod report;
pub mod state;

pub use coef::{Coef, SecondIndex};
pub use order::Order;
pub use report::{FitReport, Report, StartReason, UpdateReport};
pub use state::ChannelState;

/// A fitted FARMA(p,q,d) model of one channel on the lag index x_{t-d} or on a 2-D
/// index (x_{t-d}, z_{t-d2}) (`coef.second`).
#[derive(Clone, Debug, PartialEq)]
pub struct Farma {
    pub order: Order,
    /// Mean subtracted before fitting (0 without demeaning), channel units.
    pub mean: f64,
    /// MA coefficients b_1..b_q.
    pub b: Vec<f64>,
    /// Innovation variance RSS / (N - max(p,q,d)).
    pub sigma2: f64,
    /// Bandwidth h of the local fits along the lag (channel units); 0 for a linear
    /// model. A 2-D index's second bandwidth h_2 is its axis's (`coef.second`).
    pub bandwidth: f64,
    /// f_1..f_p on their grid.
    pub coef: Coef,
}

impl Farma {
    /// The linear ARMA(p,q) y_t = sum_m a_m y_{t-m} + e_t + sum_m b_m e_{t-m} as a FARMA
    /// with constant f_m = a_m and d = 1.
    pub fn linear(ar: &[f64], ma: &[f64], mean: f64, sigma2: f64) -> Farma {
        Farma {
            order: Order::new(ar.len(), ma.len(), 1),
            mean,
            b: ma.to_vec(),
            sigma2,
            bandwidth: 0.0,
            coef: Coef::constant(ar),
        }
    }

    pub fn p(&self) -> usize {
        self.order.p
    }

    pub fn q(&self) -> usize {
        self.order.q
    }

    pub fn d(&self) -> usize {
        self.order.d
    }

    /// The second coordinate of a 2-D index (None on the lag index).
    pub fn second(&self) -> Option<&SecondIndex> {
        self.coef.second.as_ref()
    }

    /// The bandwidths of the local fits as the GCV table records them: h, and h_2 on
    /// a 2-D index.
    pub fn bandwidths(&self) -> (f64, Option<f64>) {
        (self.bandwidth, self.second().map(|s| s.bandwidth))
    }

    /// f_1..f_p on the lag index at the centred index value `u` (x_{t-d} - mean) into
    /// `out` (length p).
    #[inline]
    pub fn f(&self, u: f64, out: &mut [f64]) {
        self.coef.eval(u, out)
    }

    /// f_1..f_p on a 2-D index at the centred lag value `u1` (x_{t-d} - mean) and the
    /// second channel's value `u2` (z_{t-d2}) into `out` (length p).
    #[inline]
    pub fn f2(&self, u1: f64, u2: f64, out: &mut [f64]) {
        self.coef.eval2(u1, u2, out)
    }

    /// Residuals e_t of centred values `y` (x - mean) by the model's recursion on the
    /// lag index (zeros before the series; see the module documentation).
    pub fn residuals(&self, y: &[f64]) -> Vec<f64> {
        let d = self.d();
        self.recursion(y, |t, f| self.f(if t >= d { y[t - d] } else { 0.0 }, f))
    }

    /// Residuals e_t of centred values `y` (x - mean) by the model's recursion on its
    /// 2-D index with the second channel's values `z` (channel units, as long as `y`);
    /// see the module documentation. The fit's own pass (`estimator::fit::grid2::
    /// residuals2`) gives the same values.
    pub fn residuals2(&self, y: &[f64], z: &[f64]) -> Vec<f64> {
        let (d, d2) = (self.d(), self.second().expect("a 2-D index").lag);
        assert_eq!(y.len(), z.len(), "the series and the index channel");
        self.recursion(y, |t, f| {
            let u1 = if t >= d { y[t - d] } else { 0.0 };
            self.f2(u1, z[t.saturating_sub(d2)], f)
        })
    }

    /// The residual recursion with f_1..f_p at t from `f_at(t, out)`.
    fn recursion(&self, y: &[f64], mut f_at: impl FnMut(usize, &mut [f64])) -> Vec<f64> {
        let (p, b) = (self.p(), &self.b);
        let mut f = vec![0.0; p];
        let mut e = vec![0.0; y.len()];
        for t in 0..y.len() {
            f_at(t, &mut f);
            let mut s = y[t];
            for k in 0..p.min(t) {
                s -= f[k] * y[t - k - 1];
            }
            for (k, bk) in b.iter().enumerate() {
                if t > k {
                    s -= bk * e[t - k - 1];
                }
            }
            e[t] = s;
        }
        e
    }

    /// Squared errors of the k-step predictions on the lag index of the last `holdout`
    /// samples of `y` (centred), summed per horizon k = 1..=kmax (index k-1), and
    /// their counts. Every target t of the hold-out is predicted from origin s = t - k,
    /// which may lie before the hold-out (those data are observed, not fitted).
    pub fn kstep(&self, y: &[f64], holdout: usize, kmax: usize) -> (Vec<f64>, Vec<usize>) {
        let n = y.len();
        let (p, d, b) = (self.p(), self.d(), &self.b);
        let lag = p.max(d).max(b.len());
        let e = self.residuals(y);
        let h0 = n - holdout;
        let mut sse = vec![0.0; kmax];
        let mut cnt = vec![0usize; kmax];
        let mut f = vec![0.0; p];
        let mut yt = vec![0.0; lag + kmax];
        let mut et = vec![0.0; lag + kmax];
        for s in h0.saturating_sub(kmax)..n - 1 {
            if s + 1 < lag {
                continue;
            }
            for i in 0..lag {
                yt[i] = y[s + 1 - lag + i];
                et[i] = e[s + 1 - lag + i];
            }
            for j in 1..=kmax {
                let t = s + j;
                if t >= n {
                    break;
                }
                let i = lag + j - 1;
                self.f(yt[i - d], &mut f);
                let mut v = 0.0;
                for k in 0..p {
                    v += f[k] * yt[i - k - 1];
                }
                for (k, bk) in b.iter().enumerate() {
                    v += bk * et[i - k - 1];
                }
                yt[i] = v;
                et[i] = 0.0;
                if t >= h0 {
                    sse[j - 1] += (y[t] - v).powi(2);
                    cnt[j - 1] += 1;
                }
            }
        }
        (sse, cnt)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The recursion by its definition for an AR(1) with one MA term: e_t = y_t -
    /// a y_{t-1} - b e_{t-1}.
    #[test]
    fn residuals_of_a_linear_model() {
        let m = Farma::linear(&[0.5], &[0.25], 0.0, 1.0);
        let y = [1.0, 2.0, -1.0, 0.5];
        let e = m.residuals(&y);
        let mut want = vec![0.0; 4];
        for t in 0..4 {
            want[t] = y[t]
                - if t > 0 { 0.5 * y[t - 1] } else { 0.0 }
                - if t > 0 { 0.25 * want[t - 1] } else { 0.0 };
        }
        assert_eq!(e, want);
    }

    /// One step ahead the prediction error is the residual (innovation) itself.
    #[test]
    fn one_step_errors_are_the_residuals() {
        let m = Farma::linear(&[0.8, -0.1], &[0.3], 0.0, 1.0);
        let y: Vec<f64> = (0..200)
            .map(|t| ((t * 37 % 101) as f64 / 50.0) - 1.0)
            .collect();
        let e = m.residuals(&y);
        let (sse, cnt) = m.kstep(&y, 50, 3);
        let want: f64 = e[150..].iter().map(|v| v * v).sum();
        assert_eq!(cnt[0], 50);
        assert!((sse[0] - want).abs() <= 1e-12 * want);
        assert!(sse[2] > 0.0 && cnt[2] == 50);
    }
}
