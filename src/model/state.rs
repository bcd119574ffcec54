//! The state of a fitted channel that an online update continues from: the normal
//! equations of the batch fit as a value ([`ChannelState`]), with the checks a state
//! read from a file must pass. What it holds and why (Gram form, not P = S^-1) is
//! documented in [`crate::estimator::update`], which builds it from a fit and carries
//! it over new samples; [`super::folder`] writes and reads it (`state.parquet`).

use crate::estimator::linalg::spd_solve_inverse;

/// Version of the state file layout (file metadata `farma_state_version`).
pub const STATE_VERSION: &str = "1";

/// The time of the last sample the state has seen (column `t_last_s` of the state
/// file): what `farma update` checks a new log against, so that it continues the
/// fitted series in time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LastTime {
    /// The state file has no `t_last_s` column (written before it): not known.
    NotRecorded,
    /// The log had no time column (its rate came from metadata or --rate): a null.
    NoTimeColumn,
    /// Seconds, from the log's time column.
    At(f64),
}

/// What recursive least squares needs to continue a fitted channel.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelState {
    pub channel: String,
    pub p: usize,
    pub q: usize,
    pub d: usize,
    /// Mean removed at fit time (new samples are centred with it).
    pub mean: f64,
    pub bandwidth: f64,
    /// Grid points, centred units (add `mean` for channel units).
    pub grid: Vec<f64>,
    /// G x (2p)^2, row-major per point: S_g.
    pub gram: Vec<f64>,
    /// G x 2p x (1+q), row-major per point: C_g.
    pub cross: Vec<f64>,
    /// G x (2p)^2: S2_g = sum K^2 z z'.
    pub gram2: Vec<f64>,
    /// sum of kernel weights per point (discounted with the forgetting factor).
    pub kernel_mass: Vec<f64>,
    /// Samples inside each support (not discounted).
    pub n_support: Vec<u64>,
    pub b: Vec<f64>,
    /// q x q.
    pub b_gram: Vec<f64>,
    pub b_rhs: Vec<f64>,
    /// The last max(p,q,d) centred samples, oldest first.
    pub x_tail: Vec<f64>,
    /// The last max(p,q,d) residuals, oldest first.
    pub e_tail: Vec<f64>,
    /// Samples seen (fit plus updates).
    pub n: u64,
    /// Residual sum of squares (discounted).
    pub rss: f64,
    /// Rows behind the RSS (discounted); sigma^2 = rss / rows.
    pub rows: f64,
    /// The forgetting factor of the last update (1 after a fit).
    pub forgetting: f64,
    /// The fit returned its linear ARMA start ([`FitReport::linear_start`](crate::model::FitReport::linear_start)): the
    /// sums above are of the local fits it rejected, so [`update`](crate::estimator::update::update) refuses the channel.
    /// Column `linear_start` of the state file (absent in files written before it:
    /// false).
    pub linear_start: bool,
    /// The time of the last sample seen (fit plus updates); [`state_from_fit`](crate::estimator::update::state_from_fit) and
    /// [`update`](crate::estimator::update::update) leave it as [`LastTime::NoTimeColumn`] and as it was, the caller
    /// sets it from the log's time column.
    pub t_last: LastTime,
}

/// The most samples a state's `n` may count: f64's exact integers (rows, sigma2 and
/// the tables take n as f64). A larger n (an edited state) is refused: the update's
/// count would wrap around (a panic in a debug build) and be blamed on the new samples.
pub const MAX_STATE_N: u64 = 1 << 53;

impl ChannelState {
    pub fn n_grid(&self) -> usize {
        self.grid.len()
    }

    /// max(p, q, d): the samples and residuals the state carries.
    pub fn lag(&self) -> usize {
        self.p.max(self.q).max(self.d)
    }

    /// The local right-hand side C_g (1, -b_1, ..., -b_q)' of grid point g for MA
    /// coefficients `b`.
    pub fn right_hand_side(&self, g: usize, b: &[f64]) -> Vec<f64> {
        let n = 2 * self.p;
        let nc = 1 + self.q;
        let c = &self.cross[g * n * nc..(g + 1) * n * nc];
        (0..n)
            .map(|i| {
                let mut v = c[i * nc];
                for (m, bm) in b.iter().enumerate() {
                    v -= bm * c[i * nc + 1 + m];
                }
                v
            })
            .collect()
    }

    /// An error unless b is invertible (every root of 1 + b_1 z + ... + b_q z^q
    /// outside the unit circle). An update can leave another b (it says so in a note),
    /// and so can an edited file; continuing from it would make the residuals of the
    /// new samples grow without bound. Not part of [`ChannelState::check`], which also
    /// checks an update's own result before it is written with that note.
    pub fn check_invertible(&self) -> std::result::Result<(), String> {
        match crate::estimator::arma::not_invertible(&self.b) {
            None => Ok(()),
            Some(what) => Err(format!(
                "field 'b': {what} (an update that leaves one says so in a note): the residuals of new samples would grow without bound; refit the channel (farma fit --save-state)"
            )),
        }
    }

    /// An error unless the state's normal equations can start the recursions: some
    /// grid point with at least 2p samples whose local system (its `gram` block) is
    /// solvable, and for q > 0 a solvable `b_gram`. A fitted state always has both (its
    /// fit had a local fit somewhere and the MA part's normal equations); an edited or
    /// corrupt file may not, and that is the state's fault, not the new samples': the
    /// message names the field. Call after [`ChannelState::check`] (it relies on the
    /// shapes). A state whose fit returned its linear start passes: [`update`](crate::estimator::update::update) refuses
    /// it with a message of its own.
    pub fn check_solvable(&self) -> std::result::Result<(), String> {
        if self.linear_start {
            return Ok(());
        }
        let n = 2 * self.p;
        let zero = vec![0.0; n];
        let solvable = (0..self.n_grid()).any(|g| {
            self.n_support[g] as usize >= n
                && spd_solve_inverse(&self.gram[g * n * n..(g + 1) * n * n], &zero, n).is_some()
        });
        if !solvable {
            return Err(format!(
                "field 'gram': no grid point has a solvable local system (every block is singular, or its 'n_support' is below 2p = {n}): the state cannot start the recursion; refit the channel (farma fit --save-state)"
            ));
        }
        if self.q > 0 && spd_solve_inverse(&self.b_gram, &self.b_rhs, self.q).is_none() {
            return Err(
                "field 'b_gram': the MA part's normal equations are singular: the state cannot start the recursion for b; refit the channel (farma fit --save-state)".into(),
            );
        }
        Ok(())
    }

    /// Checks the shapes, that every number is finite and that the values are possible
    /// for a fitted (or updated) channel (a state read from a file may be corrupt or
    /// edited). The message names the field and what is wrong.
    pub fn check(&self) -> std::result::Result<(), String> {
        let (p, q, g) = (self.p, self.q, self.grid.len());
        let lag = self.lag();
        let bad = |what: &str| {
            Err(format!(
                "{what} has the wrong length for p = {p}, q = {q}, G = {g}"
            ))
        };
        if let LastTime::At(t) = self.t_last
            && !t.is_finite()
        {
            return Err(format!("field 't_last_s': {t} is not a finite time"));
        }
        if p == 0 || self.d == 0 || g < 2 {
            return Err(format!(
                "p = {p}, d = {}, G = {g}: not a fitted model",
                self.d
            ));
        }
        // sizes with checked arithmetic: a corrupt p or q must not overflow
        let n = p.checked_mul(2);
        let nn = n
            .and_then(|n| n.checked_mul(n))
            .and_then(|v| v.checked_mul(g));
        let nc = n
            .zip(q.checked_add(1))
            .and_then(|(n, c)| n.checked_mul(c))
            .and_then(|v| v.checked_mul(g));
        let qq = q.checked_mul(q);
        let (Some(nn), Some(nc), Some(qq)) = (nn, nc, qq) else {
            return Err(format!("p = {p}, q = {q}: impossible model order"));
        };
        if self.gram.len() != nn || self.gram2.len() != nn {
            return bad("gram");
        }
        if self.cross.len() != nc {
            return bad("cross");
        }
        if self.kernel_mass.len() != g || self.n_support.len() != g {
            return bad("kernel_mass / n_support");
        }
        if self.b.len() != q || self.b_gram.len() != qq || self.b_rhs.len() != q {
            return bad("b / b_gram / b_rhs");
        }
        if self.x_tail.len() != lag || self.e_tail.len() != lag {
            return bad("x_tail / e_tail");
        }
        let scalars = [
            ("mean", self.mean),
            ("bandwidth", self.bandwidth),
            ("rss", self.rss),
            ("rows", self.rows),
            ("forgetting", self.forgetting),
        ];
        for (name, v) in scalars {
            if !v.is_finite() {
                return Err(format!("field '{name}' is {v}, not a finite number"));
            }
        }
        let lists: [(&str, &[f64]); 10] = [
            ("grid", &self.grid),
            ("gram", &self.gram),
            ("cross", &self.cross),
            ("gram2", &self.gram2),
            ("kernel_mass", &self.kernel_mass),
            ("b", &self.b),
            ("b_gram", &self.b_gram),
            ("b_rhs", &self.b_rhs),
            ("x_tail", &self.x_tail),
            ("e_tail", &self.e_tail),
        ];
        for (name, v) in lists {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(format!(
                    "field '{name}' holds {} at index {i} (of {}), not a finite number",
                    v[i],
                    v.len()
                ));
            }
        }
        if self.bandwidth <= 0.0 {
            return Err(format!(
                "field 'bandwidth' is {}, not positive",
                self.bandwidth
            ));
        }
        if !self.grid.windows(2).all(|w| w[0] < w[1]) {
            return Err("field 'grid' is not strictly increasing".into());
        }
        let (lo, hi) = (self.grid[0] + self.mean, self.grid[g - 1] + self.mean);
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            return Err(format!(
                "field 'mean' = {:e} does not fit the grid [{:e}, {:e}] (centred units): the grid points coincide or overflow in channel units",
                self.mean,
                self.grid[0],
                self.grid[g - 1]
            ));
        }
        if !(self.forgetting > 0.0 && self.forgetting <= 1.0) {
            return Err(format!(
                "field 'forgetting' is {}, not in (0, 1]",
                self.forgetting
            ));
        }
        if self.n <= lag as u64 {
            return Err(format!(
                "field 'n' is {}: a fitted channel has more than max(p, q, d) = {lag} samples (the length of x_tail / e_tail)",
                self.n
            ));
        }
        if self.n > MAX_STATE_N {
            return Err(format!(
                "field 'n' is {}: more samples than any fit or update counts (at most 2^53)",
                self.n
            ));
        }
        let n_rows = self.n - lag as u64;
        if self.rss < 0.0 {
            return Err(format!("field 'rss' is {}, negative", self.rss));
        }
        // rows = N - lag after a fit, discounted (never above N - lag) by updates
        if !(self.rows > 0.0 && self.rows <= n_rows as f64 * (1.0 + 1e-12)) {
            return Err(format!(
                "field 'rows' is {}, not in (0, n - max(p, q, d) = {n_rows}]",
                self.rows
            ));
        }
        if let Some(i) = self.n_support.iter().position(|c| *c > n_rows) {
            return Err(format!(
                "field 'n_support' is {} at grid point {i}, above the {n_rows} rows of n = {}",
                self.n_support[i], self.n
            ));
        }
        // Biweight weights lie in [0, 15/16]: 0 <= kernel mass <= samples in the support
        if let Some(i) = (0..g).find(|i| {
            let m = self.kernel_mass[*i];
            !(m >= 0.0 && m <= self.n_support[*i] as f64 * (1.0 + 1e-9))
        }) {
            return Err(format!(
                "field 'kernel_mass' is {} at grid point {i}, not in [0, n_support = {}]",
                self.kernel_mass[i], self.n_support[i]
            ));
        }
        let n = 2 * p;
        let diag = |name: &str, v: &[f64], k: usize| -> std::result::Result<(), String> {
            for (blk, m) in v.chunks(k * k).enumerate() {
                if let Some(i) = (0..k).find(|i| m[i * k + i] < 0.0) {
                    return Err(format!(
                        "field '{name}' has the negative diagonal entry {} (block {blk}, row {i}): not a Gram matrix",
                        m[i * k + i]
                    ));
                }
            }
            Ok(())
        };
        diag("gram", &self.gram, n)?;
        diag("gram2", &self.gram2, n)?;
        if q > 0 {
            diag("b_gram", &self.b_gram, q)?;
        }
        Ok(())
    }
}
