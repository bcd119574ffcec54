//! Reading a channel's model back from its folder.
//!
//! Reads `params.parquet` (`channel`, `p`, `q`, `d`, `b` (list), `mean`, `sigma2`,
//! `bandwidth`) and `coef.parquet` (`channel`, `m`, `grid`, `f`, `se`, `filled`) as the
//! README's "farma fit" documents them. The grid is in the channel's units (the fit's
//! mean added back) and is kept so ([`crate::model::Coef::grid_shift`]), so f_m is
//! evaluated at exactly the values written. Every f_m of a channel must share one
//! grid (a fit writes one).

use arrow_array::{
    Array, BooleanArray, Float64Array, Int64Array, ListArray, RecordBatch, StringArray,
};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use std::path::Path;

use super::ModelDir;
use crate::error::{Error, Result};
use crate::model::{Coef, Farma, Order};

impl ModelDir {
    /// The channels fitted, in the order of params.parquet.
    pub fn channels(&self) -> Result<Vec<String>> {
        crate::output::settle(self.path())?;
        let pp = self.params_path();
        strings(&read_all(&pp)?, "channel", &pp)
    }

    /// The `index` of a 2-D fit's params.parquet metadata (`lag,CHANNEL`), if the
    /// folder holds one (None for a 1-D fit, or when there is no readable
    /// params.parquet).
    pub fn index2(&self) -> Option<String> {
        let file = std::fs::File::open(self.params_path()).ok()?;
        let builder = ParquetRecordBatchReaderBuilder::try_new(file).ok()?;
        let kv = builder.metadata().file_metadata().key_value_metadata()?;
        kv.iter()
            .find(|e| e.key == "index2")
            .and(kv.iter().find(|e| e.key == "index"))
            .and_then(|e| e.value.clone())
    }

    /// The log the folder's models were fitted on, as params.parquet's metadata records
    /// it (`source`, `source_size`, `source_mtime_ns`): (path, size, modification time
    /// in ns); None when it does not (a folder of an older farma, or unreadable).
    pub fn source(&self) -> Option<(String, u64, u128)> {
        let file = std::fs::File::open(self.params_path()).ok()?;
        let builder = ParquetRecordBatchReaderBuilder::try_new(file).ok()?;
        let kv = builder.metadata().file_metadata().key_value_metadata()?;
        let get = |k: &str| kv.iter().find(|e| e.key == k).and_then(|e| e.value.clone());
        Some((
            get("source")?,
            get("source_size")?.parse().ok()?,
            get("source_mtime_ns")?.parse().ok()?,
        ))
    }

    /// One channel's model: `channel`, or the only channel fitted when `None`; with the
    /// channel's name. Errors name the file and what is wrong: an unknown channel, a
    /// missing column, d = 0, non-finite values, a `b` whose length is not q, an f_m
    /// without rows, a repeated grid point, grids that differ between the f_m.
    pub fn load(&self, channel: Option<&str>) -> Result<(String, Farma)> {
        crate::output::settle(self.path())?;
        let params_path = self.params_path();
        let coef_path = self.coef_path();
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
            usize::try_from(v).map_err(|_| {
                Error::format(&params_path, format!("column '{col}': {v} is negative"))
            })
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
        let bandwidth = floats(&params, "bandwidth", &params_path)?[row];

        let coef = read_all(&coef_path)?;
        let cch = strings(&coef, "channel", &coef_path)?;
        let cm = ints(&coef, "m", &coef_path)?;
        let cg = floats(&coef, "grid", &coef_path)?;
        let cf = floats(&coef, "f", &coef_path)?;
        let cse = floats(&coef, "se", &coef_path)?;
        let cfilled = bools(&coef, "filled", &coef_path)?;
        // (grid, f, se, filled) per m
        let mut pts: Vec<Vec<(f64, f64, f64, bool)>> = vec![Vec::new(); p];
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
            pts[m as usize - 1].push((cg[i], cf[i], cse[i], cfilled[i]));
        }
        let mut grid: Vec<f64> = Vec::new();
        let mut filled: Vec<bool> = Vec::new();
        let mut per_m: Vec<Vec<(f64, f64, f64, bool)>> = Vec::with_capacity(p);
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
            if m == 0 {
                grid = v.iter().map(|x| x.0).collect();
                filled = v.iter().map(|x| x.3).collect();
            } else if v.len() != grid.len() || v.iter().zip(&grid).any(|(x, g)| x.0 != *g) {
                return Err(Error::format(
                    &coef_path,
                    format!(
                        "channel '{name}': the grid of f_{} differs from that of f_1 (a fit writes one grid for every f_m)",
                        m + 1
                    ),
                ));
            }
            per_m.push(v);
        }
        let g_n = grid.len();
        let mut f = vec![0.0; g_n * p];
        let mut se = vec![0.0; g_n * p];
        for (m, v) in per_m.iter().enumerate() {
            for (g, x) in v.iter().enumerate() {
                f[g * p + m] = x.1;
                se[g * p + m] = x.2;
            }
        }
        Ok((
            name,
            Farma {
                order: Order::new(p, q, d),
                mean,
                b,
                sigma2,
                bandwidth,
                coef: Coef {
                    grid,
                    grid_shift: mean,
                    f,
                    se,
                    filled,
                    second: None,
                },
            },
        ))
    }
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

fn column<'a, T: 'static>(batch: &'a RecordBatch, name: &str, path: &Path) -> Result<&'a T> {
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
    let mut out = Vec::new();
    for b in batches {
        let a: &StringArray = column(b, name, path)?;
        out.extend((0..a.len()).map(|i| a.value(i).to_string()));
    }
    Ok(out)
}

fn ints(batches: &[RecordBatch], name: &str, path: &Path) -> Result<Vec<i64>> {
    let mut out = Vec::new();
    for b in batches {
        let a: &Int64Array = column(b, name, path)?;
        out.extend(a.values().iter().copied());
    }
    Ok(out)
}

fn floats(batches: &[RecordBatch], name: &str, path: &Path) -> Result<Vec<f64>> {
    let mut out = Vec::new();
    for b in batches {
        let a: &Float64Array = column(b, name, path)?;
        out.extend(a.values().iter().copied());
    }
    Ok(out)
}

fn bools(batches: &[RecordBatch], name: &str, path: &Path) -> Result<Vec<bool>> {
    let mut out = Vec::new();
    for b in batches {
        let a: &BooleanArray = column(b, name, path)?;
        out.extend((0..a.len()).map(|i| a.value(i)));
    }
    Ok(out)
}

fn list_row(batches: &[RecordBatch], name: &str, row: usize, path: &Path) -> Result<Vec<f64>> {
    let mut base = 0;
    for b in batches {
        let a: &ListArray = column(b, name, path)?;
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
