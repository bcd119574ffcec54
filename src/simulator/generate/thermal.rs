//! Temperature-driven components: temperature_bias, thermal_rate, and the scale of
//! heteroskedastic noise. The temperature series (degC, one value per sample) comes
//! with the request.

use rayon::prelude::*;

/// Mean of the temperature series (the default reference temperature), by a
/// sequential sum (deterministic).
pub fn mean_c(temp_c: &[f64]) -> f64 {
    temp_c.iter().sum::<f64>() / temp_c.len() as f64
}

/// temperature_bias: sum_j coeffs[j-1] (T_k - reference_c)^j \[u\], by Horner's rule.
pub fn temperature_bias(out: &mut [f64], coeffs: &[f64], reference_c: f64, temp_c: &[f64]) {
    out.par_iter_mut()
        .zip(temp_c.par_iter())
        .for_each(|(o, t)| {
            let u = t - reference_c;
            *o += coeffs.iter().rev().fold(0.0, |acc, c| acc * u + c) * u;
        });
}

/// Half-width h (samples) of the centred moving average used by thermal_rate:
/// h = round(smoothing_s * rate_hz / 2), window 2h + 1 samples.
pub fn smoothing_half_width(smoothing_s: f64, rate_hz: f64) -> usize {
    (smoothing_s * rate_hz / 2.0).round() as usize
}

/// The temperature smoothed by a centred moving average over samples k-h ..= k+h,
/// truncated at the ends of the series (prefix sums, compensated).
pub fn smooth(temp_c: &[f64], h: usize) -> Vec<f64> {
    let n = temp_c.len();
    if h == 0 {
        return temp_c.to_vec();
    }
    // Prefix sums with Neumaier compensation (sum and correction kept apart).
    let mut s = vec![0.0; n + 1];
    let mut c = vec![0.0; n + 1];
    let (mut sum, mut comp) = (0.0f64, 0.0f64);
    for (i, &x) in temp_c.iter().enumerate() {
        let t = sum + x;
        if sum.abs() >= x.abs() {
            comp += (sum - t) + x;
        } else {
            comp += (x - t) + sum;
        }
        sum = t;
        s[i + 1] = sum;
        c[i + 1] = comp;
    }
    (0..n)
        .map(|k| {
            let lo = k.saturating_sub(h);
            let hi = (k + h + 1).min(n);
            ((s[hi] - s[lo]) + (c[hi] - c[lo])) / (hi - lo) as f64
        })
        .collect()
}

/// The temperature through a first-order lag of time constant `lag_s` (the exact
/// discretization of a lag driven by a signal held over each sample interval):
/// y_0 = T_0, y_k = a y_{k-1} + (1 - a) T_k with a = exp(-1 / (rate_hz lag_s)); the
/// series itself for lag_s = 0.
pub fn lagged(temp_c: &[f64], lag_s: f64, rate_hz: f64) -> std::borrow::Cow<'_, [f64]> {
    if lag_s <= 0.0 || temp_c.is_empty() {
        return std::borrow::Cow::Borrowed(temp_c);
    }
    let a = (-1.0 / (rate_hz * lag_s)).exp();
    let mut y = temp_c[0];
    std::borrow::Cow::Owned(
        temp_c
            .iter()
            .map(|&t| {
                y = a * y + (1.0 - a) * t;
                y
            })
            .collect(),
    )
}

/// thermal_rate: coeff * dS/dt \[u\], S the temperature smoothed over `smoothing_s`
/// ([`smooth`], half-width [`smoothing_half_width`]), dS/dt by the central difference
/// (S_{k+1} - S_{k-1}) rate_hz / 2, one-sided at the two ends (0 for one sample). The
/// Shupe effect of a fibre-optic gyro: a bias proportional to the rate of change of
/// temperature (Shupe, Appl. Opt. 19(5), 1980).
pub fn thermal_rate(out: &mut [f64], coeff: f64, smoothing_s: f64, rate_hz: f64, temp_c: &[f64]) {
    let s = smooth(temp_c, smoothing_half_width(smoothing_s, rate_hz));
    thermal_rate_from(out, coeff, rate_hz, &s, 0)
}

/// [`thermal_rate`] for the block of `out.len()` samples from sample `start`, given
/// the whole smoothed temperature `s` ([`smooth`]).
pub fn thermal_rate_from(out: &mut [f64], coeff: f64, rate_hz: f64, s: &[f64], start: usize) {
    let n = s.len();
    if n < 2 {
        return;
    }
    for (j, o) in out.iter_mut().enumerate() {
        let k = start + j;
        let d = if k == 0 {
            (s[1] - s[0]) * rate_hz
        } else if k == n - 1 {
            (s[n - 1] - s[n - 2]) * rate_hz
        } else {
            (s[k + 1] - s[k - 1]) * rate_hz / 2.0
        };
        *o += coeff * d;
    }
}

/// heteroskedastic scale at each sample: max(floor, 1 + slope (T_k - reference_c)),
/// the reference being the component's `reference_c` or else the log's mean
/// temperature, `floor` in [0, 1) (0: a noise scale is
/// not negative; above 0: a sensor's noise levels off rather than vanishing).
pub fn scale(slope: f64, floor: f64, reference_c: f64, temp_c: &[f64]) -> Vec<f64> {
    temp_c
        .iter()
        .map(|t| (1.0 + slope * (t - reference_c)).max(floor))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lag_gives_the_first_order_step_response() {
        // a unit step at sample 1: y_k = 1 - a^k, a = exp(-dt / lag_s)
        let (fs, lag_s) = (10.0, 3.0);
        let t: Vec<f64> = (0..100).map(|k| if k == 0 { 0.0 } else { 1.0 }).collect();
        let y = lagged(&t, lag_s, fs);
        let a = (-1.0 / (fs * lag_s)).exp();
        for (k, v) in y.iter().enumerate() {
            assert!((v - (1.0 - a.powi(k as i32))).abs() < 1e-14, "{k}: {v}");
        }
        assert_eq!(&*lagged(&t, 0.0, fs), &t[..]);
    }
}
