//! The coefficient functions f_1..f_p of a FARMA model on their grid, with pointwise
//! standard errors, and the one interpolation every verb evaluates them with. The
//! index is the lag x_{t-d} (a 1-D grid) or the pair (x_{t-d}, z_{t-d2}) with another
//! channel z of the log (a 2-D grid: the lag's axis and [`SecondIndex`]).
//!
//! On the lag index f_m is linear between grid points and constant beyond the ends:
//! f_m(u) = f_m(u_k) + lambda (f_m(u_{k+1}) - f_m(u_k)), lambda = (u - u_k)/(u_{k+1} - u_k)
//! for u_k <= u < u_{k+1}, f_m(u_1) for u <= u_1, f_m(u_G) for u >= u_G.
//!
//! On a 2-D grid f_m is bilinear in each cell and constant beyond the grid in each
//! coordinate: with (lambda_1, lambda_2) the weights of the right neighbours on each
//! axis as above (0 beyond an end), f_m(u) = sum over the cell's four corners c of
//! w_c f_m(c), w = (1 - lambda_1)(1 - lambda_2), lambda_1 (1 - lambda_2),
//! (1 - lambda_1) lambda_2, lambda_1 lambda_2, summed in that order, corners of zero
//! weight left out. Grid point g = i G2 + j is (grid\[i\], second.grid\[j\]); a 1-D
//! grid is the case G2 = 1.
//!
//! The estimators' residual recursions and RSS are exact for these evaluations
//! (`estimator::direct::rss_trace`, `estimator::fit::grid2::rss_trace2`), which call
//! [`interp_rows`] and [`bilinear_corners`].

/// The second coordinate of a 2-D index: channel z of the log at delay d2,
/// z_{t-d2} (z_0 before the first sample), with its grid axis and bandwidth.
#[derive(Clone, Debug, PartialEq)]
pub struct SecondIndex {
    /// The channel z.
    pub channel: String,
    /// Its delay d2.
    pub lag: usize,
    /// Ascending grid points of the second axis, in z's units.
    pub grid: Vec<f64>,
    /// Bandwidth h_2 of the local fits along this axis (z's units).
    pub bandwidth: f64,
}

/// f_1..f_p at the grid points of the model's index.
#[derive(Clone, Debug, PartialEq)]
pub struct Coef {
    /// Ascending grid points u_1..u_G of the lag's axis, in the units given by
    /// `grid_shift`.
    pub grid: Vec<f64>,
    /// Added to a centred index value (x_{t-d} minus the model's mean) before it is
    /// located on the grid: 0 for a fresh fit, whose grid is centred; the mean for a
    /// model read from its folder, whose grid keeps the channel units coef.parquet
    /// stores (so f is evaluated at exactly the values written).
    pub grid_shift: f64,
    /// f_m(u_g), row-major G x p: `f[g * p + m - 1]` (G = G1 G2 on a 2-D grid).
    pub f: Vec<f64>,
    /// Pointwise standard error of f_m(u_g), G x p (NaN at filled points).
    pub se: Vec<f64>,
    /// Grid points whose f was filled from their neighbours (no local fit there).
    pub filled: Vec<bool>,
    /// The second coordinate of a 2-D index; None on the lag index.
    pub second: Option<SecondIndex>,
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
            second: None,
        }
    }

    /// p, the number of coefficient functions.
    pub fn p(&self) -> usize {
        self.f.len() / self.n_grid()
    }

    /// Points G2 on the second axis (1 on the lag index).
    fn n2(&self) -> usize {
        self.second.as_ref().map_or(1, |s| s.grid.len())
    }

    /// Grid points G (G1 G2 on a 2-D grid).
    pub fn n_grid(&self) -> usize {
        self.grid.len() * self.n2()
    }

    /// f_m at grid point g (m from 1).
    pub fn at(&self, g: usize, m: usize) -> f64 {
        self.f[g * self.p() + m - 1]
    }

    /// The lag coordinate of grid point g as a centred index value (x - mean).
    pub fn centred_grid(&self, g: usize) -> f64 {
        self.grid[g / self.n2()] - self.grid_shift
    }

    /// The second coordinate of grid point g (z's units; None on the lag index).
    pub fn second_grid(&self, g: usize) -> Option<f64> {
        let s = self.second.as_ref()?;
        Some(s.grid[g % s.grid.len()])
    }

    /// f_1..f_p on the lag index at the centred index value `u` (x_{t-d} minus the
    /// model's mean) into `out` (length p); see the module documentation.
    #[inline]
    pub fn eval(&self, u: f64, out: &mut [f64]) {
        debug_assert!(self.second.is_none(), "a 2-D index: Coef::eval2");
        interp_rows(&self.grid, &self.f, u + self.grid_shift, out)
    }

    /// f_1..f_p on a 2-D index at (`u1`, `u2`): `u1` the centred lag value (x_{t-d}
    /// minus the model's mean), `u2` the second channel's value z_{t-d2}, into `out`
    /// (length p); see the module documentation.
    #[inline]
    pub fn eval2(&self, u1: f64, u2: f64, out: &mut [f64]) {
        let second = self.second.as_ref().expect("a 2-D index");
        interp_rows2(
            &self.grid,
            &second.grid,
            &self.f,
            u1 + self.grid_shift,
            u2,
            out,
        )
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

/// Cell of `u` on an ascending axis: (left, right, weight of right); constant beyond
/// the ends (weight 0 there).
#[inline]
fn axis(g: &[f64], u: f64) -> (usize, usize, f64) {
    let n = g.len();
    if u <= g[0] {
        (0, 0, 0.0)
    } else if u >= g[n - 1] {
        (n - 1, n - 1, 0.0)
    } else {
        let k = g.partition_point(|v| *v <= u) - 1;
        (k, k + 1, (u - g[k]) / (g[k + 1] - g[k]))
    }
}

/// The grid points (g = i G2 + j over ascending axes `g1`, `g2`) whose bilinear weights
/// at (u1, u2) may be non-zero, with the weights (constant beyond the grid in each
/// coordinate), in the order the module documentation sums them.
#[inline]
pub fn bilinear_corners(g1: &[f64], g2: &[f64], u1: f64, u2: f64) -> [(usize, f64); 4] {
    let (i0, i1, a) = axis(g1, u1);
    let (j0, j1, c) = axis(g2, u2);
    let n2 = g2.len();
    [
        (i0 * n2 + j0, (1.0 - a) * (1.0 - c)),
        (i1 * n2 + j0, a * (1.0 - c)),
        (i0 * n2 + j1, (1.0 - a) * c),
        (i1 * n2 + j1, a * c),
    ]
}

/// Bilinear interpolation of the rows of `f` (G1 G2 x p, row-major, p = `out.len()`)
/// over the grid of axes `g1`, `g2` at (u1, u2) ([`bilinear_corners`]).
#[inline]
pub fn interp_rows2(g1: &[f64], g2: &[f64], f: &[f64], u1: f64, u2: f64, out: &mut [f64]) {
    let p = out.len();
    out.iter_mut().for_each(|v| *v = 0.0);
    for (g, w) in bilinear_corners(g1, g2, u1, u2) {
        if w != 0.0 {
            for m in 0..p {
                out[m] += w * f[g * p + m];
            }
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
            second: None,
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

    /// Bilinear in the cell, constant beyond the grid in each coordinate, and the lag
    /// coordinate shifted as on the lag index.
    #[test]
    fn a_2d_grid_interpolates_bilinearly_and_holds_the_ends() {
        // f_1 = u1 + 10 u2, f_2 = -u1 at the points of axes (0, 1) x (0, 2)
        let (g1, g2) = (vec![0.0, 1.0], vec![0.0, 2.0]);
        let mut f = vec![];
        for a in &g1 {
            for b in &g2 {
                f.extend([a + 10.0 * b, -a]);
            }
        }
        let c = Coef {
            grid: g1.iter().map(|v| v + 5.0).collect(),
            grid_shift: 5.0,
            f,
            se: vec![f64::NAN; 8],
            filled: vec![false; 4],
            second: Some(SecondIndex {
                channel: "temp_c".into(),
                lag: 1,
                grid: g2,
                bandwidth: 1.0,
            }),
        };
        assert_eq!((c.p(), c.n_grid()), (2, 4));
        assert_eq!((c.centred_grid(3), c.second_grid(3)), (1.0, Some(2.0)));
        let mut out = [0.0; 2];
        c.eval2(0.5, 1.0, &mut out);
        assert_eq!(out, [10.5, -0.5]);
        c.eval2(-3.0, 9.0, &mut out);
        assert_eq!(out, [20.0, 0.0]);
        c.eval2(0.25, -1.0, &mut out);
        assert_eq!(out, [0.25, -0.25]);
    }
}
