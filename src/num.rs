//! Numeric primitives shared by the simulator and the diagnosis: rounding to an
//! integer grid as fast as the hot loops (quantizers, printed precision, value grids)
//! need it, with the standard library's result bit for bit.

/// `v` rounded to the nearest integer, halfway cases away from zero: the value and
/// sign of [`f64::round`] bit for bit (its slow twin, a library call on x86-64 without
/// SSE4.1), from the truncation by an integer conversion. Below 2^52 in magnitude the
/// conversion truncates exactly and the fraction v - trunc(v) is exact (Sterbenz), so
/// comparing it with 1/2 decides the rounding; the sign is copied from `v`, as -0.3
/// rounds to -0; from 2^52 on every double is an integer (and NaN, inf pass through).
#[inline]
pub fn round_half_away(v: f64) -> f64 {
    const TWO_52: f64 = 4_503_599_627_370_496.0;
    if v.abs() < TWO_52 {
        let t = (v as i64) as f64;
        let f = v - t;
        // selects, not branches: the fraction of noisy data is random
        let up = if f >= 0.5 { 1.0 } else { 0.0 };
        let down = if f <= -0.5 { 1.0 } else { 0.0 };
        (t + up - down).copysign(v)
    } else {
        v
    }
}

#[cfg(test)]
mod tests {
    use super::round_half_away;

    #[test]
    fn round_half_away_is_f64_round_bit_for_bit() {
        let two52 = 4_503_599_627_370_496.0f64;
        let mut vals = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.5,
            -1.5,
            2.5,
            -2.5,
            0.49999999999999994,
            -0.49999999999999994,
            0.3,
            -0.3,
            1.0 - f64::EPSILON,
            two52,
            -two52,
            two52 - 0.5,
            -(two52 - 0.5),
            two52 - 1.5,
            two52 * 2.0 + 2.0,
            1e300,
            -1e300,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            f64::MIN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        // every magnitude, on and off the halfway points
        let mut s = 11u64;
        for _ in 0..200_000 {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = (s >> 11) as f64 / (1u64 << 53) as f64;
            let mag = 2f64.powf(120.0 * u - 60.0);
            let v = if s & 1 == 0 { mag } else { -mag };
            vals.push(v);
            vals.push((v * 2.0).round() / 2.0);
            vals.push(f64::from_bits(s));
        }
        for v in vals {
            let (got, want) = (round_half_away(v), v.round());
            assert!(
                got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                "{v:e}: {got:e} against {want:e}"
            );
        }
    }
}
