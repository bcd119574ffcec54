//! The statistics that localise a sim-to-real gap: one vector of features per series,
//! computed on one part (training or withheld blocks) of a log.
//!
//! Every feature is computed inside blocks (never across a block boundary) and belongs
//! to one statistic family of contracts.md section 3:
//! - `adev`: ln of the overlapping Allan variance at octave averaging factors
//!   m = 1, 2, 4, ... up to a quarter of the longest block, pooled over the blocks at
//!   least 4m long as sum_b (N_b - 2m + 1) AVAR_b(m) / sum_b (N_b - 2m + 1) (each
//!   AVAR_b from [`crate::stats::adev::deviations`], SP 1065 eq. (10)): the short
//!   pieces at the start of a log count at short averaging times only;
//! - `psd`: ln of the mean Welch PSD over the segments that fit in a block (segments of
//!   up to an eighth of the longest block; Hann window, 50 % overlap, one-sided, u^2/Hz;
//!   P. D. Welch, IEEE Trans. Audio Electroacoust. 15 (1967) 70-73) in log-spaced bands,
//!   five per decade, from the lowest resolved frequency to Nyquist;
//! - `time`: mean and ln variance in windows of a quarter block, in time order;
//! - `distribution`: of the first differences d_t = x_t - x_{t-1} (which remove the
//!   slow drift): ln standard deviation, ln kurtosis, ln of the 0.999 and 0.9999
//!   quantiles of |d| over its median (tails: outliers), and ln of the share of
//!   distinct values of x, the values in one cell of a grid of 1e-9 of the largest
//!   magnitude counted once (discreteness: quantization);
//! - `temperature` (with a temperature channel): least-squares coefficients of x on
//!   (1, T - Tm, (T - Tm)^2, dT/dt), the mean of x in five temperature bins and in five
//!   dT/dt bins (bin edges: quintiles of the real temperature over the part, the same
//!   for every series), and ln variance of d in the five temperature bins;
//! - `state`: state-dependent dynamics: the least-squares slope of x_t on x_{t-1} in
//!   the five quintile bins of x_{t-1}, values within 1e-9 of the largest magnitude of
//!   an edge counted at the edge (a linear model has one slope; a FARMA model's
//!   f_1(x_{t-1}) shows as slopes that vary across bins);
//! - `cross_axis` (with other channels): correlation of the differences and of the
//!   window means of x with each other channel.
//!
//! Log-scale features compare as ratios, the others as differences; both are scored
//! by [`super::distance`] against the spread of a simulation ensemble.

use std::ops::Range;

use realfft::RealFftPlanner;
use serde::Serialize;

use super::blocks::Blocks;
use crate::stats::adev;

/// A statistic family: the `statistic` of a region in contracts.md section 3.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Statistic {
    Adev,
    Psd,
    Time,
    Distribution,
    Temperature,
    State,
    CrossAxis,
}

impl Statistic {
    pub fn as_str(self) -> &'static str {
        match self {
            Statistic::Adev => "adev",
            Statistic::Psd => "psd",
            Statistic::Time => "time",
            Statistic::Distribution => "distribution",
            Statistic::Temperature => "temperature",
            Statistic::State => "state",
            Statistic::CrossAxis => "cross_axis",
        }
    }
}

/// What one feature measures, and where it sits (its `lo`..`hi` in `unit`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FeatureDef {
    pub statistic: Statistic,
    /// What is measured: `ln_avar`, `ln_psd`, `mean`, `ln_var`, `ln_sd_diff`, ...
    pub name: String,
    pub lo: f64,
    pub hi: f64,
    pub unit: String,
    /// Natural logarithm of a positive quantity (compared as a ratio).
    pub log_scale: bool,
    /// The fold whose withheld part the feature is computed on: 1 for the blocks of
    /// [`Blocks::part`]`(false)`, 2 for those of `part(true)` (fold 2 trains on fold
    /// 1's withheld part and the reverse).
    pub fold: u8,
}

/// The temperature of the log as the features use it (the same for the real log and
/// every simulation: the simulator is driven by the real temperature).
#[derive(Clone, Debug)]
pub struct Temperature {
    /// degC, one per sample.
    pub t_c: Vec<f64>,
    /// dT/dt in degC/s, a central difference over `DTDT_HALF_WINDOW_S` on each side.
    pub dtdt_c_per_s: Vec<f64>,
}

/// Half-width of the central difference behind dT/dt, seconds.
pub const DTDT_HALF_WINDOW_S: f64 = 30.0;

impl Temperature {
    /// Temperature `t_c` sampled at `rate_hz`, with its smoothed rate of change.
    pub fn new(t_c: Vec<f64>, rate_hz: f64) -> Temperature {
        let n = t_c.len();
        let w = ((DTDT_HALF_WINDOW_S * rate_hz).round() as usize).max(1);
        let dtdt = (0..n)
            .map(|i| {
                let a = i.saturating_sub(w);
                let b = (i + w).min(n - 1);
                if b > a {
                    (t_c[b] - t_c[a]) * rate_hz / (b - a) as f64
                } else {
                    0.0
                }
            })
            .collect();
        Temperature {
            t_c,
            dtdt_c_per_s: dtdt,
        }
    }
}

/// The fixed layout of the features of one part of a log.
#[derive(Clone, Debug)]
pub struct Layout {
    pub defs: Vec<FeatureDef>,
    ranges: Vec<Range<usize>>,
    ms: Vec<usize>,
    seg_len: usize,
    bands: Vec<Range<usize>>,
    windows: Vec<Range<usize>>,
    temp: Option<TempLayout>,
    n_other: usize,
    /// The distribution family holds `ln_distinct_share` (not in a diagnosis of a log
    /// averaged over blocks, [`Layout::without_distinct`]).
    distinct: bool,
}

#[derive(Clone, Debug)]
struct TempLayout {
    t_mean: f64,
    /// The normal matrix of the regressors (1, T - Tm, (T - Tm)^2, dT/dt) over the
    /// part, row-major: the same for every series.
    ata: [f64; 16],
    /// Per sample of the part (blocks in order): its temperature bin and its dT/dt bin.
    bins: Vec<(u8, u8)>,
}

const N_BINS: usize = 5;
const WINDOWS_PER_BLOCK: usize = 4;
const BANDS_PER_DECADE: f64 = 5.0;

fn quantile_edges(mut v: Vec<f64>) -> Vec<f64> {
    v.sort_by(f64::total_cmp);
    (1..N_BINS)
        .map(|k| v[(k * (v.len() - 1)) / N_BINS])
        .collect()
}

fn bin_of(edges: &[f64], v: f64) -> usize {
    edges.partition_point(|e| *e < v)
}

impl Layout {
    /// The layout for the training (`training = true`) or withheld part of `blocks`, at
    /// `rate_hz`, with the log's temperature and `others` (names of the other channels
    /// compared for cross-axis coupling).
    pub fn new(
        blocks: &Blocks,
        training: bool,
        rate_hz: f64,
        temperature: Option<&Temperature>,
        others: &[String],
    ) -> Layout {
        let ranges = blocks.part(training);
        let fold = if training { 2 } else { 1 };
        let max_len = ranges.iter().map(|r| r.len()).max().unwrap_or(0);
        let mut defs = Vec::new();
        let dt = 1.0 / rate_hz;

        let mut ms = Vec::new();
        let mut m = 1;
        while 4 * m <= max_len {
            ms.push(m);
            m *= 2;
        }
        for &m in &ms {
            let tau = m as f64 * dt;
            defs.push(FeatureDef {
                statistic: Statistic::Adev,
                name: "ln_avar".into(),
                lo: tau,
                hi: tau,
                unit: "s".into(),
                log_scale: true,
                fold,
            });
        }

        let mut seg_len = 64;
        while seg_len * 2 * 4 <= max_len {
            seg_len *= 2;
        }
        let df = rate_hz / seg_len as f64;
        let n_bins = seg_len / 2; // bins 1..=n_bins (0 is the mean)
        let mut bands = Vec::new();
        let mut lo = 1usize;
        while lo <= n_bins {
            let hi_f = (lo as f64 * 10f64.powf(1.0 / BANDS_PER_DECADE)).ceil() as usize;
            let hi = hi_f.max(lo + 1).min(n_bins + 1);
            bands.push(lo..hi);
            lo = hi;
        }
        for b in &bands {
            defs.push(FeatureDef {
                statistic: Statistic::Psd,
                name: "ln_psd".into(),
                lo: b.start as f64 * df,
                hi: (b.end - 1) as f64 * df,
                unit: "Hz".into(),
                log_scale: true,
                fold,
            });
        }

        let mut windows = Vec::new();
        for r in &ranges {
            for k in 0..WINDOWS_PER_BLOCK {
                let a = r.start + k * r.len() / WINDOWS_PER_BLOCK;
                let b = r.start + (k + 1) * r.len() / WINDOWS_PER_BLOCK;
                windows.push(a..b);
            }
        }
        for (name, log_scale) in [("mean", false), ("ln_var", true)] {
            for w in &windows {
                defs.push(FeatureDef {
                    statistic: Statistic::Time,
                    name: name.into(),
                    lo: w.start as f64 * dt,
                    hi: w.end as f64 * dt,
                    unit: "s".into(),
                    log_scale,
                    fold,
                });
            }
        }

        for name in [
            "ln_sd_diff",
            "ln_kurtosis_diff",
            "ln_q999_over_median_abs_diff",
            "ln_q9999_over_median_abs_diff",
            "ln_distinct_share",
        ] {
            defs.push(FeatureDef {
                statistic: Statistic::Distribution,
                name: name.into(),
                lo: f64::NAN,
                hi: f64::NAN,
                unit: "u".into(),
                log_scale: true,
                fold,
            });
        }

        let temp = temperature.map(|tp| {
            let t: Vec<f64> = ranges
                .iter()
                .flat_map(|r| tp.t_c[r.clone()].iter().copied())
                .collect();
            let rr: Vec<f64> = ranges
                .iter()
                .flat_map(|r| tp.dtdt_c_per_s[r.clone()].iter().copied())
                .collect();
            let t_mean = t.iter().sum::<f64>() / t.len() as f64;
            let (tmin, tmax) = t
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                    (a.min(*v), b.max(*v))
                });
            let (rmin, rmax) = rr
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                    (a.min(*v), b.max(*v))
                });
            let t_edges = quantile_edges(t);
            let r_edges = quantile_edges(rr);
            for (name, unit) in [
                ("coef_t", "degC"),
                ("coef_t2", "degC"),
                ("coef_dtdt", "degC/s"),
            ] {
                let (lo, hi) = if unit == "degC" {
                    (tmin, tmax)
                } else {
                    (rmin, rmax)
                };
                defs.push(FeatureDef {
                    statistic: Statistic::Temperature,
                    name: name.into(),
                    lo,
                    hi,
                    unit: unit.into(),
                    log_scale: false,
                    fold,
                });
            }
            let bins = |edges: &[f64], min: f64, max: f64| -> Vec<(f64, f64)> {
                (0..N_BINS)
                    .map(|k| {
                        (
                            if k == 0 { min } else { edges[k - 1] },
                            if k == N_BINS - 1 { max } else { edges[k] },
                        )
                    })
                    .collect()
            };
            for (lo, hi) in bins(&t_edges, tmin, tmax) {
                defs.push(FeatureDef {
                    statistic: Statistic::Temperature,
                    name: "mean_by_t".into(),
                    lo,
                    hi,
                    unit: "degC".into(),
                    log_scale: false,
                    fold,
                });
            }
            for (lo, hi) in bins(&r_edges, rmin, rmax) {
                defs.push(FeatureDef {
                    statistic: Statistic::Temperature,
                    name: "mean_by_dtdt".into(),
                    lo,
                    hi,
                    unit: "degC/s".into(),
                    log_scale: false,
                    fold,
                });
            }
            for (lo, hi) in bins(&t_edges, tmin, tmax) {
                defs.push(FeatureDef {
                    statistic: Statistic::Temperature,
                    name: "ln_var_diff_by_t".into(),
                    lo,
                    hi,
                    unit: "degC".into(),
                    log_scale: true,
                    fold,
                });
            }
            let mut ata = [0.0; 16];
            let mut bins = Vec::with_capacity(ranges.iter().map(|r| r.len()).sum());
            for r in &ranges {
                for i in r.clone() {
                    let dtc = tp.t_c[i] - t_mean;
                    let row = [1.0, dtc, dtc * dtc, tp.dtdt_c_per_s[i]];
                    for a in 0..4 {
                        for b in 0..4 {
                            ata[a * 4 + b] += row[a] * row[b];
                        }
                    }
                    bins.push((
                        bin_of(&t_edges, tp.t_c[i]) as u8,
                        bin_of(&r_edges, tp.dtdt_c_per_s[i]) as u8,
                    ));
                }
            }
            TempLayout { t_mean, ata, bins }
        });

        for k in 0..N_BINS {
            defs.push(FeatureDef {
                statistic: Statistic::State,
                name: "lag1_slope_by_state".into(),
                lo: k as f64 / N_BINS as f64,
                hi: (k + 1) as f64 / N_BINS as f64,
                unit: "quantile".into(),
                log_scale: false,
                fold,
            });
        }

        for (j, name) in others.iter().enumerate() {
            for what in ["corr_diff", "corr_window_mean"] {
                defs.push(FeatureDef {
                    statistic: Statistic::CrossAxis,
                    name: format!("{what}:{name}"),
                    lo: j as f64,
                    hi: j as f64,
                    unit: "channel".into(),
                    log_scale: false,
                    fold,
                });
            }
        }

        Layout {
            defs,
            ranges,
            ms,
            seg_len,
            bands,
            windows,
            temp,
            n_other: others.len(),
            distinct: true,
        }
    }

    /// This layout without the distinct-value share: a log averaged over blocks of
    /// samples lies on the grid of its resolution over the block length, a per-sample
    /// property that a diagnosis at the averaged rate does not simulate
    /// ([`crate::diagnosis::averaged`]).
    pub fn without_distinct(mut self) -> Layout {
        self.defs.retain(|d| d.name != "ln_distinct_share");
        self.distinct = false;
        self
    }

    /// The blocks this layout covers.
    pub fn ranges(&self) -> &[Range<usize>] {
        &self.ranges
    }

    /// Averaging factors of the `adev` features.
    pub fn adev_factors(&self) -> &[usize] {
        &self.ms
    }

    /// The features of series `x` (a whole log's length), with the log's temperature (the
    /// one given to [`Layout::new`], whose regressors and bins the layout holds) and the
    /// other channels (same order as the names given to [`Layout::new`]).
    pub fn compute(
        &self,
        x: &[f64],
        temperature: Option<&Temperature>,
        others: &[&[f64]],
    ) -> Vec<f64> {
        self.compute_with(x, temperature, &self.others(others))
    }

    /// The first differences x_t - x_{t-1} within each of the layout's withheld ranges,
    /// range by range: the series the cross-axis correlation of differences pairs.
    fn diffs<'a>(&'a self, x: &'a [f64]) -> impl Iterator<Item = f64> + Clone + 'a {
        self.ranges
            .iter()
            .flat_map(move |r| x[r.start..r.end].windows(2).map(|w| w[1] - w[0]))
    }

    /// How many values [`Layout::diffs`] gives.
    fn n_diffs(&self) -> usize {
        self.ranges.iter().map(|r| r.len().saturating_sub(1)).sum()
    }

    /// What the cross-axis features need of each other channel in `others` on this
    /// layout's blocks, computed once for every series compared with the same channels
    /// (see [`OtherSide`]).
    pub fn others<'o>(&self, others: &[&'o [f64]]) -> Vec<OtherSide<'o>> {
        others
            .iter()
            .map(|o| {
                let window_means: Vec<f64> = self
                    .windows
                    .iter()
                    .map(|w| mean_var(&o[w.clone()]).0)
                    .collect();
                OtherSide {
                    x: o,
                    diff: CorrSide::of(self.diffs(o)),
                    window_mean: CorrSide::of(window_means.iter().copied()),
                    window_means,
                }
            })
            .collect()
    }

    /// [`Layout::compute`] with the other channels' side of the cross-axis features
    /// computed beforehand by [`Layout::others`].
    pub fn compute_with(
        &self,
        x: &[f64],
        temperature: Option<&Temperature>,
        others: &[OtherSide],
    ) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.defs.len());
        out.extend(self.ln_avar(x));
        out.extend(self.ln_psd(x));
        let (means, lnvars): (Vec<f64>, Vec<f64>) = self
            .windows
            .iter()
            .map(|w| {
                let (m, v) = mean_var(&x[w.clone()]);
                (m, v.max(f64::MIN_POSITIVE).ln())
            })
            .unzip();
        out.extend(&means);
        out.extend(lnvars);
        let cell = self.value_cell(x);
        out.extend(self.distribution(x, cell));
        if let (Some(tl), Some(tp)) = (&self.temp, temperature) {
            out.extend(self.temperature(x, tl, tp));
        }
        out.extend(self.state(x, cell));
        debug_assert!(others.len() == self.n_other);
        if self.n_other > 0 {
            // the mean of the series' differences, once for every other channel
            let mean_diff = CorrSide::mean_of(self.diffs(x), self.n_diffs());
            for o in others.iter().take(self.n_other) {
                out.push(o.diff.corr_given_mean(x, mean_diff, &self.ranges, o.x));
                out.push(
                    o.window_mean
                        .corr(|| means.iter().copied(), o.window_means.iter().copied()),
                );
            }
        }
        debug_assert_eq!(out.len(), self.defs.len());
        out
    }

    /// Seconds each family of [`Layout::compute_with`] takes on `x`, `reps` times over
    /// (for `benches/features.rs`; the features are computed and dropped).
    #[doc(hidden)]
    pub fn family_seconds(
        &self,
        x: &[f64],
        temperature: Option<&Temperature>,
        reps: usize,
    ) -> Vec<(&'static str, f64)> {
        let time = |f: &dyn Fn() -> usize| {
            let t0 = std::time::Instant::now();
            let mut k = 0;
            for _ in 0..reps {
                k += std::hint::black_box(f());
            }
            std::hint::black_box(k);
            t0.elapsed().as_secs_f64()
        };
        let mut out = vec![
            ("adev", time(&|| self.ln_avar(x).len())),
            ("psd", time(&|| self.ln_psd(x).len())),
            (
                "time",
                time(&|| {
                    self.windows
                        .iter()
                        .map(|w| mean_var(&x[w.clone()]).0 as usize)
                        .sum()
                }),
            ),
            (
                "distribution",
                time(&|| self.distribution(x, self.value_cell(x)).len()),
            ),
            ("state", time(&|| self.state(x, self.value_cell(x)).len())),
        ];
        if let (Some(tl), Some(tp)) = (&self.temp, temperature) {
            out.push(("temperature", time(&|| self.temperature(x, tl, tp).len())));
        }
        out
    }

    /// ln of the pooled Allan variance at the layout's averaging factors.
    pub fn ln_avar(&self, x: &[f64]) -> Vec<f64> {
        let mut num = vec![0.0; self.ms.len()];
        let mut den = vec![0.0; self.ms.len()];
        for r in &self.ranges {
            let y = &x[r.clone()];
            // the factors this block is long enough for (4m <= N_b)
            let n_ms = self.ms.iter().take_while(|&&m| 4 * m <= y.len()).count();
            let devs = adev::deviations(y, adev::Kind::Adev, &self.ms[..n_ms]);
            for (i, (&m, d)) in self.ms.iter().zip(devs).enumerate() {
                let terms = (y.len() + 1 - 2 * m) as f64;
                num[i] += terms * d * d;
                den[i] += terms;
            }
        }
        num.iter()
            .zip(&den)
            .map(|(a, b)| (a / b).max(f64::MIN_POSITIVE).ln())
            .collect()
    }

    fn ln_psd(&self, x: &[f64]) -> Vec<f64> {
        let l = self.seg_len;
        let mut planner = RealFftPlanner::<f64>::new();
        let fft = planner.plan_fft_forward(l);
        let win: Vec<f64> = (0..l)
            .map(|i| {
                let s = (std::f64::consts::PI * i as f64 / l as f64).sin();
                s * s
            })
            .collect();
        let w2: f64 = win.iter().map(|w| w * w).sum();
        let mut acc = vec![0.0; l / 2 + 1];
        let mut count = 0usize;
        let mut buf = fft.make_input_vec();
        let mut spec = fft.make_output_vec();
        for r in &self.ranges {
            let y = &x[r.clone()];
            let mut start = 0;
            while start + l <= y.len() {
                let seg = &y[start..start + l];
                let mean = seg.iter().sum::<f64>() / l as f64;
                for i in 0..l {
                    buf[i] = (seg[i] - mean) * win[i];
                }
                fft.process(&mut buf, &mut spec)
                    .expect("fft sizes are fixed");
                for (a, c) in acc.iter_mut().zip(&spec) {
                    *a += c.norm_sqr();
                }
                count += 1;
                start += l / 2;
            }
        }
        // One-sided PSD: 2 |X_k|^2 / (rate_hz sum w^2); the rate is folded into the
        // band's constant, which cancels in every comparison, so it is left out.
        let scale = 2.0 / (w2 * count.max(1) as f64);
        self.bands
            .iter()
            .map(|b| {
                let s: f64 = acc[b.clone()].iter().sum::<f64>() * scale / b.len() as f64;
                s.max(f64::MIN_POSITIVE).ln()
            })
            .collect()
    }

    /// The cell within which two values of `x` on the part are one value: 1e-9 of
    /// their largest magnitude (0 when none is finite). A rate computed as a
    /// difference of rounded angles carries float noise in its last digits
    /// (0.22904528993991607 and 0.2290452899399163), not more levels; the distinct
    /// values and the state bins read the same cell.
    fn value_cell(&self, x: &[f64]) -> f64 {
        1e-9 * self
            .ranges
            .iter()
            .map(|r| largest_finite_magnitude(&x[r.clone()]))
            .fold(0.0f64, f64::max)
    }

    fn distribution(&self, x: &[f64], cell: f64) -> Vec<f64> {
        let mut d: Vec<f64> = Vec::with_capacity(self.ranges.iter().map(|r| r.len()).sum());
        for r in &self.ranges {
            d.extend(x[r.clone()].windows(2).map(|w| w[1] - w[0]));
        }
        let (m, v) = mean_var(&d);
        // the fourth central moment and |d| in one pass
        let mut s4 = 0.0;
        for e in d.iter_mut() {
            s4 += (*e - m).powi(4);
            *e = e.abs();
        }
        let m4 = s4 / d.len() as f64;
        let kurt = if v > 0.0 { m4 / (v * v) } else { 1.0 };
        // the order statistics of |d| at the ranks of p = 0.5, 0.999, 0.9999
        let len = d.len();
        let rank = |p: f64| ((p * (len - 1) as f64).round() as usize).min(len - 1);
        let q = order_statistics(&d, &[rank(0.5), rank(0.999), rank(0.9999)]);
        let med = q[0].max(f64::MIN_POSITIVE * 1e10);
        let ratio = |qp: f64| (qp / med).max(f64::MIN_POSITIVE).ln();
        // values in one cell ([`Layout::value_cell`]) are one value
        let n_part: usize = self.ranges.iter().map(|r| r.len()).sum();
        let mut out = vec![
            v.max(f64::MIN_POSITIVE).sqrt().ln(),
            kurt.max(f64::MIN_POSITIVE).ln(),
            ratio(q[1]),
            ratio(q[2]),
        ];
        if !self.distinct {
            return out;
        }
        let distinct = if cell > 0.0 {
            distinct_count_on_grid(
                self.ranges
                    .iter()
                    .flat_map(|r| x[r.clone()].iter().copied()),
                cell,
                n_part,
            )
        } else {
            distinct_count_of(
                self.ranges
                    .iter()
                    .flat_map(|r| x[r.clone()].iter().copied()),
                n_part,
            )
        };
        out.push((distinct as f64 / n_part as f64).ln());
        out
    }

    fn temperature(&self, x: &[f64], tl: &TempLayout, tp: &Temperature) -> Vec<f64> {
        // normal equations of x on (1, dT, dT^2, dT/dt); the matrix and the bins are
        // the layout's (its temperature is the one every series is compared under)
        debug_assert_eq!(
            tl.bins.len(),
            self.ranges.iter().map(|r| r.len()).sum::<usize>()
        );
        let mut aty = [0.0; 4];
        let mut at = 0;
        let mut sum_t = [0.0; N_BINS];
        let mut cnt_t = [0.0; N_BINS];
        let mut sum_r = [0.0; N_BINS];
        let mut cnt_r = [0.0; N_BINS];
        let mut d_sum = [0.0; N_BINS];
        let mut d_sq = [0.0; N_BINS];
        for r in &self.ranges {
            for t in r.clone() {
                let dtc = tp.t_c[t] - tl.t_mean;
                let row = [1.0, dtc, dtc * dtc, tp.dtdt_c_per_s[t]];
                for i in 0..4 {
                    aty[i] += row[i] * x[t];
                }
                let (bt, br) = tl.bins[at];
                let (bt, br) = (bt as usize, br as usize);
                at += 1;
                sum_t[bt] += x[t];
                cnt_t[bt] += 1.0;
                sum_r[br] += x[t];
                cnt_r[br] += 1.0;
                if t > r.start {
                    let d = x[t] - x[t - 1];
                    d_sum[bt] += d;
                    d_sq[bt] += d * d;
                }
            }
        }
        let coef = crate::estimator::linalg::normal_equations(&tl.ata, &aty, 4)
            .unwrap_or_else(|| vec![0.0; 4]);
        let mut out = vec![coef[1], coef[2], coef[3]];
        let mean_or_zero = |s: f64, c: f64| if c > 0.0 { s / c } else { 0.0 };
        out.extend((0..N_BINS).map(|k| mean_or_zero(sum_t[k], cnt_t[k])));
        out.extend((0..N_BINS).map(|k| mean_or_zero(sum_r[k], cnt_r[k])));
        out.extend((0..N_BINS).map(|k| {
            let c = cnt_t[k].max(2.0);
            let m = d_sum[k] / c;
            (d_sq[k] / c - m * m).max(f64::MIN_POSITIVE).ln()
        }));
        out
    }

    fn state(&self, x: &[f64], cell: f64) -> Vec<f64> {
        let mut u: Vec<f64> = Vec::with_capacity(self.ranges.iter().map(|r| r.len()).sum());
        for r in &self.ranges {
            u.extend_from_slice(&x[r.start..r.end - 1]);
        }
        let ranks: Vec<usize> = (1..N_BINS).map(|k| (k * (u.len() - 1)) / N_BINS).collect();
        let edges = order_statistics(&u, &ranks);
        // a value within one cell ([`Layout::value_cell`]) above an edge is that edge's
        // value, as the distinct values count them: a level of a discrete series must
        // not be split across two bins by the float noise in its last digits
        // per bin: sums for the slope of x_t on x_{t-1}
        let mut s = [[0.0f64; 5]; N_BINS]; // n, su, sy, suu, suy
        for r in &self.ranges {
            for t in r.start + 1..r.end {
                let (a, y) = (x[t - 1], x[t]);
                let k = bin_of(&edges, a - cell).min(N_BINS - 1);
                let b = &mut s[k];
                b[0] += 1.0;
                b[1] += a;
                b[2] += y;
                b[3] += a * a;
                b[4] += a * y;
            }
        }
        s.iter()
            .map(|b| {
                let n = b[0].max(1.0);
                let suu = b[3] - b[1] * b[1] / n;
                let suy = b[4] - b[1] * b[2] / n;
                // a bin whose lagged values have no spread (one level of a discrete
                // series: suu is then rounding residue of b[3]; or a spread within a
                // cell, the float noise of a level 0 that block means carry) has no
                // slope
                if suu > 1e-9 * b[3] && suu > n * cell * cell {
                    suy / suu
                } else {
                    0.0
                }
            })
            .collect()
    }
}

/// The largest |v| over the finite values of `x` (0 when there are none), in eight
/// lanes: a maximum does not depend on the order its values are taken in, and lanes
/// break the chain of dependent compares that one running maximum makes.
/// `x.iter().filter(|v| v.is_finite()).fold(0.0, |m, v| m.max(v.abs()))` is its slow
/// twin.
pub fn largest_finite_magnitude(x: &[f64]) -> f64 {
    const LANES: usize = 8;
    let mut lane = [0.0f64; LANES];
    let (chunks, rest) = x.as_chunks::<LANES>();
    for c in chunks {
        for l in 0..LANES {
            let a = c[l].abs();
            // NaN and infinity fail the first compare
            lane[l] = if a < f64::INFINITY && a > lane[l] {
                a
            } else {
                lane[l]
            };
        }
    }
    let mut m = lane.iter().copied().fold(0.0f64, f64::max);
    for v in rest {
        let a = v.abs();
        if a < f64::INFINITY && a > m {
            m = a;
        }
    }
    m
}

/// The values at ranks `ranks` (ascending, 0-based) of `v` in the order of
/// [`f64::total_cmp`]: what `v` sorted would hold there. An MSD radix selection on
/// the order-preserving 64-bit keys of the values (`total_order_key`), 16 bits a
/// level: one pass counts the keys' top digit, a second gathers the keys of the digits
/// that hold a wanted rank, and the gathered keys go to the next digit the same way
/// until at most `SELECT_SORTED` (4096) are left, which are sorted. Each level reads its
/// input in order (no partitioning's data-dependent branches), and the gathered part
/// of a level is the share of one digit: a few per cent of `v` for a spread of values.
/// [`order_statistics_by_sort`] is its slow twin.
pub fn order_statistics(v: &[f64], ranks: &[usize]) -> Vec<f64> {
    debug_assert!(ranks.windows(2).all(|w| w[0] <= w[1]));
    debug_assert!(ranks.last().is_none_or(|&r| r < v.len()));
    let mut out = Vec::with_capacity(ranks.len());
    select_level(v, total_order_key, ranks, 64 - SELECT_DIGIT_BITS, &mut out);
    out.into_iter().map(from_total_order_key).collect()
}

/// Bits of key a level of [`order_statistics`] counts.
const SELECT_DIGIT_BITS: u32 = 16;
/// At most this many keys, [`order_statistics`] sorts instead of counting digits.
const SELECT_SORTED: usize = 4096;

/// The key of `v` in [`f64::total_cmp`]'s order as an unsigned integer: a non-negative
/// value's bits with the sign bit set, a negative value's bits inverted (the standard
/// trick `total_cmp` itself rests on).
fn total_order_key(v: f64) -> u64 {
    let b = v.to_bits();
    if b >> 63 == 1 { !b } else { b | 1 << 63 }
}

/// The value of a key of [`total_order_key`].
fn from_total_order_key(k: u64) -> f64 {
    f64::from_bits(if k >> 63 == 1 { k & !(1 << 63) } else { !k })
}

/// One level of [`order_statistics`]: pushes onto `out` the keys at `ranks` among the
/// keys `key(items[i])`, which agree in every bit above `shift + SELECT_DIGIT_BITS`;
/// the digit counted is bits `shift..shift + SELECT_DIGIT_BITS`.
fn select_level<T: Copy>(
    items: &[T],
    key: impl Fn(T) -> u64 + Copy,
    ranks: &[usize],
    shift: u32,
    out: &mut Vec<u64>,
) {
    const DIGITS: usize = 1 << SELECT_DIGIT_BITS;
    // few keys are sorted; so are the keys for more ranks than a u8 tags groups by
    if items.len() <= SELECT_SORTED || ranks.len() >= u8::MAX as usize {
        let mut keys: Vec<u64> = items.iter().map(|&t| key(t)).collect();
        keys.sort_unstable();
        out.extend(ranks.iter().map(|&r| keys[r]));
        return;
    }
    let digit = |k: u64| ((k >> shift) as usize) & (DIGITS - 1);
    let mut count = vec![0u32; DIGITS];
    for &t in items {
        count[digit(key(t))] += 1;
    }
    // the digit of each rank and the rank within it, walking the counts once
    let mut groups: Vec<(usize, Vec<usize>)> = Vec::new();
    let (mut d, mut start) = (0usize, 0usize);
    for &r in ranks {
        while start + count[d] as usize <= r {
            start += count[d] as usize;
            d += 1;
        }
        match groups.last_mut() {
            Some((gd, rs)) if *gd == d => rs.push(r - start),
            _ => groups.push((d, vec![r - start])),
        }
    }
    // a group per distinct digit that holds a wanted rank, told apart by a u8 tag
    let mut tag = vec![u8::MAX; DIGITS];
    for (g, (d, _)) in groups.iter().enumerate() {
        tag[*d] = g as u8;
    }
    let mut gathered: Vec<Vec<u64>> = groups
        .iter()
        .map(|(d, _)| Vec::with_capacity(count[*d] as usize))
        .collect();
    for &t in items {
        let k = key(t);
        let g = tag[digit(k)];
        if g != u8::MAX {
            gathered[g as usize].push(k);
        }
    }
    drop((count, tag));
    for ((_, rs), keys) in groups.iter().zip(gathered) {
        // the keys of one lowest digit are all one key; so are the many copies of one
        // value in a series on a grid (a quantized output's increments)
        if shift == 0 || keys.iter().all(|&k| k == keys[0]) {
            out.extend(rs.iter().map(|_| keys[0]));
        } else {
            select_level(
                &keys,
                std::convert::identity,
                rs,
                shift - SELECT_DIGIT_BITS,
                out,
            );
        }
    }
}

/// The values at ranks `ranks` of `v` sorted by [`f64::total_cmp`] (the slow twin of
/// [`order_statistics`]).
pub fn order_statistics_by_sort(v: &[f64], ranks: &[usize]) -> Vec<f64> {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    ranks.iter().map(|&k| s[k]).collect()
}

/// How many distinct values `x` holds, as a sort by [`f64::total_cmp`] followed by
/// `dedup` counts them (values equal under `==` counted once, so -0 and +0 are one
/// value, and every NaN its own): the bit patterns, -0 read as +0, in a hash set, plus
/// the NaNs. [`distinct_count_by_sort`] is its slow twin.
///
/// A direct-mapped table of the last key seen in each of `RECENT` slots (indexed by the
/// key's hash) stands before the set: a key found there is in the set already and is
/// not hashed into it again, which spares the set's probing for a series on a grid of
/// few values (a rounded log); a miss only costs the insert it would have made anyway.
pub fn distinct_count(x: impl Iterator<Item = f64>) -> usize {
    let n = x.size_hint().0;
    distinct_count_of(x, n)
}

/// [`distinct_count`] of the `n` values of `x` (room for them reserved at once).
pub fn distinct_count_of(x: impl Iterator<Item = f64>, n: usize) -> usize {
    const RECENT: usize = 1 << 10;
    // a NaN's bit pattern: never a key (NaNs are counted apart)
    const EMPTY: u64 = u64::MAX;
    let mut recent = [EMPTY; RECENT];
    // room for every value at once: no rehash as the set grows
    let mut seen: std::collections::HashSet<u64, BitsHash> =
        std::collections::HashSet::with_capacity_and_hasher(n, BitsHash);
    let mut nans = 0;
    for v in x {
        if v.is_nan() {
            nans += 1;
        } else {
            let key = if v == 0.0 { 0 } else { v.to_bits() };
            let slot = (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 54) as usize;
            if recent[slot] != key {
                recent[slot] = key;
                seen.insert(key);
            }
        }
    }
    seen.len() + nans
}

/// How many distinct values the cells `round_half_away(v / cell)` of the values `v` of
/// `x` (`n` of them) hold, as [`distinct_count`] of the rounded values counts them (every
/// NaN its own value, each infinity one), for a `cell` with `|v| / cell` below about
/// 1e15 for every finite `v` (the features' grid: 1e-9 of the largest magnitude).
///
/// The finite cells are integers: up to 4096 distinct ones are counted in a small hash
/// set; more (a span of up to 2^32 cells), in a bitmap by `distinct_count_u32`, which
/// reads the cells in order a fixed number of times where a hash set probes memory at
/// random and a sort makes passes by the span's digits. [`distinct_count_by_sort`] of
/// the rounded values is its slow twin.
pub fn distinct_count_on_grid(x: impl Iterator<Item = f64>, cell: f64, n: usize) -> usize {
    let mut keys: Vec<i64> = Vec::with_capacity(n);
    let (mut nans, mut pos_inf, mut neg_inf) = (0usize, false, false);
    let (mut lo, mut hi) = (i64::MAX, i64::MIN);
    let mut wide = false;
    for v in x {
        let c = crate::num::round_half_away(v / cell);
        if c.is_nan() {
            nans += 1;
        } else if c == f64::INFINITY {
            pos_inf = true;
        } else if c == f64::NEG_INFINITY {
            neg_inf = true;
        } else {
            if c.abs() >= 1e15 {
                wide = true;
            }
            let k = c as i64;
            lo = lo.min(k);
            hi = hi.max(k);
            keys.push(k);
        }
    }
    let extra = nans + usize::from(pos_inf) + usize::from(neg_inf);
    if keys.is_empty() {
        return extra;
    }
    if wide {
        // beyond the grid this is for: the values themselves, hashed
        return distinct_count_of(keys.iter().map(|&k| k as f64), keys.len()) + extra;
    }
    // a series on a grid of few levels (a printed or quantized log) is counted in a
    // small set; one with more levels than FEW_LEVELS is sorted
    if let Some(c) = few_levels(&keys) {
        return c + extra;
    }
    let span = (hi - lo) as u64;
    if span > u64::from(u32::MAX) {
        let mut a: Vec<u64> = keys.iter().map(|&k| (k - lo) as u64).collect();
        a.sort_unstable();
        return 1 + a.windows(2).filter(|w| w[0] != w[1]).count() + extra;
    }
    RADIX_SCRATCH.with(|cell| {
        let (a, b, seen) = &mut *cell.borrow_mut();
        a.clear();
        a.extend(keys.iter().map(|&k| (k - lo) as u32));
        drop(keys);
        distinct_count_u32(a, b, seen, span as u32) + extra
    })
}

/// Most distinct values [`few_levels`] counts in a set.
const FEW_LEVELS: usize = 4096;

/// How many distinct values `keys` holds when at most [`FEW_LEVELS`], else None (as
/// soon as more are seen): a direct-mapped table of the last key in each of 1024 slots
/// before a hash set, so that a key seen recently is not hashed again.
fn few_levels(keys: &[i64]) -> Option<usize> {
    const RECENT: usize = 1 << 10;
    // the fill: never a cell (every cell is below 1e15 in magnitude)
    let mut recent = [i64::MIN; RECENT];
    let mut seen: std::collections::HashSet<u64, BitsHash> =
        std::collections::HashSet::with_capacity_and_hasher(2 * FEW_LEVELS, BitsHash);
    for &k in keys {
        let slot = ((k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 54) as usize;
        if recent[slot] != k {
            recent[slot] = k;
            seen.insert(k as u64);
            if seen.len() > FEW_LEVELS {
                return None;
            }
        }
    }
    Some(seen.len())
}

thread_local! {
    /// The buffers of [`distinct_count_u32`], kept per thread between calls (a fresh
    /// allocation of a few MB pays a page fault for each of its pages).
    static RADIX_SCRATCH: std::cell::RefCell<(Vec<u32>, Vec<u32>, Vec<u64>)> =
        const { std::cell::RefCell::new((Vec::new(), Vec::new(), Vec::new())) };
}

/// Bits of a key [`distinct_count_u32`] marks in its bitmap: 2^20 bits, 128 kB (a
/// level-2 cache holds it).
const BITMAP_BITS: u32 = 20;

/// How many distinct values `a` holds, every value at most `max`: marked in a bitmap
/// of 2^[`BITMAP_BITS`] bits, after one counting pass and one scatter of `a` into `b`
/// by the bits above those (at most 2^12 buckets) when `max` needs more. Each value is
/// read a fixed number of times (no sort), and the bitmap's bits are cleared bucket by
/// bucket as they were set, so `seen` (grown to the bitmap's words once) stays zero
/// between calls. [`distinct_count_by_sort`] is its slow twin.
fn distinct_count_u32(a: &[u32], b: &mut Vec<u32>, seen: &mut Vec<u64>, max: u32) -> usize {
    let bits = 32 - max.leading_zeros();
    let low = bits.min(BITMAP_BITS);
    let mask = (1u32 << low) - 1;
    let words = (1usize << low).div_ceil(64);
    if seen.len() < words {
        seen.resize(words, 0);
    }
    // the values of one bucket marked, counted as they are first set, then cleared
    let mut count_bucket = |vals: &[u32]| -> usize {
        let mut n = 0;
        for &k in vals {
            let i = (k & mask) as usize;
            let (w, bit) = (i >> 6, 1u64 << (i & 63));
            n += usize::from(seen[w] & bit == 0);
            seen[w] |= bit;
        }
        for &k in vals {
            seen[((k & mask) as usize) >> 6] = 0;
        }
        n
    };
    if bits <= BITMAP_BITS {
        return count_bucket(a);
    }
    let shift = BITMAP_BITS;
    let n_buckets = 1usize << (bits - shift);
    let mut start = vec![0usize; n_buckets + 1];
    for &k in a {
        start[(k >> shift) as usize + 1] += 1;
    }
    for i in 0..n_buckets {
        start[i + 1] += start[i];
    }
    b.resize(a.len(), 0);
    let mut at = start.clone();
    for &k in a {
        let d = (k >> shift) as usize;
        b[at[d]] = k;
        at[d] += 1;
    }
    (0..n_buckets)
        .map(|d| count_bucket(&b[start[d]..start[d + 1]]))
        .sum()
}

/// The count of [`distinct_count`] by sorting and `dedup` (its slow twin).
pub fn distinct_count_by_sort(x: impl Iterator<Item = f64>) -> usize {
    let mut vals: Vec<f64> = x.collect();
    vals.sort_by(f64::total_cmp);
    vals.dedup();
    vals.len()
}

/// A hasher for the bit patterns of doubles: one multiply and a fold of the high half
/// (Fibonacci hashing, Knuth TAOCP vol. 3, 6.4), far cheaper than the default SipHash
/// and enough for keys that are not chosen by an adversary.
#[derive(Clone, Copy, Default)]
struct BitsHash;

impl std::hash::BuildHasher for BitsHash {
    type Hasher = BitsHasher;
    fn build_hasher(&self) -> BitsHasher {
        BitsHasher(0)
    }
}

struct BitsHasher(u64);

impl std::hash::Hasher for BitsHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.write_u64(u64::from(*b));
        }
    }
    fn write_u64(&mut self, i: u64) {
        let h = (self.0 ^ i).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        self.0 = h ^ (h >> 32);
    }
}

/// Mean and (population) variance.
pub fn mean_var(x: &[f64]) -> (f64, f64) {
    if x.is_empty() {
        return (0.0, 0.0);
    }
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let v = x.iter().map(|e| (e - m) * (e - m)).sum::<f64>() / n;
    (m, v)
}

/// Pearson correlation of the pairs (0 when either side is constant): the slow twin of
/// [`CorrSide::corr`], which gives the same value bit for bit.
#[cfg(test)]
fn corr_pairs(pairs: impl Iterator<Item = (f64, f64)>) -> f64 {
    let v: Vec<(f64, f64)> = pairs.collect();
    let n = v.len().max(1) as f64;
    let (ma, mb) = v
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (a, b) in &v {
        sab += (a - ma) * (b - mb);
        saa += (a - ma) * (a - ma);
        sbb += (b - mb) * (b - mb);
    }
    if saa > 0.0 && sbb > 0.0 {
        sab / (saa * sbb).sqrt()
    } else {
        0.0
    }
}

/// One other channel as the cross-axis features compare a series with it, on one
/// layout's blocks: its samples, and its side of the two correlations (of the
/// differences, of the window means), the same for every series compared with it.
#[derive(Clone, Debug)]
pub struct OtherSide<'o> {
    x: &'o [f64],
    diff: CorrSide,
    window_means: Vec<f64>,
    window_mean: CorrSide,
}

/// One side b of a Pearson correlation of pairs (a_i, b_i), i < n: the count n, the
/// mean m_b = sum_i b_i / n (summed as b_i / n in order) and the centred sum of squares
/// S_bb = sum_i (b_i - m_b)^2. The correlation with a side a is
/// S_ab / sqrt(S_aa S_bb) (0 when S_aa or S_bb is 0), every sum taken in the order of
/// the pairs, so that it equals [`corr_pairs`] of the zipped pairs bit for bit.
#[derive(Clone, Copy, Debug)]
struct CorrSide {
    n: usize,
    mean: f64,
    ss: f64,
}

impl CorrSide {
    fn of(b: impl Iterator<Item = f64> + Clone) -> CorrSide {
        let n = b.clone().count();
        let mean = CorrSide::mean_of(b.clone(), n);
        let ss = b.fold(0.0, |s, y| s + (y - mean) * (y - mean));
        CorrSide { n, mean, ss }
    }

    /// The mean of the `n` values of `b`, summed as b_i / n in order (the mean every
    /// side of a correlation takes, so that [`corr_pairs`] is matched bit for bit).
    fn mean_of(b: impl Iterator<Item = f64>, n: usize) -> f64 {
        let nf = n.max(1) as f64;
        b.fold(0.0, |m, y| m + y / nf)
    }

    /// [`CorrSide::corr`] of the differences of `x` within `ranges`, whose mean
    /// [`CorrSide::mean_of`] is `mean_a`, with this side's values, the differences of
    /// `o` within the same ranges: both range by range (as [`Layout::diffs`] lists
    /// them), the same sums in the same order.
    fn corr_given_mean(&self, x: &[f64], mean_a: f64, ranges: &[Range<usize>], o: &[f64]) -> f64 {
        let (mut sab, mut saa) = (0.0, 0.0);
        for r in ranges {
            let (xs, os) = (&x[r.start..r.end], &o[r.start..r.end]);
            for (wx, wo) in xs.windows(2).zip(os.windows(2)) {
                let (a, b) = (wx[1] - wx[0], wo[1] - wo[0]);
                sab += (a - mean_a) * (b - self.mean);
                saa += (a - mean_a) * (a - mean_a);
            }
        }
        self.of_sums(sab, saa)
    }

    /// The correlation of `a` (a fresh iterator per call, n values) with this side,
    /// whose values `b` gives again in the same order.
    fn corr<A: Iterator<Item = f64>>(
        &self,
        a: impl Fn() -> A,
        b: impl Iterator<Item = f64>,
    ) -> f64 {
        let ma = CorrSide::mean_of(a(), self.n);
        let (mut sab, mut saa) = (0.0, 0.0);
        for (x, y) in a().zip(b) {
            sab += (x - ma) * (y - self.mean);
            saa += (x - ma) * (x - ma);
        }
        self.of_sums(sab, saa)
    }

    /// The correlation S_ab / sqrt(S_aa S_bb) from the centred sums S_ab and S_aa of the
    /// other side (0 when S_aa or S_bb is 0).
    fn of_sums(&self, sab: f64, saa: f64) -> f64 {
        if saa > 0.0 && self.ss > 0.0 {
            sab / (saa * self.ss).sqrt()
        } else {
            0.0
        }
    }
}

/// The precision a log was printed with: 10^-k for the smallest k in 0..=9 such that
/// every finite value times 10^k is an integer (to 1e-6, far above the error of a
/// decimal parsed to binary, far below a step), None when there is no such k or a
/// value is beyond 1e9 times that step (where a double no longer shows the fraction). A log written as text with k decimals holds
/// values on this grid whatever the sensor measured; its share of distinct values (and
/// the distribution of small differences) says how the log was written, not what the
/// sensor does, so the simulations are rounded to the same grid before they are
/// compared ([`round_to`]).
pub fn printed_step(x: &[f64]) -> Option<f64> {
    let finite: Vec<f64> = x.iter().copied().filter(|v| v.is_finite()).collect();
    if finite.len() < 2 {
        return None;
    }
    (0..=9).find_map(|k: i32| {
        let scale = 10f64.powi(k);
        finite
            .iter()
            .all(|v| {
                let a = v * scale;
                a.abs() < 1e9 && (a - a.round()).abs() <= 1e-6
            })
            .then(|| 10f64.powi(-k))
    })
}

/// `x` rounded to the grid of `step` (round half away from zero, as printing does).
pub fn round_to(x: &[f64], step: f64) -> Vec<f64> {
    let mut y = x.to_vec();
    round_in_place(&mut y, step);
    y
}

/// [`round_to`] in place.
pub fn round_in_place(x: &mut [f64], step: f64) {
    for v in x {
        *v = crate::num::round_half_away(*v / step) * step;
    }
}

#[cfg(test)]
mod printed_tests {
    use super::{printed_step, round_to};

    #[test]
    fn the_printed_precision_is_found_and_continuous_values_have_none() {
        let x: Vec<f64> = (0..2000).map(|k| (k as f64 * 0.731).sin() * 0.37).collect();
        assert_eq!(printed_step(&x), None);
        for k in [0, 2, 4, 6] {
            let step = 10f64.powi(-k);
            // as a CSV with k decimals would be parsed back
            let printed: Vec<f64> = x
                .iter()
                .map(|v| format!("{v:.prec$}", prec = k as usize).parse().unwrap())
                .collect();
            let got = printed_step(&printed).unwrap();
            assert!((got - step).abs() < 1e-15 * step.max(1.0), "{k}: {got}");
            let r = round_to(&x, got);
            assert_eq!(
                printed_step(&r).map(|s| (s / step).round()),
                Some(1.0),
                "{k}"
            );
        }
        // an LSB of 0.05 printed with 2 decimals: the printing step, 0.01
        let lsb: Vec<f64> = x
            .iter()
            .map(|v| format!("{:.2}", (v / 0.05).round() * 0.05).parse().unwrap())
            .collect();
        assert!((printed_step(&lsb).unwrap() - 0.01).abs() < 1e-15);
    }
}

#[cfg(test)]
mod selection_tests {
    use super::{
        distinct_count, distinct_count_by_sort, distinct_count_on_grid, largest_finite_magnitude,
        order_statistics, order_statistics_by_sort,
    };

    /// A reproducible series with ties, signed zeros, a grid and wide tails.
    fn series(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|i| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let u = (s >> 11) as f64 / (1u64 << 53) as f64;
                match i % 7 {
                    0 => 0.0,
                    1 => -0.0,
                    2 => (u * 20.0).round() * 0.01,
                    _ => (u - 0.5) * 10f64.powf(6.0 * u - 3.0),
                }
            })
            .collect()
    }

    #[test]
    fn selection_gives_the_sorted_values_bit_for_bit() {
        for (n, seed) in [(1usize, 1u64), (2, 2), (17, 3), (1000, 4), (100_003, 5)] {
            let x = series(n, seed);
            let ranks: Vec<usize> = [0.0, 0.2, 0.2, 0.5, 0.999, 0.9999, 1.0]
                .iter()
                .map(|p| ((p * (n - 1) as f64).round() as usize).min(n - 1))
                .collect();
            let want = order_statistics_by_sort(&x, &ranks);
            let got = order_statistics(&x, &ranks);
            let bits = |v: &[f64]| v.iter().map(|e| e.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&got), bits(&want), "n {n}");
        }
    }

    #[test]
    fn selection_of_narrow_tied_and_special_values_gives_the_sorted_values_bit_for_bit() {
        let n = 30_011;
        let base = series(n, 9);
        // values that share their top digits (every level of the radix is used), many
        // copies of a few values (groups whose keys are one key), and the specials
        let narrow: Vec<f64> = base.iter().map(|u| 1.0 + u * 1e-12).collect();
        let tied: Vec<f64> = (0..n).map(|i| ((i * 7919) % 5) as f64 * 0.25).collect();
        let mut special = base.clone();
        for (i, v) in [
            f64::NAN,
            -f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            -0.0,
            0.0,
        ]
        .into_iter()
        .enumerate()
        {
            for k in 0..50 {
                special[(k * 601 + i * 97) % n] = v;
            }
        }
        for x in [narrow, tied, special] {
            let ranks: Vec<usize> = (0..=20).map(|k| k * (n - 1) / 20).collect();
            let want = order_statistics_by_sort(&x, &ranks);
            let got = order_statistics(&x, &ranks);
            let bits = |v: &[f64]| v.iter().map(|e| e.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&got), bits(&want));
        }
    }

    #[test]
    fn the_largest_finite_magnitude_is_the_running_maximum_of_the_finite_values() {
        let slow = |x: &[f64]| {
            x.iter()
                .filter(|v| v.is_finite())
                .fold(0.0f64, |m, v| m.max(v.abs()))
        };
        for (n, seed) in [
            (0usize, 1u64),
            (1, 2),
            (7, 3),
            (8, 4),
            (1001, 5),
            (100_003, 6),
        ] {
            let mut x = series(n, seed);
            assert_eq!(largest_finite_magnitude(&x).to_bits(), slow(&x).to_bits());
            // specials larger than every finite value, at the start, inside and in the tail
            for (i, v) in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -f64::NAN]
                .into_iter()
                .enumerate()
            {
                if n > 0 {
                    x[(i * 7919) % n] = v;
                }
            }
            if n > 0 {
                x[n - 1] = -1e6;
            }
            assert_eq!(
                largest_finite_magnitude(&x).to_bits(),
                slow(&x).to_bits(),
                "n {n}"
            );
        }
        assert_eq!(largest_finite_magnitude(&[f64::NAN; 9]), 0.0);
    }

    #[test]
    fn the_distinct_count_is_the_stable_sort_and_dedup_count() {
        for (n, seed) in [(1usize, 1u64), (50, 2), (10_000, 3), (200_003, 4)] {
            let mut x = series(n, seed);
            x.push(f64::NAN);
            x.push(f64::NAN);
            let want = distinct_count_by_sort(x.iter().copied());
            assert_eq!(distinct_count(x.iter().copied()), want, "n {n}");
            // on a grid, as a printed log's values are
            let grid: Vec<f64> = x.iter().map(|v| (v * 100.0).round() / 100.0).collect();
            assert_eq!(
                distinct_count(grid.iter().copied()),
                distinct_count_by_sort(grid.iter().copied()),
                "n {n}"
            );
            // the cells of the features' grid, NaNs and infinities among the values
            let mut y = x.clone();
            y.extend([f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, -0.0, 0.0]);
            for cell in [1e-9, 1e-7, 1e-6, 1e-4, 1e-3, 0.1, 7.0] {
                let rounded = y.iter().map(|v| crate::num::round_half_away(v / cell));
                assert_eq!(
                    distinct_count_on_grid(y.iter().copied(), cell, y.len()),
                    distinct_count_by_sort(rounded),
                    "n {n} cell {cell}"
                );
            }
        }
    }
}

#[cfg(test)]
mod cross_axis_tests {
    use super::{Layout, corr_pairs, mean_var};
    use crate::diagnosis::blocks::Blocks;

    #[test]
    fn the_cross_axis_features_are_the_pairwise_correlations_bit_for_bit() {
        let n = 20_011;
        let mut s = 3u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let x: Vec<f64> = (0..n).map(|_| next()).collect();
        let o1: Vec<f64> = x.iter().map(|v| 0.3 * v + next()).collect();
        let o2: Vec<f64> = (0..n)
            .map(|t| (t as f64 * 1e-3).sin() + 0.1 * next())
            .collect();
        let flat = vec![1.5; n];
        let names: Vec<String> = ["a", "b", "c"].map(String::from).to_vec();
        let blocks = Blocks::interleaved(n, 8, 0.5).unwrap();
        for training in [false, true] {
            let l = Layout::new(&blocks, training, 100.0, None, &names);
            let others: [&[f64]; 3] = [&o1, &o2, &flat];
            let got = l.compute(&x, None, &others);
            let tail = &got[got.len() - 2 * others.len()..];
            for (j, o) in others.iter().enumerate() {
                let diff = corr_pairs(l.ranges.iter().flat_map(|r| {
                    (r.start + 1..r.end).map(|t| (x[t] - x[t - 1], o[t] - o[t - 1]))
                }));
                let wm = corr_pairs(
                    l.windows
                        .iter()
                        .map(|w| (mean_var(&x[w.clone()]).0, mean_var(&o[w.clone()]).0)),
                );
                assert_eq!(tail[2 * j].to_bits(), diff.to_bits(), "{j}");
                assert_eq!(tail[2 * j + 1].to_bits(), wm.to_bits(), "{j}");
            }
            // a constant channel's differences have no spread: no correlation
            assert_eq!(tail[4], 0.0);
        }
    }
}

#[cfg(test)]
mod state_tests {
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::Layout;
    use crate::diagnosis::blocks::Blocks;

    /// A rate on a grid of four levels whose values carry float noise in their last
    /// digits (as a rate computed as `(k1 q - k0 q) / dt` from a rounded angle does):
    /// the state features are those of the exact levels.
    #[test]
    fn float_noise_on_the_levels_of_a_discrete_series_leaves_the_state_features_as_they_are() {
        let n = 40_000;
        let lsb = 2.792_360_385_672_882;
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut next = || rng.random::<f64>();
        // the level index, a persistent chain: mostly 0 and 1, rarely -1 and 2
        let mut k = 0i64;
        let mut exact = Vec::with_capacity(n);
        let mut noisy = Vec::with_capacity(n);
        for _ in 0..n {
            if next() > 0.7 {
                k = match next() {
                    u if u < 0.01 => -1,
                    u if u < 0.5 => 0,
                    u if u < 0.97 => 1,
                    _ => 2,
                };
            }
            let v = k as f64 * lsb;
            exact.push(v);
            // a few ulps either way
            noisy.push(v * (1.0 + (next() - 0.5) * 8.0 * f64::EPSILON));
        }
        let names: Vec<String> = Vec::new();
        let blocks = Blocks::interleaved(n, 8, 0.5).unwrap();
        for training in [false, true] {
            let l = Layout::new(&blocks, training, 10.0, None, &names);
            let (a, b) = (
                l.state(&exact, l.value_cell(&exact)),
                l.state(&noisy, l.value_cell(&noisy)),
            );
            assert!(a.iter().any(|v| *v != 0.0), "{a:?}");
            for (x, y) in a.iter().zip(&b) {
                assert!((x - y).abs() < 1e-9, "{a:?} against {b:?}");
            }
        }
    }
}

#[cfg(test)]
mod timing_probe {
    use super::*;
    #[test]
    #[ignore]
    fn probe_compute_parts() {
        let n = 1_000_000usize;
        let mut s = 7u64;
        let x: Vec<f64> = (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5) * 100.0).round() / 100.0
            })
            .collect();
        let o1 = x.iter().rev().copied().collect::<Vec<_>>();
        let o2 = x.iter().map(|v| v * 0.3).collect::<Vec<_>>();
        let blocks = Blocks::interleaved(n, 12, 0.5).unwrap();
        let names = vec!["a".to_string(), "b".to_string()];
        let l = Layout::new(&blocks, false, 100.0, None, &names);
        let reps = 10;
        let t = |what: &str, f: &dyn Fn()| {
            let t0 = std::time::Instant::now();
            for _ in 0..reps {
                f();
            }
            eprintln!(
                "{what}: {:.2} ms",
                t0.elapsed().as_secs_f64() * 1e3 / reps as f64
            );
        };
        t("compute", &|| {
            std::hint::black_box(l.compute(&x, None, &[&o1, &o2]));
        });
        let sides = l.others(&[&o1, &o2]);
        t("compute_with", &|| {
            std::hint::black_box(l.compute_with(&x, None, &sides));
        });
        t("ln_avar", &|| {
            std::hint::black_box(l.ln_avar(&x));
        });
        t("ln_psd", &|| {
            std::hint::black_box(l.ln_psd(&x));
        });
        t("distribution", &|| {
            std::hint::black_box(l.distribution(&x, l.value_cell(&x)));
        });
        t("state", &|| {
            std::hint::black_box(l.state(&x, l.value_cell(&x)));
        });
        t("round", &|| {
            let mut y = x.clone();
            round_in_place(&mut y, 0.01);
            std::hint::black_box(y);
        });
    }
}
