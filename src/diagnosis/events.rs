//! Test-stand events: shocks that every channel of a log sees at once (a knock on the
//! stand, a door slammed), found in the log and kept out of the gap diagnosis. They are
//! properties of the test, not of the sensor, and the simulator is not asked to
//! reproduce them: the multi-channel analogue of the Pauta (3-sigma) outlier cleaning
//! that starts the usual workflow.
//!
//! **Detection.** For each scanned channel `x`, the first differences
//! `d_t = x_t - x_{t-1}` are standardised robustly:
//! `z_t = |d_t - median(d)| / s`, with `s = 1.4826 * median(|d - median(d)|)` (the MAD,
//! a standard deviation for Gaussian differences); on a quantized channel whose
//! differences are mostly one value the MAD is 0, and `s` is then the plain standard
//! deviation of the differences (a channel with no spread at all has no exceedances).
//! An event is a time `t` where the diagnosed channel's `z_t > K_SD` ([`K_SD`] = 8:
//! for Gaussian differences a false-positive rate of `P(|Z| > 8) = 1.2e-15` per
//! sample) AND, within the coincidence window `+-` [`WINDOW_S`] (0.1 s, in samples
//! from the rate, at least 1), at least two other channels cross [`K_CONFIRM_SD`]
//! (5 sd, `P(|Z| > 5) = 5.7e-7` per sample: a channel's chance crossing in a window of
//! 21 samples is about 1.2e-5, two of five others about 1.4e-9) AND at least half of
//! all the channels scanned (the diagnosed one counted) do. The confirmation is lower
//! than the trigger because a knock's size differs between axes (ADIS16405 run 4's
//! first knock: 13 sd on gyro x, 7.3 sd on gyro y, 6 sd on accel x). A sensor's own
//! effect on one channel (an outlier, a bias step, a burst of noise) is on one
//! channel only and is never an event; a log of fewer than three channels has none.
//!
//! **Span.** From the first to the last crossing (any channel) of the coincident
//! groups, merged when they overlap; widened while the diagnosed channel stays beyond
//! [`K_LOW_SD`] (3 robust sd: the shock's ringing), a quiet stretch shorter than the
//! window not ending it; then [`SETTLE_S`] (1 s) more on each side for the mount to
//! settle. Spans that then overlap are merged.
//!
//! **Exclusion.** Each span of every channel the diagnosis reads (the diagnosed one and
//! its cross-axis channels; the temperature is slow and not touched) is replaced by
//! the same-length stretch just before it (just after it for a span too close to the
//! start). Dropping the spans from the real and the simulated features alike was the
//! other way; replacement was chosen because it keeps the time base, the block layout
//! and every statistic's definition (an Allan variance or a PSD over a cut would join
//! two stretches that were never adjacent) and leaves the simulations untouched, at the
//! price of a few seconds of the log counted twice; the copied stretch has the
//! sensor's own noise, resolution and cross-axis coupling.

use crate::error::{Error, Result};

/// Robust standard deviations the diagnosed channel's first difference must exceed
/// to start an event.
pub const K_SD: f64 = 8.0;
/// Robust standard deviations another channel's first difference must exceed, within
/// the coincidence window, to confirm it.
pub const K_CONFIRM_SD: f64 = 5.0;
/// Robust standard deviations the diagnosed channel's first differences stay beyond
/// while the span is widened.
pub const K_LOW_SD: f64 = 3.0;
/// Half-width of the coincidence window, seconds.
pub const WINDOW_S: f64 = 0.1;
/// Settling margin added on each side of a span, seconds.
pub const SETTLE_S: f64 = 1.0;

/// One test-stand event: a span of the log kept out of the diagnosis.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Event {
    /// First sample of the span.
    pub start: usize,
    /// One past its last sample.
    pub end: usize,
    /// The span in seconds from the log's first sample (`end_s` exclusive).
    pub start_s: f64,
    pub end_s: f64,
    /// The channels whose first differences crossed [`K_CONFIRM_SD`] in the
    /// coincident groups, the diagnosed one first, then in the log's order.
    pub channels: Vec<String>,
    /// The largest robust z of the diagnosed channel's first differences in the span.
    pub peak_sd: f64,
}

/// The robust z-scores of the first differences of `x` (`z[t]` for the step from
/// `x[t-1]` to `x[t]`; `z[0] = 0`); all zero for a channel with no spread.
pub fn robust_z(x: &[f64]) -> Vec<f64> {
    let n = x.len();
    if n < 3 {
        return vec![0.0; n];
    }
    let d: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
    let med = median(&d);
    let dev: Vec<f64> = d.iter().map(|v| (v - med).abs()).collect();
    let mut s = 1.4826 * median(&dev);
    if s.is_nan() || s <= 0.0 {
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        s = (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (d.len() - 1) as f64).sqrt();
    }
    let mut z = vec![0.0; n];
    if s.is_finite() && s > 0.0 {
        for (t, v) in dev.iter().enumerate() {
            z[t + 1] = v / s;
        }
    }
    z
}

fn median(v: &[f64]) -> f64 {
    let mut w = v.to_vec();
    let m = w.len() / 2;
    let (_, hi, _) = w.select_nth_unstable_by(m, |a, b| a.total_cmp(b));
    let hi = *hi;
    if w.len() % 2 == 1 {
        hi
    } else {
        let lo = w[..m].iter().copied().fold(f64::NEG_INFINITY, f64::max);
        0.5 * (lo + hi)
    }
}

/// The events of a log: `x` the diagnosed channel (named `name`), `scan` the other
/// channels scanned (every numeric column but the time and temperature columns), all
/// of `x`'s length, sampled at `rate_hz`. Empty when fewer than two other channels
/// are scanned.
pub fn detect(name: &str, x: &[f64], scan: &[(String, &[f64])], rate_hz: f64) -> Vec<Event> {
    let n = x.len();
    if scan.len() < 2 || n < 3 {
        return Vec::new();
    }
    let w = ((WINDOW_S * rate_hz).round() as usize).max(1);
    let settle = (SETTLE_S * rate_hz).round() as usize;
    let z0 = robust_z(x);
    // each channel's crossings of the confirmation level, sorted: the diagnosed
    // channel's first
    let crossings = |z: &[f64]| -> Vec<usize> { (0..n).filter(|&t| z[t] > K_CONFIRM_SD).collect() };
    let hits: Vec<Vec<usize>> = std::iter::once(crossings(&z0))
        .chain(scan.iter().map(|(_, v)| crossings(&robust_z(v))))
        .collect();
    let triggers = (0..n).filter(|&t| z0[t] > K_SD);
    let n_ch = hits.len();
    // the exceedances of channel c within [lo, hi]
    let within = |c: usize, lo: usize, hi: usize| -> &[usize] {
        let h = &hits[c];
        let a = h.partition_point(|&t| t < lo);
        let b = h.partition_point(|&t| t <= hi);
        &h[a..b]
    };
    // coincident groups: (first, last exceedance of any channel, channels crossed)
    let mut groups: Vec<(usize, usize, Vec<bool>)> = Vec::new();
    for t in triggers {
        let (lo, hi) = (t.saturating_sub(w), t + w);
        let crossed: Vec<bool> = (0..n_ch).map(|c| !within(c, lo, hi).is_empty()).collect();
        let count = crossed.iter().filter(|b| **b).count();
        if count < 3 || 2 * count < n_ch {
            continue;
        }
        let first = (0..n_ch).map(|c| within(c, lo, hi)[..].first().copied());
        let first = first.flatten().min().unwrap_or(t);
        let last = (0..n_ch).map(|c| within(c, lo, hi).last().copied());
        let last = last.flatten().max().unwrap_or(t);
        match groups.last_mut() {
            Some(g) if first <= g.1 + w => {
                g.1 = g.1.max(last);
                g.0 = g.0.min(first);
                g.2.iter_mut().zip(&crossed).for_each(|(a, b)| *a |= b);
            }
            _ => groups.push((first, last, crossed)),
        }
    }
    let mut events: Vec<Event> = Vec::new();
    for (first, last, crossed) in groups {
        // the step t is between samples t-1 and t: both belong to the span
        let mut a = first.saturating_sub(1);
        let mut b = last;
        // widened while the diagnosed channel rings
        loop {
            let lo = a.saturating_sub(w);
            match (lo..a).rev().find(|&t| z0[t] > K_LOW_SD) {
                Some(t) if t > 0 => a = t - 1,
                _ => break,
            }
        }
        loop {
            let hi = (b + w).min(n - 1);
            match (b + 1..=hi).rev().find(|&t| z0[t] > K_LOW_SD) {
                Some(t) => b = t,
                None => break,
            }
        }
        let start = a.saturating_sub(settle);
        let end = (b + 1 + settle).min(n);
        let peak = (start..end).map(|t| z0[t]).fold(0.0, f64::max);
        let names: Vec<String> = std::iter::once(name.to_string())
            .chain(scan.iter().map(|(s, _)| s.clone()))
            .zip(&crossed)
            .filter(|(_, c)| **c)
            .map(|(s, _)| s)
            .collect();
        match events.last_mut() {
            Some(e) if start <= e.end => {
                e.end = e.end.max(end);
                e.peak_sd = e.peak_sd.max(peak);
                for s in names {
                    if !e.channels.contains(&s) {
                        e.channels.push(s);
                    }
                }
            }
            _ => events.push(Event {
                start,
                end,
                start_s: 0.0,
                end_s: 0.0,
                channels: names,
                peak_sd: peak,
            }),
        }
    }
    let order: Vec<&str> = std::iter::once(name)
        .chain(scan.iter().map(|(s, _)| s.as_str()))
        .collect();
    for e in &mut events {
        e.start_s = e.start as f64 / rate_hz;
        e.end_s = e.end as f64 / rate_hz;
        e.channels
            .sort_by_key(|s| order.iter().position(|o| o == s).unwrap_or(usize::MAX));
    }
    events
}

/// `x` with each event's span replaced by the same-length stretch just before it, or
/// just after it when the log before is shorter than the span (spans in time order,
/// earlier spans replaced first, so that a copied stretch is itself clean).
pub fn replaced(x: &[f64], events: &[Event]) -> Result<Vec<f64>> {
    let mut y = x.to_vec();
    let n = y.len();
    let mut after = Vec::new();
    for e in events {
        let len = e.end - e.start;
        if e.start >= len {
            y.copy_within(e.start - len..e.start, e.start);
        } else {
            after.push(e);
        }
    }
    for e in after.into_iter().rev() {
        let len = e.end - e.start;
        if e.end + len > n {
            return Err(Error::Data(format!(
                "a test-stand event spans {:.2} to {:.2} s, longer than the log before and after it: \
                 nothing to replace it with (use --keep-events)",
                e.start_s, e.end_s
            )));
        }
        y.copy_within(e.end..e.end + len, e.start);
    }
    Ok(y)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_distr::StandardNormal;

    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        (0..n)
            .map(|_| rng.sample::<f64, _>(StandardNormal))
            .collect()
    }

    /// Three channels of white noise at 100 Hz, a damped burst on `on` of them from
    /// sample 5000 (0.3 s of ringing).
    fn log(on: &[usize]) -> Vec<Vec<f64>> {
        let mut ch: Vec<Vec<f64>> = (0..3).map(|c| noise(20_000, c as u64 + 1)).collect();
        for &c in on {
            for k in 0..30 {
                let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
                ch[c][5000 + k] += sign * 200.0 * (-(k as f64) / 6.0).exp();
            }
        }
        ch
    }

    fn scan(ch: &[Vec<f64>]) -> Vec<(String, &[f64])> {
        ch[1..]
            .iter()
            .enumerate()
            .map(|(i, v)| (format!("c{}", i + 1), v.as_slice()))
            .collect()
    }

    #[test]
    fn a_burst_on_every_channel_is_one_event_with_its_span() {
        let ch = log(&[0, 1, 2]);
        let ev = detect("c0", &ch[0], &scan(&ch), 100.0);
        assert_eq!(ev.len(), 1, "{ev:?}");
        let e = &ev[0];
        assert_eq!(e.channels, ["c0", "c1", "c2"]);
        // the burst covers samples 5000..5030; its ringing falls below 3 sd (of
        // differences of unit white noise, sd sqrt 2) after about 20 samples; plus 1 s
        assert!(
            (4899..=4900).contains(&e.start) && (5115..=5131).contains(&e.end),
            "{e:?}"
        );
        assert_eq!(e.start_s, e.start as f64 / 100.0);
        assert!(e.peak_sd > 100.0, "{e:?}");
        // replaced by the stretch before: the burst is gone
        let y = replaced(&ch[0], &ev).unwrap();
        assert_eq!(&y[e.start..e.end], &ch[0][2 * e.start - e.end..e.start]);
        assert_eq!(&y[..e.start], &ch[0][..e.start]);
        assert_eq!(&y[e.end..], &ch[0][e.end..]);
        assert!(y.iter().all(|v| v.abs() < 6.0));
    }

    #[test]
    fn a_burst_on_one_channel_or_not_on_the_diagnosed_one_is_no_event() {
        for on in [&[0][..], &[1], &[1, 2], &[0, 1]] {
            let ch = log(on);
            let ev = detect("c0", &ch[0], &scan(&ch), 100.0);
            assert!(ev.is_empty(), "burst on {on:?}: {ev:?}");
        }
        // a single-channel log has no events
        let ch = log(&[0]);
        assert!(detect("c0", &ch[0], &[], 100.0).is_empty());
    }

    #[test]
    fn a_bias_step_on_the_diagnosed_channel_is_no_event() {
        let mut ch = log(&[]);
        for v in &mut ch[0][8000..] {
            *v += 50.0;
        }
        assert!(detect("c0", &ch[0], &scan(&ch), 100.0).is_empty());
        // the step seen on one other channel too: still short of two others
        for v in &mut ch[1][8000..] {
            *v += 50.0;
        }
        assert!(detect("c0", &ch[0], &scan(&ch), 100.0).is_empty());
    }

    #[test]
    fn gaussian_noise_on_four_channels_has_no_event() {
        let ch: Vec<Vec<f64>> = (0..4).map(|c| noise(1_000_000, 10 + c)).collect();
        let scan: Vec<(String, &[f64])> = ch[1..]
            .iter()
            .map(|v| ("o".to_string(), v.as_slice()))
            .collect();
        assert!(detect("c0", &ch[0], &scan, 100.0).is_empty());
    }

    #[test]
    fn the_other_channels_confirm_at_the_lower_level() {
        // a 12-sd step on the diagnosed channel; on the two others a step of
        // `other_sd` robust sd (differences of unit white noise: sd sqrt 2)
        let found = |other_sd: f64| {
            let mut ch: Vec<Vec<f64>> = (0..3).map(|c| noise(20_000, 50 + c)).collect();
            for (c, v) in ch.iter_mut().enumerate() {
                let sd = if c == 0 { 12.0 } else { other_sd };
                v[9000] += sd * 2f64.sqrt();
            }
            !detect("c0", &ch[0], &scan(&ch), 100.0).is_empty()
        };
        assert!(found(7.5));
        assert!(!found(2.5));
    }

    #[test]
    fn half_of_the_channels_must_cross() {
        // seven channels, the burst on three (the diagnosed one and two others): short
        // of half; on four: an event
        let mut ch: Vec<Vec<f64>> = (0..7).map(|c| noise(20_000, 30 + c)).collect();
        let burst = |v: &mut Vec<f64>| {
            for k in 0..5 {
                v[7000 + k] += 100.0;
            }
        };
        for v in ch.iter_mut().take(3) {
            burst(v);
        }
        let sc = |ch: &[Vec<f64>]| -> Vec<(String, Vec<f64>)> {
            ch[1..]
                .iter()
                .enumerate()
                .map(|(i, v)| (format!("c{}", i + 1), v.clone()))
                .collect()
        };
        let owned = sc(&ch);
        let s: Vec<(String, &[f64])> = owned.iter().map(|(a, b)| (a.clone(), &b[..])).collect();
        assert!(detect("c0", &ch[0], &s, 100.0).is_empty());
        burst(&mut ch[3]);
        let owned = sc(&ch);
        let s: Vec<(String, &[f64])> = owned.iter().map(|(a, b)| (a.clone(), &b[..])).collect();
        let ev = detect("c0", &ch[0], &s, 100.0);
        assert_eq!(ev.len(), 1, "{ev:?}");
        assert_eq!(ev[0].channels, ["c0", "c1", "c2", "c3"]);
    }

    #[test]
    fn a_quantized_channel_uses_the_sd_of_its_differences() {
        // mostly constant: the MAD of the differences is 0
        let mut x = vec![0.0; 10_000];
        for (t, v) in x.iter_mut().enumerate() {
            if t % 10 == 0 {
                *v = 1.0;
            }
        }
        let z = robust_z(&x);
        assert!(z.iter().all(|v| v.is_finite() && *v < K_SD));
        assert!(z.iter().any(|v| *v > 0.0));
        // a constant channel has no exceedance
        assert!(robust_z(&[2.0; 100]).iter().all(|v| *v == 0.0));
    }

    #[test]
    fn a_span_at_the_start_is_replaced_by_the_stretch_after() {
        let x: Vec<f64> = (0..100).map(|t| t as f64).collect();
        let e = Event {
            start: 0,
            end: 10,
            start_s: 0.0,
            end_s: 0.1,
            channels: vec![],
            peak_sd: 0.0,
        };
        let y = replaced(&x, std::slice::from_ref(&e)).unwrap();
        assert_eq!(&y[..10], &x[10..20]);
        let long = Event { end: 60, ..e };
        assert!(replaced(&x, &[long]).is_err());
    }
}
