//! The PSD job (`farma psd`, the batch task `psd`): every selected channel's one-sided
//! Welch power spectral density ([`crate::stats::psd`]: Hann window, 50 % overlap) on
//! the log's longest uniform segment, every bin or averaged in log-spaced bands; as a
//! folder, `psd.parquet`.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow_array::{ArrayRef, Float64Array, Int64Array, RecordBatch, StringArray};
use rayon::prelude::*;

use crate::error::Result;
use crate::output::{OutputSet, batch};
use crate::stats::psd::{Detrend, band_average, default_segment_len, welch};
use crate::store::Store;

/// The files a PSD folder holds.
pub const PSD_OUTPUTS: &[&str] = &["psd.parquet"];

/// Welch spectra of channels of one log.
#[derive(Clone, Debug)]
pub struct PsdJob {
    pub log: PathBuf,
    pub channels: Vec<String>,
    /// Segment length in samples (default: [`default_segment_len`] of the segment).
    pub segment_len: Option<usize>,
    pub detrend: Detrend,
    /// Log-spaced bands per decade to average in (0: every frequency bin).
    pub bands_per_decade: usize,
}

/// One channel's spectrum.
#[derive(Clone, Debug)]
pub struct ChannelPsd {
    pub channel: String,
    pub freq_hz: Vec<f64>,
    /// One-sided PSD, the channel's unit squared per Hz.
    pub psd: Vec<f64>,
    /// Frequency bins averaged in each row (1 without bands).
    pub n_bins: Vec<usize>,
    pub segment_len: usize,
    pub n_segments: usize,
}

impl PsdJob {
    /// The spectra of every channel in parallel on the rows `(start, len)`; every
    /// channel that fails is named at once.
    pub fn run(&self, store: &Store, (start, len): (usize, usize)) -> Result<Vec<ChannelPsd>> {
        let rate_hz = store.sample_rate_hz();
        let segment_len = self.segment_len.unwrap_or_else(|| default_segment_len(len));
        let bands = self.bands_per_decade;
        super::every_channel(
            self.channels
                .par_iter()
                .map(|name| {
                    let y = &store.column(name)?[start..start + len];
                    let what = format!("{}: channel '{name}'", self.log.display());
                    let p = welch(&what, y, rate_hz, segment_len, self.detrend)?;
                    let (freq_hz, psd, n_bins) = if bands == 0 {
                        let n = vec![1; p.psd.len()];
                        (p.freq_hz.clone(), p.psd.clone(), n)
                    } else {
                        let b = band_average(&p, bands);
                        (
                            b.iter().map(|x| x.freq_hz).collect(),
                            b.iter().map(|x| x.psd).collect(),
                            b.iter().map(|x| x.n_bins).collect(),
                        )
                    };
                    Ok(ChannelPsd {
                        channel: name.clone(),
                        freq_hz,
                        psd,
                        n_bins,
                        segment_len: p.segment_len,
                        n_segments: p.n_segments,
                    })
                })
                .collect(),
            "leave the failing ones out of --channel",
        )
    }

    /// The table's metadata: the method and its settings (segment counts are the same
    /// for every channel: same length, same segment length).
    pub fn metadata(&self, rate_hz: f64, first: &ChannelPsd) -> Vec<(&'static str, String)> {
        vec![
            ("log", self.log.display().to_string()),
            ("sample_rate_hz", rate_hz.to_string()),
            ("window", "hann".to_string()),
            ("overlap", "0.5".to_string()),
            ("segment_len", first.segment_len.to_string()),
            ("n_segments", first.n_segments.to_string()),
            ("detrend", detrend_name(self.detrend).to_string()),
            ("bands_per_decade", self.bands_per_decade.to_string()),
            ("unit", "u^2/Hz, one-sided".to_string()),
            ("farma.command", "psd".to_string()),
        ]
    }

    /// Writes `psd.parquet` into the folder `dir`.
    pub fn write(&self, dir: &Path, store: &Store, done: &[ChannelPsd]) -> Result<()> {
        let mut set = OutputSet::new(dir)?;
        let md = match done.first() {
            Some(f) => self.metadata(store.sample_rate_hz(), f),
            None => Vec::new(),
        };
        set.parquet("psd.parquet", &psd_table(done)?, &md)?;
        super::commit_outputs(set, PSD_OUTPUTS)
    }
}

/// `constant` or `none`.
pub fn detrend_name(d: Detrend) -> &'static str {
    match d {
        Detrend::Constant => "constant",
        Detrend::None => "none",
    }
}

/// The spectra: channel, freq_hz (Hz), psd (u^2/Hz), n_bins; one row per channel and
/// frequency.
pub fn psd_table(done: &[ChannelPsd]) -> Result<RecordBatch> {
    let (mut ch, mut f, mut p, mut nb) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for r in done {
        for i in 0..r.psd.len() {
            ch.push(r.channel.as_str());
            f.push(r.freq_hz[i]);
            p.push(r.psd[i]);
            nb.push(r.n_bins[i] as i64);
        }
    }
    batch(vec![
        ("channel", Arc::new(StringArray::from(ch)) as ArrayRef),
        ("freq_hz", Arc::new(Float64Array::from(f)) as ArrayRef),
        ("psd", Arc::new(Float64Array::from(p)) as ArrayRef),
        ("n_bins", Arc::new(Int64Array::from(nb)) as ArrayRef),
    ])
}
