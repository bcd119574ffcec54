//! The coefficient functions f_1..f_p of a FARMA model on the lag index u = x_{t-d}:
//! their values at the grid points with pointwise standard errors, and the one
//! interpolation every verb evaluates them with.
//!
//! Between grid points f_m is linear, beyond the ends constant:
//! f_m(u) = f_m(u_k) + lambda (f_m(u_{k+1}) - f_m(u_k)), lambda = (u - u_k)/(u_{k+1} - u_k)
//! for u_k <= u < u_{k+1}, f_m(u_1) for u <= u_1, f_m(u_G) for u >= u_G. The
//! estimator's residual recursion and RSS are exact for this evaluation
//! (`estimator::direct::rss_trace`).

/// f_1..f_p at the grid points of the lag index.
#[derive(Clone, Debug, PartialEq)]
pub struct Coef {
    /// Ascending grid points u_1..u_G, in the units given by `grid_shift`.
    pub grid: Vec<f64>,
    /// Added to a centred index value (x_{t-d} minus the model's mean) before it is
    /// located on the grid: 0 for a fresh fit, whose grid is centred; the mean for a
    /// model read from its folder, whose grid keeps the channel units coef.parquet
    /// stores (so f is evaluated at exactly the values written).
    pub grid_shift: f64,
    /// f_m(u_g), row-major G x p: `f[g * p + m - 1]`.
    pub f: Vec<f64>,
    /// Pointwise standard error of f_m(u_g), G x p (NaN at filled points).
    pub se: Vec<f64>,
    /// Grid points whose f was filled from their neighbours (no local fit there).
    pub filled: Vec<bool>,
}

impl Coef {
    /// Constant f_m = `a[m-1]` (a linear ARMA's AR coefficients): one grid point.
    pub fn constant(a: &[f64]) -> Coef {
        Coef {
            grid: vec![0.0],
            grid_shift: 0.0,
            f: a.to_vec(),
            se: vec![f64::NAN; a.len()],
            filled: vec![false],
        }
    }

    /// p, the number of coefficient functions.
    pub fn p(&self) -> usize {
        self.f.len() / self.grid.len()
    }

    /// Grid points G.
    pub fn n_grid(&self) -> usize {
        self.grid.len()
    }

    /// f_m at grid point g (m from 1).
    pub fn at(&self, g: usize, m: usize) -> f64 {
        self.f[g * self.p() + m - 1]
    }

    /// The grid point g as a centred index value (x - mean).
    pub fn centred_grid(&self, g: usize) -> f64 {
        self.grid[g] - self.grid_shift
    }

    /// f_1..f_p at the centred index value `u` (x_{t-d} minus the model's mean) into
    /// `out` (length p); see the module documentation.
    #[inline]
    pub fn eval(&self, u: f64, out: &mut [f64]) {
        interp_rows(&self.grid, &self.f, u + self.grid_shift, out)
    }
}

/// Linear interpolation of the rows of `f` (G x p, row-major, p = `out.len()`) over the
/// ascending `grid` at `u`, constant beyond the ends.
#[inline]
pub fn interp_rows(grid: &[f64], f: &[f64], u: f64, out: &mut [f64]) {
    let p = out.len();
    let g = grid.len();
    if u <= grid[0] {
        out.copy_from_slice(&f[..p]);
    } else if u >= grid[g - 1] {
        out.copy_from_slice(&f[(g - 1) * p..g * p]);
    } else {
        let k = grid.partition_point(|v| *v <= u) - 1;
        let lam = (u - grid[k]) / (grid[k + 1] - grid[k]);
        for m in 0..p {
            let a = f[k * p + m];
            out[m] = a + lam * (f[(k + 1) * p + m] - a);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_and_holds_the_ends() {
        let c = Coef {
            grid: vec![-1.0, 0.0, 2.0],
            grid_shift: 0.0,
            f: vec![1.0, 10.0, 3.0, 30.0, 7.0, 70.0],
            se: vec![0.0; 6],
            filled: vec![false; 3],
        };
        let mut out = [0.0; 2];
        c.eval(-5.0, &mut out);
        assert_eq!(out, [1.0, 10.0]);
        c.eval(1.0, &mut out);
        assert_eq!(out, [5.0, 50.0]);
        c.eval(9.0, &mut out);
        assert_eq!(out, [7.0, 70.0]);
        c.eval(-0.5, &mut out);
        assert_eq!(out, [2.0, 20.0]);
        // the same model with its grid in channel units (mean 10)
        let s = Coef {
            grid: vec![9.0, 10.0, 12.0],
            grid_shift: 10.0,
            ..c.clone()
        };
        s.eval(1.0, &mut out);
        assert_eq!(out, [5.0, 50.0]);
        assert_eq!(s.centred_grid(2), 2.0);
        assert_eq!(c.p(), 2);
        assert_eq!(c.at(1, 2), 30.0);
        let k = Coef::constant(&[0.5, -0.25]);
        k.eval(123.0, &mut out);
        assert_eq!(out, [0.5, -0.25]);
    }
}
