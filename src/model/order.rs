//! The order (p, q, d) of a FARMA model: p autoregressive lags with coefficient
//! functions f_1..f_p, q moving-average lags b_1..b_q, and the delay d of the index
//! x_{t-d}. Parsed from the command line's `p,q,d` once, and bounded once.

use std::fmt;

use crate::error::{Error, Result};

/// Most autoregressive lags (p) and moving-average lags (q) a fit takes: the local
/// systems are 2p x 2p and the b-step q x q per sample.
pub const MAX_PQ: usize = 6;
/// Largest delay d of the index x_{t-d}.
pub const MAX_D: usize = 1000;

/// FARMA(p,q,d).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Order {
    pub p: usize,
    pub q: usize,
    pub d: usize,
}

/// Why an order cannot be fitted (see [`Order::bounds`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutOfBounds {
    /// p = 0 or d = 0.
    Zero,
    /// p or q above [`MAX_PQ`], or d above [`MAX_D`].
    TooLarge,
}

impl Order {
    pub fn new(p: usize, q: usize, d: usize) -> Order {
        Order { p, q, d }
    }

    /// max(p, q, d): the first row of the regression (samples before it have no lags).
    pub fn lag(&self) -> usize {
        self.p.max(self.q).max(self.d)
    }

    /// `p,q,d` (blanks around each number allowed), syntax only; `None` unless three
    /// non-negative integers.
    pub fn parse(s: &str) -> Option<Order> {
        let v: Vec<Option<usize>> = s.split(',').map(|x| x.trim().parse().ok()).collect();
        match v.as_slice() {
            [Some(p), Some(q), Some(d)] => Some(Order::new(*p, *q, *d)),
            _ => None,
        }
    }

    /// `--order`: one `p,q,d`, syntax only (the fit checks the bounds against the series).
    pub fn parse_flag(s: &str) -> Result<Order> {
        Order::parse(s).ok_or_else(|| {
            Error::Usage(format!(
                "--order: '{s}' is not p,q,d (three non-negative integers, e.g. 2,1,1)"
            ))
        })
    }

    /// `--orders`: `p,q,d;p,q,d;...`, each within the fit's bounds; an order given
    /// twice is kept once, blank items are skipped.
    pub fn parse_list(s: &str) -> Result<Vec<Order>> {
        let mut out: Vec<Order> = Vec::new();
        for item in s.split(';').map(str::trim).filter(|x| !x.is_empty()) {
            let o = Order::parse(item).ok_or_else(|| {
                Error::Usage(format!(
                    "--orders: '{item}' is not p,q,d (orders separated by ';', e.g. '1,1,1;2,1,1')"
                ))
            })?;
            match o.bounds() {
                Some(OutOfBounds::Zero) => {
                    return Err(Error::Usage(format!(
                        "--orders: '{item}': p and d must be at least 1"
                    )));
                }
                Some(OutOfBounds::TooLarge) => {
                    return Err(Error::Usage(format!(
                        "--orders: '{item}': p, q at most {MAX_PQ} and d at most {MAX_D}"
                    )));
                }
                None if !out.contains(&o) => out.push(o),
                None => {}
            }
        }
        if out.is_empty() {
            return Err(Error::Usage("--orders: no order given".into()));
        }
        Ok(out)
    }

    /// `None` when the order can be fitted: p >= 1, d >= 1, p, q <= [`MAX_PQ`],
    /// d <= [`MAX_D`].
    pub fn bounds(&self) -> Option<OutOfBounds> {
        if self.p == 0 || self.d == 0 {
            Some(OutOfBounds::Zero)
        } else if self.p > MAX_PQ || self.q > MAX_PQ || self.d > MAX_D {
            Some(OutOfBounds::TooLarge)
        } else {
            None
        }
    }
}

/// `p,q,d`, as `--order` takes it.
impl fmt::Display for Order {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{},{},{}", self.p, self.q, self.d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_bounds() {
        assert_eq!(Order::parse(" 2, 1 ,1"), Some(Order::new(2, 1, 1)));
        assert_eq!(Order::parse("2,1"), None);
        assert_eq!(Order::parse("2,-1,1"), None);
        assert_eq!(Order::new(0, 1, 1).bounds(), Some(OutOfBounds::Zero));
        assert_eq!(Order::new(7, 1, 1).bounds(), Some(OutOfBounds::TooLarge));
        assert_eq!(Order::new(6, 6, 1000).bounds(), None);
        assert_eq!(Order::new(3, 2, 1).lag(), 3);
        assert_eq!(Order::new(3, 2, 1).to_string(), "3,2,1");
        let l = Order::parse_list("1,1,1; 2,1,1;1,1,1;").unwrap();
        assert_eq!(l, vec![Order::new(1, 1, 1), Order::new(2, 1, 1)]);
        assert!(Order::parse_list(";").is_err());
        assert!(Order::parse_list("0,1,1").is_err());
        assert!(Order::parse_list("1,1").is_err());
    }
}
