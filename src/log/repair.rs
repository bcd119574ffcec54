//! Repairs ingest makes under the `interpolate` policies: filling non-finite values and
//! resampling an irregular time base onto a uniform grid, both by linear interpolation.

use std::path::Path;

use rayon::prelude::*;

use crate::error::Result;
use crate::store::StoreWriter;

/// Replaces every non-finite value of `x` by linear interpolation between its nearest
/// finite neighbours, weighted by `t` when given (else by index). Values before the
/// first finite one take its value; after the last finite one, the last's.
/// `x` must hold at least one finite value.
pub(crate) fn interpolate_nonfinite(x: &mut [f64], t: Option<&[f64]>) {
    let pos = |i: usize| t.map_or(i as f64, |t| t[i]);
    let n = x.len();
    let mut prev: Option<usize> = None;
    let mut i = 0;
    while i < n {
        if x[i].is_finite() {
            prev = Some(i);
            i += 1;
            continue;
        }
        let mut j = i;
        while j < n && !x[j].is_finite() {
            j += 1;
        }
        match (prev, (j < n).then_some(j)) {
            (Some(a), Some(b)) => {
                let (ta, tb) = (pos(a), pos(b));
                let (xa, xb) = (x[a], x[b]);
                for (k, v) in x.iter_mut().enumerate().take(j).skip(i) {
                    let w = (pos(k) - ta) / (tb - ta);
                    *v = xa + w * (xb - xa);
                }
            }
            (Some(a), None) => {
                let v = x[a];
                x[i..j].fill(v);
            }
            (None, Some(b)) => {
                let v = x[b];
                x[i..j].fill(v);
            }
            (None, None) => unreachable!("caller checks for a finite value"),
        }
        i = j;
    }
}

/// Resamples every column of `src` onto `t_k = t_0 + k dt` (k = 0 .. up to the last
/// time) by linear interpolation in the time column `time_idx`; returns a new writer
/// at `target` whose time column holds the grid.
pub(crate) fn resample_uniform(
    src: &mut StoreWriter,
    target: &Path,
    time_idx: usize,
    dt: f64,
) -> Result<StoreWriter> {
    let t = src.column(time_idx);
    let t0 = t[0];
    let span = t[t.len() - 1] - t0;
    let n_out = (span / dt + 1e-6).floor() as usize + 1;
    let mut out = StoreWriter::create(target, src.names(), n_out)?;
    let src_cols: Vec<&[f64]> = (0..src.names().len()).map(|i| src.column(i)).collect();
    out.columns_mut()
        .into_par_iter()
        .zip(src_cols.into_par_iter())
        .enumerate()
        .for_each(|(ci, (dst, x))| {
            let mut j = 0usize; // t[j] <= tk < t[j + 1]
            for (k, d) in dst.iter_mut().enumerate() {
                let tk = t0 + k as f64 * dt;
                if ci == time_idx {
                    *d = tk;
                    continue;
                }
                while j + 2 < t.len() && t[j + 1] <= tk {
                    j += 1;
                }
                let w = ((tk - t[j]) / (t[j + 1] - t[j])).clamp(0.0, 1.0);
                *d = x[j] + w * (x[j + 1] - x[j]);
            }
        });
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fills_inner_and_edge_runs() {
        let mut x = [f64::NAN, 1.0, f64::NAN, f64::NAN, 4.0, f64::INFINITY];
        interpolate_nonfinite(&mut x, None);
        assert_eq!(x, [1.0, 1.0, 2.0, 3.0, 4.0, 4.0]);
        let t = [0.0, 1.0, 3.0];
        let mut y = [0.0, f64::NAN, 3.0];
        interpolate_nonfinite(&mut y, Some(&t));
        assert_eq!(y, [0.0, 1.0, 3.0]);
    }
}
