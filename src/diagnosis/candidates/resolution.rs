//! The output resolution of a log: the grid step (LSB) its rate values sit on, when
//! they sit on one.

use super::output_path::value_grid;

/// The step of the grid the values of `x` sit on, when they sit on one: an output
/// resolution (LSB) in the rate itself, the spec's `output_resolution` (not the
/// IEEE 952 `quantization`, white in the angle). The grid is
/// [`value_grid`]'s (robust to float printing noise), reported here only when there
/// are at most 1 % as many distinct values as samples and its step is not a power of
/// ten (which may be the precision the log was printed with).
pub fn output_resolution(x: &[f64]) -> Option<f64> {
    let g = value_grid(x).present()?;
    (g.levels as f64 <= 0.01 * x.len() as f64 && !g.decimal).then_some(g.quantum)
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
