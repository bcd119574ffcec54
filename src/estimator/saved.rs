//! A fitted FARMA model read back from the output folder of `farma fit`, so that the
//! simulator can run it (`kind = "farma"`, `model = OUTDIR` in a simulation spec).
//!
//! Reads `params.parquet` (`channel`, `p`, `q`, `d`, `b` (list), `mean`, `sigma2`) and
//! `coef.parquet` (`channel`, `m`, `grid`, `f`) as README "farma fit" documents them.
//! The grid is in the channel's units (the fit's mean added back), so f_m is evaluated
//! at the raw index value x_{t-d}; between grid points f_m is linear, beyond the ends
//! constant, exactly as the estimator evaluates it (`GridFit::eval`).

use std::path::{Path, PathBuf};

use arrow_array::{Array, Float64Array, Int64Array, ListArray, RecordBatch, StringArray};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

use crate::error::{Error, Result};

/// One channel's fitted FARMA(p,q,d) model.
#[derive(Debug, Clone, PartialEq)]
pub struct SavedFarma {
    /// The fitted channel.
    pub channel: String,
    pub p: usize,
    pub q: usize,
    pub d: usize,
    /// MA coefficients b_1..b_q.
    pub b: Vec<f64>,
    /// Mean subtracted before fitting (0 without demeaning), channel units.
    pub mean: f64,
    /// Innovation variance RSS / (N - max(p,q,d)).
    pub sigma2: f64,
    /// `grid[m-1]`: the ascending grid of f_m, channel units.
    pub grid: Vec<Vec<f64>>,
    /// `f[m-1][g]`: f_m at `grid[m-1][g]`.
    pub f: Vec<Vec<f64>>,
}

impl SavedFarma {
    /// f_1..f_p at index value `u` (channel units): linear between grid points,
    /// constant beyond the ends.
    #[inline]
    pub fn eval(&self, u: f64, out: &mut [f64]) {
        for (m, o) in out.iter_mut().enumerate() {
            *o = interp(&self.grid[m], &self.f[m], u);
        }
    }
}

/// Linear interpolation in an ascending `grid`, constant beyond the ends.
#[inline]
pub fn interp(grid: &[f64], f: &[f64], u: f64) -> f64 {
    let g = grid.len();
    if u <= grid[0] {
        f[0]
    } else if u >= grid[g - 1] {
        f[g - 1]
    } else {
        let k = grid.partition_point(|v| *v <= u) - 1;
        let lam = (u - grid[k]) / (grid[k + 1] - grid[k]);
        f[k] + lam * (f[k + 1] - f[k])
    }
}

/// Reads one channel's model from the output folder `dir` of `farma fit`: `channel`,
/// or the only channel fitted when `None`.
pub fn load_saved(dir: &Path, channel: Option<&str>) -> Result<SavedFarma> {
    let params_path = dir.join("params.parquet");
    let coef_path = dir.join("coef.parquet");
    let params = read_all(&params_path)?;
    let names = strings(&params, "channel", &params_path)?;
    let row = match channel {
        Some(c) => names.iter().position(|n| n == c).ok_or_else(|| {
            Error::column(
                &params_path,
                format!(
                    "no fitted channel '{c}'; fitted channels are: {}",
                    names.join(", ")
                ),
            )
        })?,
        None if names.len() == 1 => 0,
        None => {
            return Err(Error::column(
                &params_path,
                format!(
                    "{} channels were fitted ({}); name one with 'channel'",
                    names.len(),
                    names.join(", ")
                ),
            ));
        }
    };
    let name = names[row].clone();
    let int = |col: &str| -> Result<usize> {
        let v = ints(&params, col, &params_path)?[row];
        usize::try_from(v)
            .map_err(|_| Error::format(&params_path, format!("column '{col}': {v} is negative")))
    };
    let (p, q, d) = (int("p")?, int("q")?, int("d")?);
    let mean = floats(&params, "mean", &params_path)?[row];
    let sigma2 = floats(&params, "sigma2", &params_path)?[row];
    let b = list_row(&params, "b", row, &params_path)?;
    if b.len() != q {
        return Err(Error::format(
            &params_path,
            format!("channel '{name}': 'b' has {} values but q = {q}", b.len()),
        ));
    }
    if d == 0 {
        return Err(Error::format(
            &params_path,
            format!("channel '{name}': d = 0"),
        ));
    }
    if !(sigma2.is_finite() && sigma2 >= 0.0 && mean.is_finite())
        || b.iter().any(|v| !v.is_finite())
    {
        return Err(Error::format(
            &params_path,
            format!("channel '{name}': non-finite or negative mean, sigma2 or b"),
        ));
    }

    let coef = read_all(&coef_path)?;
    let cch = strings(&coef, "channel", &coef_path)?;
    let cm = ints(&coef, "m", &coef_path)?;
    let cg = floats(&coef, "grid", &coef_path)?;
    let cf = floats(&coef, "f", &coef_path)?;
    let mut pts: Vec<Vec<(f64, f64)>> = vec![Vec::new(); p];
    for i in 0..cch.len() {
        if cch[i] != name {
            continue;
        }
        let m = cm[i];
        if m < 1 || m as usize > p {
            return Err(Error::format(
                &coef_path,
                format!("channel '{name}': m = {m} outside 1..={p}"),
            ));
        }
        if !(cg[i].is_finite() && cf[i].is_finite()) {
            return Err(Error::format(
                &coef_path,
                format!("channel '{name}' m = {m}: non-finite grid or f value"),
            ));
        }
        pts[m as usize - 1].push((cg[i], cf[i]));
    }
    let mut grid = Vec::with_capacity(p);
    let mut f = Vec::with_capacity(p);
    for (m, mut v) in pts.into_iter().enumerate() {
        if v.is_empty() {
            return Err(Error::format(
                &coef_path,
                format!("channel '{name}': no rows for f_{}", m + 1),
            ));
        }
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        if v.windows(2).any(|w| w[0].0 == w[1].0) {
            return Err(Error::format(
                &coef_path,
                format!("channel '{name}': f_{} has a repeated grid point", m + 1),
            ));
        }
        grid.push(v.iter().map(|x| x.0).collect());
        f.push(v.iter().map(|x| x.1).collect());
    }
    Ok(SavedFarma {
        channel: name,
        p,
        q,
        d,
        b,
        mean,
        sigma2,
        grid,
        f,
    })
}

fn read_all(path: &Path) -> Result<Vec<RecordBatch>> {
    let file = std::fs::File::open(path).map_err(|e| Error::input_io(path, e))?;
    let bad = |e: parquet::errors::ParquetError| {
        Error::format(path, format!("not a farma fit table: {e}"))
    };
    let reader = ParquetRecordBatchReaderBuilder::try_new(file)
        .map_err(bad)?
        .build()
        .map_err(bad)?;
    reader
        .map(|b| b.map_err(|e| Error::format(path, format!("not a farma fit table: {e}"))))
        .collect()
}

fn column<'a, T: 'static>(batch: &'a RecordBatch, name: &str, path: &PathBuf) -> Result<&'a T> {
    let col = batch.column_by_name(name).ok_or_else(|| {
        Error::column(
            path,
            format!("no column '{name}' (is this a farma fit output?)"),
        )
    })?;
    col.as_any().downcast_ref::<T>().ok_or_else(|| {
        Error::column(
            path,
            format!(
                "column '{name}' has type {}, not the type farma fit writes",
                col.data_type()
            ),
        )
    })
}

fn strings(batches: &[RecordBatch], name: &str, path: &Path) -> Result<Vec<String>> {
    let path = path.to_path_buf();
    let mut out = Vec::new();
    for b in batches {
        let a: &StringArray = column(b, name, &path)?;
        out.extend((0..a.len()).map(|i| a.value(i).to_string()));
    }
    Ok(out)
}

fn ints(batches: &[RecordBatch], name: &str, path: &Path) -> Result<Vec<i64>> {
    let path = path.to_path_buf();
    let mut out = Vec::new();
    for b in batches {
        let a: &Int64Array = column(b, name, &path)?;
        out.extend(a.values().iter().copied());
    }
    Ok(out)
}

fn floats(batches: &[RecordBatch], name: &str, path: &Path) -> Result<Vec<f64>> {
    let path = path.to_path_buf();
    let mut out = Vec::new();
    for b in batches {
        let a: &Float64Array = column(b, name, &path)?;
        out.extend(a.values().iter().copied());
    }
    Ok(out)
}

fn list_row(batches: &[RecordBatch], name: &str, row: usize, path: &Path) -> Result<Vec<f64>> {
    let pathb = path.to_path_buf();
    let mut base = 0;
    for b in batches {
        let a: &ListArray = column(b, name, &pathb)?;
        if row < base + a.len() {
            let v = a.value(row - base);
            let f = v.as_any().downcast_ref::<Float64Array>().ok_or_else(|| {
                Error::column(path, format!("column '{name}' is not a list of float64"))
            })?;
            return Ok(f.values().to_vec());
        }
        base += a.len();
    }
    Err(Error::format(
        path,
        format!("column '{name}': row {row} missing"),
    ))
}
