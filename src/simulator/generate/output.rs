//! The sensor's output path: what a gyro does to the sum of its error components
//! before it writes a sample, in this order (a sensor's output chain):
//! 1. `output_filter`: a first- or second-order low-pass ([`LowPass`]), or a finite
//!    impulse response ([`Fir`], `form = "fir"`);
//! 2. `saturation`: each sample clamped to \[-limit, limit\] (the measurement range);
//! 3. `output_resolution`: each sample rounded to a multiple of the quantum (the LSB),
//!    or the integrated angle quantized and the rate its first difference ([`Quantizer`]).
//!
//! Every stage carries its state (the filter's, the angle's rounding error) from one
//! block to the next, so that a simulation by blocks gives the whole series' values
//! bit for bit whatever the block size.
//!
//! The filter is the zero-order-hold discretization of the continuous filter: the input
//! sample x_t is held over the interval ((t-1) dt, t dt] and the output y_t is the
//! filter's state at its end. For order 1, dy/dt = w_c (x - y) with w_c = 2 pi
//! bandwidth_hz gives y_t = a y_{t-1} + (1 - a) x_t, a = exp(-w_c dt) (the
//! exact sampled first-order lag, the recursion of a Gauss-Markov process; its power
//! response is (1 - a)^2 / (1 - 2 a cos w + a^2), w = 2 pi f dt). For order 2,
//! p'' + 2 z w_n p' + w_n^2 p = w_n^2 x with w_n = 2 pi bandwidth_hz and damping z,
//! in state form s = (p, p'), s' = A s + B x, A = \[\[0, 1\], \[-w_n^2, -2 z w_n\]\],
//! B = (0, w_n^2): s_t = Ad s_{t-1} + Bd x_t, y_t = p_t, with Ad = exp(A dt) and
//! Bd = A^-1 (Ad - I) B (Franklin, Powell & Workman, *Digital Control of Dynamic
//! Systems*, 3rd ed., section 4.3.3). exp(A dt) is closed form: with
//! s = z w_n and (A + s I)^2 = (s^2 - w_n^2) I,
//! exp(A dt) = e^(-s dt) \[c I + g (A + s I)\] where, with b^2 = |s^2 - w_n^2|,
//! c = cos(b dt), g = sin(b dt) / b (z < 1), c = cosh(b dt), g = sinh(b dt) / b
//! (z > 1, computed from the two real poles so nothing overflows) and c = 1, g = dt
//! (z = 1). Both orders have unit gain at 0 Hz and become the identity as the bandwidth
//! grows: a bandwidth above the Nyquist frequency is allowed (and changes little).
//! The power response at frequency f is |H(e^(i w))|^2 with H(z) = C (I - Ad z^-1)^-1 Bd
//! ([`LowPass::power_response`]), what the diagnosis fits to a PSD's roll-off.
//!
//! With `discretization = "bilinear"` the filter is instead the bilinear transform
//! s = 2 f_s (1 - z^-1) / (1 + z^-1) of the continuous one at the prewarped natural
//! frequency 2 f_s tan(pi bandwidth_hz / f_s), so that the digital response at
//! bandwidth_hz equals the analog one there (Oppenheim & Schafer, *Discrete-Time
//! Signal Processing*, 3rd ed., section 7.2.2; what scipy.signal.butter(order, fc,
//! fs=fs) and MATLAB's butter design). With K = tan(pi bandwidth_hz / f_s):
//! order 1, H(z) = K (1 + z^-1) / ((1 + K) + (K - 1) z^-1); order 2 (damping z),
//! H(z) = K^2 (1 + z^-1)^2 / (a0 + a1 z^-1 + a2 z^-2) with a0 = 1 + 2 z K + K^2,
//! a1 = 2 (K^2 - 1), a2 = 1 - 2 z K + K^2. Unit gain at 0 Hz, a zero at the Nyquist
//! frequency (the transform maps s = infinity to z = -1), run in transposed direct
//! form II.
//!
//! The FIR form is y_t = sum_k h_k x_{t-k} (what scipy.signal.lfilter(h, \[1\], x)
//! computes), the inputs before the first sample taken as zero, the last len(h) - 1
//! inputs carried from block to block; its power response is |sum_k h_k e^(-i k w)|^2,
//! its DC gain sum_k h_k.

use std::f64::consts::PI;

use crate::simulator::spec::{Component, DEFAULT_DAMPING, Discretization, Kind};

/// A discretized low-pass output filter with its state.
#[derive(Clone, Debug, PartialEq)]
pub struct LowPass {
    /// Ad (row major) and Bd of the state recursion; order 1 uses ad\[0\]\[0\], bd\[0\].
    ad: [[f64; 2]; 2],
    bd: [f64; 2],
    order: usize,
    /// The bilinear filter's coefficients (b0, b1, b2) and (a1, a2) (a0 = 1), run in
    /// place of the state recursion when present.
    iir: Option<([f64; 3], [f64; 2])>,
    /// The state after the last sample: (p, p') of the state recursion, or the two
    /// delays of the transposed direct form II; (0, 0) before the first.
    state: [f64; 2],
}

impl LowPass {
    /// The filter of `order` (1 or 2) at natural frequency `bandwidth_hz` with
    /// `damping` (order 2; None: 1/sqrt(2)) for samples at `rate_hz` (module doc).
    pub fn new(order: usize, bandwidth_hz: f64, damping: Option<f64>, rate_hz: f64) -> Self {
        Self::with(order, bandwidth_hz, damping, Discretization::Zoh, rate_hz)
    }

    /// [`LowPass::new`] discretized as `disc` says (module doc). A bilinear filter's
    /// bandwidth is held below 0.499999 of the rate (validation refuses one at or
    /// above the Nyquist frequency).
    pub fn with(
        order: usize,
        bandwidth_hz: f64,
        damping: Option<f64>,
        disc: Discretization,
        rate_hz: f64,
    ) -> Self {
        if disc == Discretization::Bilinear {
            let k = (std::f64::consts::PI * bandwidth_hz.min(0.499_999 * rate_hz) / rate_hz).tan();
            let (b, a) = if order <= 1 {
                let g = k / (1.0 + k);
                ([g, g, 0.0], [(k - 1.0) / (k + 1.0), 0.0])
            } else {
                let z = damping.unwrap_or(DEFAULT_DAMPING);
                let a0 = 1.0 + 2.0 * z * k + k * k;
                let g = k * k / a0;
                (
                    [g, 2.0 * g, g],
                    [2.0 * (k * k - 1.0) / a0, (1.0 - 2.0 * z * k + k * k) / a0],
                )
            };
            return LowPass {
                ad: [[0.0; 2]; 2],
                bd: [0.0; 2],
                order: order.clamp(1, 2),
                iir: Some((b, a)),
                state: [0.0; 2],
            };
        }
        let dt = 1.0 / rate_hz;
        let wn = 2.0 * PI * bandwidth_hz;
        if order <= 1 {
            let a = (-wn * dt).exp();
            return LowPass {
                ad: [[a, 0.0], [0.0, 0.0]],
                bd: [1.0 - a, 0.0],
                order: 1,
                iir: None,
                state: [0.0; 2],
            };
        }
        let z = damping.unwrap_or(DEFAULT_DAMPING);
        let s = z * wn;
        // exp(A dt) = f0 I + f1 (A + s I)
        let (f0, f1) = if z < 1.0 {
            let b = wn * (1.0 - z * z).sqrt();
            let e = (-s * dt).exp();
            let g = if b * dt < 1e-8 {
                dt
            } else {
                (b * dt).sin() / b
            };
            (e * (b * dt).cos(), e * g)
        } else if z > 1.0 {
            // real poles l_fast = -(s + b), l_slow = w_n^2 / l_fast (their product is w_n^2)
            let b = wn * (z * z - 1.0).sqrt();
            let l_fast = -(s + b);
            let l_slow = wn * wn / l_fast;
            let (e_slow, e_fast) = ((l_slow * dt).exp(), (l_fast * dt).exp());
            // e^(-s dt) cosh(b dt) = (e_slow + e_fast) / 2, e^(-s dt) sinh(b dt) / b
            // = (e_slow - e_fast) / (2 b)
            let g = if b * dt < 1e-8 {
                dt * (-s * dt).exp()
            } else {
                (e_slow - e_fast) / (2.0 * b)
            };
            ((e_slow + e_fast) / 2.0, g)
        } else {
            let e = (-s * dt).exp();
            (e, e * dt)
        };
        // A + s I = [[s, 1], [-w_n^2, -s]]
        let ad = [[f0 + f1 * s, f1], [-f1 * wn * wn, f0 - f1 * s]];
        // Bd = A^-1 (Ad - I) B, A^-1 = [[-2 s, -1], [w_n^2, 0]] / w_n^2, B = (0, w_n^2)
        let bd = [-2.0 * s * ad[0][1] - (ad[1][1] - 1.0), wn * wn * ad[0][1]];
        LowPass {
            ad,
            bd,
            order: 2,
            iir: None,
            state: [0.0; 2],
        }
    }

    /// Filters `x` in place, the state carried on from the previous call.
    pub fn apply(&mut self, x: &mut [f64]) {
        if let Some(([b0, b1, b2], [a1, a2])) = self.iir {
            // transposed direct form II: y = b0 x + d1; d1 = b1 x - a1 y + d2;
            // d2 = b2 x - a2 y
            let [mut d1, mut d2] = self.state;
            for x in x.iter_mut() {
                let u = *x;
                let y = b0 * u + d1;
                d1 = b1 * u - a1 * y + d2;
                d2 = b2 * u - a2 * y;
                *x = y;
            }
            self.state = [d1, d2];
            return;
        }
        let [[a11, a12], [a21, a22]] = self.ad;
        let [b1, b2] = self.bd;
        let [mut p, mut v] = self.state;
        if self.order == 1 {
            for x in x.iter_mut() {
                p = a11 * p + b1 * *x;
                *x = p;
            }
        } else {
            for x in x.iter_mut() {
                let u = *x;
                let p1 = a11 * p + a12 * v + b1 * u;
                v = a21 * p + a22 * v + b2 * u;
                p = p1;
                *x = p;
            }
        }
        self.state = [p, v];
    }

    /// |H(e^(i w))|^2 at frequency `f_hz` for samples at `rate_hz`, w = 2 pi f / rate:
    /// the factor by which the filter multiplies a PSD (1 at 0 Hz).
    /// H(z) = C (I - Ad z^-1)^-1 Bd, C = (1, 0), solved as a complex 2x2 system.
    pub fn power_response(&self, f_hz: f64, rate_hz: f64) -> f64 {
        let w = 2.0 * PI * f_hz / rate_hz;
        // z^-1 = e^(-i w)
        let (c, s) = (w.cos(), -w.sin());
        if let Some((b, a)) = self.iir {
            // |B(z)|^2 / |A(z)|^2 at z^-1 = e^(-i w), z^-2 = e^(-2 i w)
            let (c2, s2) = ((2.0 * w).cos(), -(2.0 * w).sin());
            let nr = b[0] + b[1] * c + b[2] * c2;
            let ni = b[1] * s + b[2] * s2;
            let dr = 1.0 + a[0] * c + a[1] * c2;
            let di = a[0] * s + a[1] * s2;
            return (nr * nr + ni * ni) / (dr * dr + di * di);
        }
        if self.order == 1 {
            let a = self.ad[0][0];
            let b = self.bd[0];
            // |1 - a z^-1|^2 = 1 - 2 a cos w + a^2
            return b * b / (1.0 - 2.0 * a * c + a * a);
        }
        // M = I - Ad z^-1, complex entries (re, im)
        let [[a11, a12], [a21, a22]] = self.ad;
        let m11 = (1.0 - a11 * c, -a11 * s);
        let m12 = (-a12 * c, -a12 * s);
        let m21 = (-a21 * c, -a21 * s);
        let m22 = (1.0 - a22 * c, -a22 * s);
        let mul = |x: (f64, f64), y: (f64, f64)| (x.0 * y.0 - x.1 * y.1, x.0 * y.1 + x.1 * y.0);
        let det = {
            let p = mul(m11, m22);
            let q = mul(m12, m21);
            (p.0 - q.0, p.1 - q.1)
        };
        // first row of M^-1 = (m22, -m12) / det; H = (m22 b1 - m12 b2) / det
        let [b1, b2] = self.bd;
        let num = (m22.0 * b1 - m12.0 * b2, m22.1 * b1 - m12.1 * b2);
        (num.0 * num.0 + num.1 * num.1) / (det.0 * det.0 + det.1 * det.1)
    }
}

/// A finite-impulse-response output filter with its state (module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct Fir {
    taps: Vec<f64>,
    /// The last taps.len() - 1 inputs, the newest first; zeros before the first sample.
    history: Vec<f64>,
}

impl Fir {
    /// The filter y_t = sum_k taps\[k\] x_{t-k}, at rest (zero history).
    pub fn new(taps: &[f64]) -> Self {
        Fir {
            taps: taps.to_vec(),
            history: vec![0.0; taps.len().saturating_sub(1)],
        }
    }

    /// Filters `x` in place, the history carried on from the previous call: the
    /// inputs laid out oldest first after the history (u), y_t = taps\[0\] u_t +
    /// taps\[1\] u_{t-1} + ..., summed in that order. `apply_slow` is the plain twin.
    pub fn apply(&mut self, x: &mut [f64]) {
        let m = self.history.len();
        if self.taps.is_empty() || x.is_empty() {
            return;
        }
        let mut u: Vec<f64> = Vec::with_capacity(m + x.len());
        u.extend(self.history.iter().rev());
        u.extend_from_slice(x);
        let (h0, rest) = (self.taps[0], &self.taps[1..]);
        for (t, v) in x.iter_mut().enumerate() {
            // u[m + t] is x_t, u[m + t - k] is x_{t-k}
            let mut y = h0 * u[m + t];
            for (k, h) in rest.iter().enumerate() {
                y += h * u[m + t - 1 - k];
            }
            *v = y;
        }
        for (k, h) in self.history.iter_mut().enumerate() {
            *h = u[u.len() - 1 - k];
        }
    }

    /// [`Fir::apply`] with the history rotated at every sample: the slow twin.
    #[cfg(test)]
    fn apply_slow(&mut self, x: &mut [f64]) {
        let m = self.history.len();
        if self.taps.is_empty() {
            return;
        }
        let h0 = self.taps[0];
        for v in x.iter_mut() {
            let u = *v;
            let mut y = h0 * u;
            for (h, p) in self.taps[1..].iter().zip(&self.history) {
                y += h * p;
            }
            if m > 0 {
                self.history.rotate_right(1);
                self.history[0] = u;
            }
            *v = y;
        }
    }

    /// |H(e^(i w))|^2 at frequency `f_hz` for samples at `rate_hz`, w = 2 pi f / rate.
    pub fn power_response(&self, f_hz: f64, rate_hz: f64) -> f64 {
        let w = 2.0 * PI * f_hz / rate_hz;
        let (mut re, mut im) = (0.0, 0.0);
        for (k, h) in self.taps.iter().enumerate() {
            re += h * (k as f64 * w).cos();
            im -= h * (k as f64 * w).sin();
        }
        re * re + im * im
    }
}

/// The output resolution's rounding with its state.
#[derive(Clone, Debug, PartialEq)]
pub struct Quantizer {
    /// The LSB in the rate unit (> 0).
    quantum: f64,
    on_angle: bool,
    /// On the angle: the angle's rounding error after the last sample, in quanta of
    /// angle (quantum dt), within \[-1/2, 1/2\]; 0 before the first sample.
    carry: f64,
}

impl Quantizer {
    /// Rounding to multiples of `quantum` \[u\], of the rate or (`on_angle`) of the angle.
    pub fn new(quantum: f64, on_angle: bool) -> Self {
        Quantizer {
            quantum,
            on_angle,
            carry: 0.0,
        }
    }

    /// Rounds `x` in place. On the rate: y_t = quantum round(x_t / quantum). On the
    /// angle (in quanta of angle, quantum dt): the angle before rounding is the last
    /// rounded angle plus the carried error plus x_t / quantum; with
    /// s_t = e_{t-1} + x_t / quantum, k_t = round(s_t), e_t = s_t - k_t, the rate is
    /// y_t = k_t quantum (the first difference of the rounded angle over dt). The
    /// rounded angle sum_t k_t then never strays more than half a quantum from the
    /// true angle sum_t x_t / quantum, and the error is carried in e (bounded), not in
    /// a growing angle.
    pub fn apply(&mut self, x: &mut [f64]) {
        let q = self.quantum;
        if !self.on_angle {
            for x in x.iter_mut() {
                *x = crate::num::round_half_away(*x / q) * q;
            }
            return;
        }
        // The carried error makes the loop a chain from sample to sample; on it, the
        // rounding is (s + C) - C with C = 1.5 * 2^52 (to nearest, ties to even, for
        // |s| < 2^51: s + C lies where the doubles are the integers), and the rare
        // exact tie or the out-of-range value takes round_half_away, so that k is
        // round_half_away(s) bit for bit; the sign of a zero k is s's, as
        // round_half_away gives it. `apply_slow` is the plain twin.
        const C: f64 = 6_755_399_441_055_744.0;
        const TWO_51: f64 = 2_251_799_813_685_248.0;
        let mut e = self.carry;
        for x in x.iter_mut() {
            let s = e + *x / q;
            let r = (s + C) - C;
            let k = if s.abs() < TWO_51 && (s - r).abs() != 0.5 {
                r
            } else {
                crate::num::round_half_away(s)
            };
            e = s - k;
            *x = k.copysign(s) * q;
        }
        self.carry = e;
    }

    /// [`Quantizer::apply`] as its formula reads, round_half_away at every sample: the
    /// slow twin the fast loop is tested against.
    #[cfg(test)]
    fn apply_slow(&mut self, x: &mut [f64]) {
        let q = self.quantum;
        if !self.on_angle {
            for x in x.iter_mut() {
                *x = crate::num::round_half_away(*x / q) * q;
            }
            return;
        }
        let mut e = self.carry;
        for x in x.iter_mut() {
            let s = e + *x / q;
            let k = crate::num::round_half_away(s);
            e = s - k;
            *x = k * q;
        }
        self.carry = e;
    }
}

/// One stage of the output path.
#[derive(Clone, Debug, PartialEq)]
pub enum Stage {
    Filter(LowPass),
    Fir(Fir),
    Saturation(f64),
    Resolution(Quantizer),
}

impl Stage {
    fn apply(&mut self, x: &mut [f64]) {
        match self {
            Stage::Filter(f) => f.apply(x),
            Stage::Fir(f) => f.apply(x),
            Stage::Saturation(limit) => {
                for v in x.iter_mut() {
                    *v = v.clamp(-*limit, *limit);
                }
            }
            Stage::Resolution(q) => q.apply(x),
        }
    }
}

/// A channel's output path: its stages in the order filter -> saturation ->
/// resolution, each with its state.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct OutputPath {
    stages: Vec<Stage>,
}

impl OutputPath {
    /// The output path of a channel with `components` at `rate_hz`; with `before`
    /// (an output-path kind), only the stages that come before that kind's stage
    /// (with `include`, that stage too). Empty when the channel has none.
    pub fn of(components: &[Component], rate_hz: f64, upto: Option<(Kind, bool)>) -> OutputPath {
        let limit =
            upto.and_then(|(k, include)| k.output_stage().map(|s| if include { s + 1 } else { s }));
        let mut staged: Vec<(usize, Stage)> = components
            .iter()
            .filter_map(|c| {
                let pos = c.kind().output_stage()?;
                if limit.is_some_and(|l| pos >= l) {
                    return None;
                }
                let stage = match c {
                    Component::OutputFilter {
                        order,
                        bandwidth_hz,
                        damping,
                        discretization,
                    } => Stage::Filter(LowPass::with(
                        *order,
                        *bandwidth_hz,
                        *damping,
                        *discretization,
                        rate_hz,
                    )),
                    Component::OutputFir { taps } => Stage::Fir(Fir::new(taps)),
                    Component::Saturation { limit } => Stage::Saturation(*limit),
                    Component::OutputResolution { quantum, on_angle } => {
                        Stage::Resolution(Quantizer::new(*quantum, *on_angle))
                    }
                    _ => return None,
                };
                Some((pos, stage))
            })
            .collect();
        staged.sort_by_key(|(pos, _)| *pos);
        OutputPath {
            stages: staged.into_iter().map(|(_, s)| s).collect(),
        }
    }

    /// No stage: the output is the sum itself.
    pub fn is_empty(&self) -> bool {
        self.stages.is_empty()
    }

    /// Passes the block `x` (the sum of the channel's components) through every stage,
    /// in place, the stages' states carried on from the previous block.
    pub fn apply(&mut self, x: &mut [f64]) {
        for s in &mut self.stages {
            s.apply(x);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn white(n: usize, seed: u64) -> Vec<f64> {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        (0..n).map(|_| StandardNormal.sample(&mut rng)).collect()
    }

    #[test]
    fn the_fir_is_its_slow_twin_bit_for_bit() {
        let x = white(5000, 11);
        for taps in [vec![], vec![0.7], vec![0.5, 0.3, 0.2], vec![0.1; 9]] {
            let (mut fast, mut slow) = (Fir::new(&taps), Fir::new(&taps));
            let (mut a, mut b) = (x.clone(), x.clone());
            // pieces shorter and longer than the history, the state carried across
            for piece in [0..1, 1..4, 4..4, 4..1000, 1000..5000] {
                fast.apply(&mut a[piece.clone()]);
                slow.apply_slow(&mut b[piece.clone()]);
                assert_eq!(fast.history, slow.history);
            }
            assert!(a.iter().zip(&b).all(|(p, q)| p.to_bits() == q.to_bits()));
        }
    }

    #[test]
    fn the_angle_quantizer_is_its_slow_twin_bit_for_bit() {
        // noise, values on the half-quantum grid (exact ties), zeros of both signs,
        // values past 2^51 quanta, infinities and NaN, carried across two calls
        let mut x = white(20_000, 7);
        for (i, v) in x.iter_mut().enumerate() {
            match i % 11 {
                1 => *v = (i % 9) as f64 * 0.5 - 2.0,
                2 => *v = -0.0,
                3 => *v = 0.0,
                4 => *v *= 1e17,
                5 => *v = (i % 5) as f64 * 0.25 - 0.5,
                _ => *v *= 3.0,
            }
        }
        // exact ties from rest: ties to even would give 0, 2, -0, -2
        for (v, want) in [(0.5, 1.0), (2.5, 3.0), (-0.5, -1.0), (-2.5, -3.0)] {
            let mut y = [v];
            Quantizer::new(1.0, true).apply(&mut y);
            assert_eq!(y[0], want, "the tie {v}");
        }
        x[100] = f64::INFINITY;
        x[5000] = f64::NAN;
        for q in [1.0, 0.05, 0.5, 1e-3] {
            let (mut fast, mut slow) = (Quantizer::new(q, true), Quantizer::new(q, true));
            let (mut a, mut b) = (x.clone(), x.clone());
            // after a NaN the carry is NaN: the two runs are compared before it and
            // from a fresh quantizer after it
            for piece in [0..97, 97..4999, 5001..20_000] {
                if piece.start == 5001 {
                    fast = Quantizer::new(q, true);
                    slow = Quantizer::new(q, true);
                }
                fast.apply(&mut a[piece.clone()]);
                slow.apply_slow(&mut b[piece.clone()]);
                for i in piece {
                    assert_eq!(
                        a[i].to_bits(),
                        b[i].to_bits(),
                        "q {q}, sample {i}: {} {}",
                        a[i],
                        b[i]
                    );
                }
                assert_eq!(fast.carry.to_bits(), slow.carry.to_bits());
            }
        }
    }

    #[test]
    fn first_order_is_the_sampled_lag_with_its_minus_3_db_point() {
        let f = LowPass::new(1, 5.0, None, 100.0);
        let a = (-2.0 * PI * 5.0 / 100.0).exp();
        assert_eq!(f.ad[0][0], a);
        assert!((f.power_response(0.0, 100.0) - 1.0).abs() < 1e-12);
        // close to the continuous -3 dB point when the bandwidth is well below Nyquist
        let f = LowPass::new(1, 1.0, None, 1000.0);
        assert!((f.power_response(1.0, 1000.0) - 0.5).abs() < 0.01);
        // a step settles to 1 (unit DC gain)
        let mut f = LowPass::new(1, 5.0, None, 100.0);
        let mut x = vec![1.0; 500];
        f.apply(&mut x);
        assert!((x[499] - 1.0).abs() < 1e-12 && x[0] < 0.5);
    }

    #[test]
    fn second_order_has_unit_dc_gain_and_its_roll_off() {
        for z in [0.3, DEFAULT_DAMPING, 1.0, 2.5, 40.0] {
            let mut f = LowPass::new(2, 2.0, Some(z), 100.0);
            assert!(
                (f.power_response(0.0, 100.0) - 1.0).abs() < 1e-9,
                "z {z}: {}",
                f.power_response(0.0, 100.0)
            );
            let mut x = vec![1.0; 200_000];
            f.apply(&mut x);
            assert!((x[199_999] - 1.0).abs() < 1e-9, "z {z}: {}", x[199_999]);
        }
        // -40 dB/decade: a decade above the bandwidth the power falls about 1e4
        let f = LowPass::new(2, 1.0, None, 1000.0);
        let r = f.power_response(10.0, 1000.0);
        assert!(r > 0.5e-4 && r < 2e-4, "{r}");
        // the Butterworth -3 dB point at the natural frequency
        assert!((f.power_response(1.0, 1000.0) - 0.5).abs() < 0.01);
        // damping near 1 from both sides is continuous
        let lo = LowPass::new(2, 3.0, Some(1.0 - 1e-9), 100.0);
        let hi = LowPass::new(2, 3.0, Some(1.0 + 1e-9), 100.0);
        let one = LowPass::new(2, 3.0, Some(1.0), 100.0);
        for f in [&lo, &hi] {
            for (a, b) in f.ad.iter().flatten().zip(one.ad.iter().flatten()) {
                assert!((a - b).abs() < 1e-6, "{a} {b}");
            }
        }
    }

    #[test]
    fn power_response_matches_the_filtered_noise_variance() {
        // variance of filtered unit white noise = mean of |H|^2 over (0, Nyquist)
        for (order, z) in [(1, None), (2, Some(0.4)), (2, Some(3.0))] {
            let fs = 100.0;
            let mut f = LowPass::new(order, 4.0, z, fs);
            let k = 20_000;
            let mean_h: f64 = (0..k)
                .map(|i| f.power_response((i as f64 + 0.5) / k as f64 * fs / 2.0, fs))
                .sum::<f64>()
                / k as f64;
            let mut x = white(400_000, 3);
            f.apply(&mut x);
            let var = x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64;
            assert!(
                (var / mean_h - 1.0).abs() < 0.03,
                "order {order} z {z:?}: var {var}, mean |H|^2 {mean_h}"
            );
        }
    }

    #[test]
    fn the_bilinear_filter_is_scipys_butterworth() {
        // scipy.signal.butter(1, 12.0, fs=100) and butter(2, 0.84, fs=10)
        let f = LowPass::with(1, 12.0, None, Discretization::Bilinear, 100.0);
        let (b, a) = f.iir.unwrap();
        for (x, y) in [b[0], b[1], a[0]]
            .iter()
            .zip([0.28363068, 0.28363068, -0.43273864])
        {
            assert!((x - y).abs() < 1e-8, "{x} {y}");
        }
        let f = LowPass::with(2, 0.84, None, Discretization::Bilinear, 10.0);
        let (b, a) = f.iir.unwrap();
        let want = [0.05017146, 0.10034292, 0.05017146, -1.27411492, 0.47480076];
        for (x, y) in [b[0], b[1], b[2], a[0], a[1]].iter().zip(want) {
            assert!((x - y).abs() < 1e-8, "{x} {y}");
        }
        // -3 dB exactly at the bandwidth, unit DC gain, a zero at Nyquist
        for order in [1, 2] {
            let mut f = LowPass::with(order, 20.0, None, Discretization::Bilinear, 100.0);
            assert!((f.power_response(20.0, 100.0) - 0.5).abs() < 1e-12);
            assert!((f.power_response(0.0, 100.0) - 1.0).abs() < 1e-12);
            assert!(f.power_response(50.0, 100.0) < 1e-20);
            // the power response is the filtered noise's variance, block by block
            let k = 20_000;
            let mean_h: f64 = (0..k)
                .map(|i| f.power_response((i as f64 + 0.5) / k as f64 * 50.0, 100.0))
                .sum::<f64>()
                / k as f64;
            let x0 = white(400_000, 4);
            let mut x = x0.clone();
            f.apply(&mut x);
            let var = x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64;
            assert!((var / mean_h - 1.0).abs() < 0.03, "{var} {mean_h}");
            let mut g = LowPass::with(order, 20.0, None, Discretization::Bilinear, 100.0);
            let mut y = x0;
            for c in y.chunks_mut(777) {
                g.apply(c);
            }
            assert!(y == x);
        }
    }

    #[test]
    fn a_bandwidth_far_above_nyquist_is_the_identity() {
        for order in [1, 2] {
            let mut f = LowPass::new(order, 1e6, None, 100.0);
            let x0 = white(1000, 1);
            let mut x = x0.clone();
            f.apply(&mut x);
            assert!(x.iter().zip(&x0).all(|(a, b)| (a - b).abs() < 1e-9));
        }
    }

    #[test]
    fn the_angle_quantizer_keeps_the_angle_within_half_a_quantum() {
        let x0: Vec<f64> = white(10_000, 2).iter().map(|v| 0.3 + 0.07 * v).collect();
        let q = 0.05;
        let mut x = x0.clone();
        Quantizer::new(q, true).apply(&mut x);
        let (mut a, mut b) = (0.0, 0.0);
        for (u, v) in x0.iter().zip(&x) {
            a += u / q;
            b += v / q;
            assert!((a - b).abs() <= 0.5 + 1e-9, "{a} {b}");
            assert!(((v / q) - (v / q).round()).abs() < 1e-9);
        }
        // on the rate: each sample within half a quantum
        let mut y = x0.clone();
        Quantizer::new(q, false).apply(&mut y);
        assert!(
            x0.iter()
                .zip(&y)
                .all(|(u, v)| (u - v).abs() <= q / 2.0 + 1e-12)
        );
    }

    #[test]
    fn the_path_by_blocks_gives_the_whole_series() {
        let comps = vec![
            Component::WhiteNoise { n: 1.0 },
            Component::OutputResolution {
                quantum: 0.1,
                on_angle: true,
            },
            Component::Saturation { limit: 2.0 },
            Component::OutputFilter {
                order: 2,
                bandwidth_hz: 7.0,
                damping: Some(0.5),
                discretization: Default::default(),
            },
        ];
        let x0: Vec<f64> = white(10_007, 5).iter().map(|v| 3.0 * v).collect();
        let mut whole = x0.clone();
        OutputPath::of(&comps, 100.0, None).apply(&mut whole);
        assert!(whole.iter().all(|v| v.abs() <= 2.0 + 1e-12));
        for block in [1, 7, 1000, 4096] {
            let mut p = OutputPath::of(&comps, 100.0, None);
            let mut got = x0.clone();
            for c in got.chunks_mut(block) {
                p.apply(c);
            }
            assert!(got == whole, "block {block}");
        }
        // prefixes: before the resolution is filter + saturation
        let pre = OutputPath::of(&comps, 100.0, Some((Kind::OutputResolution, false)));
        assert_eq!(pre.stages.len(), 2);
        let upto = OutputPath::of(&comps, 100.0, Some((Kind::OutputFilter, true)));
        assert!(matches!(upto.stages[..], [Stage::Filter(_)]));
    }
}
