//! Numbers in messages: a bounded number of digits. `{}` of an f64 prints every digit
//! of its shortest round-trip form, which for 1e300 or 1e-300 written out in full is
//! hundreds of characters; [`num`] gives at most 7 significant digits, in scientific
//! notation outside [1e-4, 1e7).

/// `v` with at most 7 significant digits: `10`, `0.5`, `1234567`, `1.5e300`,
/// `-2.5e-8`, `NaN`, `inf`.
pub fn num(v: f64) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if (1e-4..1e7).contains(&a) {
        let decimals = (6 - a.log10().floor() as i32).clamp(0, 10) as usize;
        let s = format!("{v:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        let s = format!("{v:.6e}");
        match s.split_once('e') {
            Some((m, e)) if m.contains('.') => {
                format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.'))
            }
            _ => s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::num;

    #[test]
    fn numbers_have_a_bounded_number_of_digits() {
        assert_eq!(num(10.0), "10");
        assert_eq!(num(0.5), "0.5");
        assert_eq!(num(1e300), "1e300");
        assert_eq!(num(-2.5e-8), "-2.5e-8");
        assert_eq!(num(1234567.0), "1234567");
        assert_eq!(num(1.0 / 3.0), "0.3333333");
        assert_eq!(num(f64::MAX), "1.797693e308");
        assert_eq!(num(f64::INFINITY), "inf");
        assert_eq!(num(0.0), "0");
        for v in [
            1e-300,
            1e300,
            123.456e200,
            f64::MIN_POSITIVE,
            7.0e-5,
            9999999.5,
        ] {
            assert!(num(v).len() <= 14, "{v}: {}", num(v));
        }
    }
}
