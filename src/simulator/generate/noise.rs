//! White-type noise: angle random walk (white rate noise), angle quantization noise,
//! outliers. Draws come by fixed chunks from the component's streams (see
//! [`super::streams`]), so the output does not depend on the thread count.

use rand::Rng;
use rand_distr::{Distribution, Geometric, StandardNormal, StudentT};
use rayon::prelude::*;

use super::streams::{CHUNK, StreamKey, for_chunks_from};

/// white_noise: white rate noise with IEEE Std 952 angle random walk coefficient `n`
/// [u sqrt(s)]: one-sided PSD n^2, so each sample (an average over dt = 1/rate_hz) has
/// standard deviation n / sqrt(dt) = n sqrt(rate_hz), and ADEV(tau) = n / sqrt(tau)
/// exactly at every tau = m dt (IEEE Std 952-1997 Annex C, eq. C.13 with the rate
/// sample being the average rate over dt). For a block starting at sample `c0 * CHUNK`
/// of the series (0 for a whole series).
pub fn white_noise_from(out: &mut [f64], n: f64, rate_hz: f64, key: &StreamKey, c0: u64) {
    let sd = n * rate_hz.sqrt();
    for_chunks_from(out, c0, |c, s| {
        let mut rng = key.rng(0, c);
        for v in s.iter_mut() {
            let w: f64 = StandardNormal.sample(&mut rng);
            *v += sd * w;
        }
    });
}

/// quantization: the rate read from a quantized angle. The angle error e_k is white,
/// uniform on [-Q/2, Q/2) with the angle quantum Q = sqrt(12) q (variance q^2), and
/// the rate sample is (e_k - e_{k-1}) / dt \[u\]. Then the angle error is white with
/// variance q^2, its second difference over m samples has variance 6 q^2, and the
/// Allan variance is 6 q^2 / (2 tau^2): ADEV(tau) = sqrt(3) q / tau exactly at every
/// tau = m dt (IEEE Std 952-1997 Annex C, quantization noise). The integrated angle
/// sum_k rate_k dt = e_k - e_{-1} stays within one quantum. e_{-1} is drawn from the
/// initial-state stream ([`quantization_init`]).
///
/// For a block starting at sample `c0 * CHUNK`: `prev` holds the angle error before the
/// block ([`quantization_init`] for the first) and is left holding the block's last.
pub fn quantization_from(
    out: &mut [f64],
    q: f64,
    rate_hz: f64,
    key: &StreamKey,
    c0: u64,
    prev: &mut f64,
) {
    if out.is_empty() {
        return;
    }
    let quantum = 12f64.sqrt() * q;
    let mut e = vec![0.0; out.len()];
    for_chunks_from(&mut e, c0, |c, s| {
        let mut rng = key.rng(0, c);
        for v in s.iter_mut() {
            *v = quantum * (rng.random::<f64>() - 0.5);
        }
    });
    let e_init = *prev;
    let e = &e;
    out.par_chunks_mut(CHUNK).enumerate().for_each(|(c, s)| {
        let base = c * CHUNK;
        for (j, v) in s.iter_mut().enumerate() {
            let k = base + j;
            let prev = if k == 0 { e_init } else { e[k - 1] };
            *v += (e[k] - prev) * rate_hz;
        }
    });
    *prev = e[e.len() - 1];
}

/// The angle error e_{-1} before the first sample of [`quantization_from`].
pub fn quantization_init(q: f64, key: &StreamKey) -> f64 {
    12f64.sqrt() * q * (key.init_rng(0).random::<f64>() - 0.5)
}

/// outliers: at each sample, with probability rate_hz / sample_rate_hz independently
/// (a Bernoulli process, `rate_hz` outliers per second on average), a spike
/// scale * N(0, 1) \[u\] is added, or with `dof` scale * T_dof, T_dof a Student-t draw
/// of `dof` degrees of freedom (rand_distr's `StudentT`: N(0, 1) / sqrt(chi2_dof / dof)).
/// Positions come from geometric gaps drawn per chunk (memoryless, so restarting at
/// each chunk start is exact). For a block starting at sample `c0 * CHUNK` of the
/// series (0 for a whole series).
pub fn outliers_from(
    out: &mut [f64],
    rate_hz: f64,
    scale: f64,
    dof: Option<f64>,
    sample_rate_hz: f64,
    key: &StreamKey,
    c0: u64,
) {
    let p = (rate_hz / sample_rate_hz).min(1.0);
    if p <= 0.0 {
        return;
    }
    let Ok(gaps) = Geometric::new(p) else {
        return; // p is in (0, 1] for every valid spec
    };
    // None: normal amplitudes (dof >= 1 for every valid spec)
    let t = dof.and_then(|d| StudentT::new(d).ok());
    for_chunks_from(out, c0, |c, s| {
        let mut rng = key.rng(0, c);
        let mut pos = gaps.sample(&mut rng);
        while (pos as usize) < s.len() {
            let w: f64 = match &t {
                Some(t) => t.sample(&mut rng),
                None => StandardNormal.sample(&mut rng),
            };
            s[pos as usize] += scale * w;
            pos = pos.saturating_add(1).saturating_add(gaps.sample(&mut rng));
        }
    });
}
