//! The output resolution of a log: the grid step (LSB) its rate values sit on, when
//! they sit on one.

/// The step of the grid the values of `x` sit on, when they sit on one: an output
/// resolution (LSB) in the rate itself, which no component of the spec contract
/// reproduces (`quantization` is the IEEE 952 angle quantization, white in the
/// angle). The distinct values are sorted; the step is the smallest gap between
/// neighbours, and a grid is reported only when there are at most 1 % as many distinct
/// values as samples and every gap between neighbours is an integer multiple of the
/// step to 1e-6 of the step.
pub fn output_resolution(x: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = x.iter().copied().filter(|a| a.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    v.dedup();
    if v.len() < 2 || v.len() as f64 > 0.01 * x.len() as f64 {
        return None;
    }
    let step = v
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(f64::INFINITY, f64::min);
    if !step.is_finite() || step <= 0.0 {
        return None;
    }
    let on_grid = v.windows(2).all(|w| {
        let k = (w[1] - w[0]) / step;
        (k - k.round()).abs() <= 1e-6 * k.round().max(1.0)
    });
    on_grid.then_some(step)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_resolution_finds_the_lsb() {
        // rates rounded to a 0.05 grid, as an ADIS16405 writes them
        let x: Vec<f64> = (0..5000)
            .map(|k| (((k as f64 * 0.37).sin() * 0.8) / 0.05).round() * 0.05 + 0.4)
            .collect();
        let q = output_resolution(&x).unwrap();
        assert!((q - 0.05).abs() < 1e-9, "{q}");
        // continuous values: none
        let y: Vec<f64> = (0..5000).map(|k| (k as f64 * 0.37).sin()).collect();
        assert_eq!(output_resolution(&y), None);
    }
}
