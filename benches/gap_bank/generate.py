#!/usr/bin/env python3
"""The independent acceptance bank of `farma gap` (issue 27).

Writes, for every case, a "real" log (Parquet: `time_s` in seconds, `rate` in the unit
named in the spec's comment and in truth.json, `temp_c` where the case has a
temperature channel), a spec (docs/contracts.md section 2) that is the truth MINUS the
withheld effect(s), and truth.json (what was withheld, with its true parameters).

The logs come from this file's own numpy code, from the physics, never from `farma
simulate`, and deliberately NOT in the forms farma's candidates assume: the bias
instability is 1/f noise shaped in the frequency domain (not a Gauss-Markov bank),
temperature effects refer to physical temperatures (25 degC) and not to the log's mean,
the sensor's temperature lags the chamber, warm-ups have two time constants, the
quantizer is a true quantizer (the rate rounded to an LSB, or the integrated angle
rounded and differenced), a low-pass output filter shapes the whole output, the
Shupe-like thermal rate acts through an exponential lag, outliers are Student-t, a
sinusoid is slowly amplitude-modulated, the heteroskedastic noise scales with
(T - 25 degC).

Usage:
    python3 generate.py OUTDIR [--part dev|dev2|heldout|heldout2|all] [--only CASE_SUBSTRING]

OUTDIR/<part>/<case>/{real.parquet, spec.toml, truth.json}, and OUTDIR/<part>/cases.json.
Deterministic: the same command writes the same bank (seeds per part and case).
"""

import argparse
import json
import math
import os
import sys

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from scipy import signal

# The candidate kinds of contracts.md section 2 that `farma gap` may add, and the names
# an answer may use for each withheld effect (issue 27 adds output_resolution and an
# output filter as kinds; their names there are not fixed yet, so several are accepted).
ACCEPT = {
    "constant_bias": ["constant_bias"],
    "temperature_bias": ["temperature_bias"],
    "thermal_rate": ["thermal_rate"],
    "heteroskedastic": ["heteroskedastic"],
    "warmup": ["warmup"],
    "rate_ramp": ["rate_ramp"],
    "sinusoid": ["sinusoid"],
    "gauss_markov": ["gauss_markov"],
    "rate_random_walk": ["rate_random_walk"],
    "bias_instability": ["bias_instability"],
    "quantization": ["quantization", "output_resolution"],
    "outliers": ["outliers"],
    "output_filter": ["output_filter", "low_pass", "lowpass", "filter", "output_lowpass"],
}
# kinds that are candidate kinds of contracts.md section 2 today (the rest: issue 27's)
CONTRACT_KINDS = set(ACCEPT) - {"output_filter"}

PART_SEED = {"dev": 27_001, "heldout": 27_999_013, "dev2": 28_500_007, "heldout2": 29_311_021,
             "dev3": 30_017_003, "dev4": 31_204_011, "dev5": 32_405_017,
             "path6": 33_606_029, "dev6": 34_808_041, "path7": 35_010_053,
             "dev7": 36_212_061, "heldout3": 37_414_073,
             "dev8": 38_616_083, "heldout4": 39_818_101, "dev9": 40_020_119,
             "heldout5": 41_222_137, "dev10": 42_424_151}


# ----------------------------------------------------------------------------- physics

def lowpass1(x, tau_s, fs, x0=None):
    """First-order lag y' = (x - y) / tau (exact discretisation)."""
    a = math.exp(-1.0 / (fs * tau_s))
    zi = [(x[0] if x0 is None else x0) * a]
    y, _ = signal.lfilter([1 - a], [1, -a], x, zi=zi)
    return y


def gauss_markov(rng, n, fs, sigma, tau_s):
    a = math.exp(-1.0 / (fs * tau_s))
    e = rng.standard_normal(n) * sigma * math.sqrt(1 - a * a)
    x0 = rng.standard_normal() * sigma
    y, _ = signal.lfilter([1.0], [1, -a], e, zi=[a * x0])
    return y


def flicker(rng, n, fs, b, f_lo):
    """1/f noise with one-sided PSD h / f, h = (0.664 b)^2 / (2 ln 2), for f >= f_lo
    (flat below), shaped in the frequency domain (not a Gauss-Markov bank)."""
    h = (0.664 * b) ** 2 / (2 * math.log(2))
    m = 1 << int(math.ceil(math.log2(n)))
    w = rng.standard_normal(m)
    W = np.fft.rfft(w)
    f = np.fft.rfftfreq(m, 1.0 / fs)
    s = h / np.maximum(f, f_lo)
    # unit-variance white noise has one-sided PSD 2 / fs
    W *= np.sqrt(s / (2.0 / fs))
    W[0] = 0.0
    return np.fft.irfft(W, m)[:n]


def student_spikes(rng, n, fs, rate_hz, scale):
    x = np.zeros(n)
    k = rng.poisson(rate_hz * n / fs)
    idx = rng.integers(0, n, size=k)
    x[idx] += scale * rng.standard_t(3, size=k) / math.sqrt(3.0)
    return x


# ------------------------------------------------------------------------- temperature

def temperature(rng, kind, t, fs, lo, hi):
    """Chamber profile, the sensor's lagging temperature, its reading (noise, 1/16 degC)."""
    T = t[-1] + 1.0 / fs
    u = t / T
    if kind == "ramp":  # soak, linear ramp, soak
        a, b = 0.1, 0.9
        c = lo + (hi - lo) * np.clip((u - a) / (b - a), 0, 1)
    elif kind == "steps":  # plateaus
        k = int(rng.integers(3, 6))
        levels = np.linspace(lo, hi, k)
        rng.shuffle(levels)
        c = levels[np.minimum((u * k).astype(int), k - 1)]
    elif kind == "drift":  # slow warming of a room / vehicle
        c = lo + (hi - lo) * (1 - np.exp(-u * 3.0)) + 0.5 * np.sin(2 * np.pi * u * 1.3)
    elif kind == "cycle":  # triangular chamber cycles with dwells
        ncyc = int(rng.integers(1, 4))
        ph = (u * ncyc) % 1.0
        tri = np.clip(np.where(ph < 0.5, ph * 2, 2 - ph * 2) * 1.25 - 0.125, 0, 1)
        c = lo + (hi - lo) * tri
    elif kind == "soak_ramp":  # cold soak, fast ramp, hot soak, partial cool
        c = np.where(u < 0.3, lo, np.where(u < 0.45, lo + (hi - lo) * (u - 0.3) / 0.15,
                     np.where(u < 0.8, hi, hi - 0.5 * (hi - lo) * np.clip((u - 0.8) / 0.1, 0, 1))))
    elif kind == "sine":  # sinusoidal chamber cycles (dev5 only)
        k = int(rng.integers(1, 4))
        c = lo + (hi - lo) * (0.5 + 0.5 * np.sin(2 * np.pi * u * k + float(rng.uniform(0, 2 * np.pi))))
    elif kind == "rw_drift":  # ambient random drift (smoothed random walk)
        k = 400
        steps = rng.standard_normal(k).cumsum()
        steps = (steps - steps.min()) / max(np.ptp(steps), 1e-9)
        c = lo + (hi - lo) * np.interp(u, np.linspace(0, 1, k), steps)
    else:
        raise ValueError(kind)
    tau_th = float(rng.uniform(150, 600))
    ts = lowpass1(c.astype(float), tau_th, fs)
    reading = np.round((ts + 0.02 * rng.standard_normal(len(t))) * 16) / 16
    return ts, reading, tau_th


# ------------------------------------------------------------------------------ cases

def fmt(v):
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(fmt(x) for x in v) + "]"
    return repr(float(v)) if not isinstance(v, bool) else ("true" if v else "false")


def spec_toml(fs, unit, temp, comps, note):
    lines = [f"# independent bank (issue 27): {note}",
             f"# rate unit: {unit}; the truth is in truth.json",
             f"sample_rate_hz = {fmt(fs)}"]
    if temp:
        lines.append('temperature_channel = "temp_c"')
    lines += ["", "[[channel]]", 'name = "rate"']
    for c in comps:
        lines += ["", "[[channel.component]]", f'kind = "{c["kind"]}"']
        for k, v in c.items():
            if k != "kind":
                lines.append(f"{k} = {fmt(v)}")
    return "\n".join(lines) + "\n"


class Case:
    """One case: base sensor + effects; builds the log, the spec and the truth."""

    def __init__(self, part, idx, name, category, effects, fs, dur_s, tprof, size, trange, seed):
        self.part, self.idx, self.name, self.category = part, idx, name, category
        self.effects = effects          # list of (kind, variant) of the truth beyond the base
        self.fs, self.dur_s, self.tprof, self.size = fs, dur_s, tprof, size
        self.trange, self.seed = trange, seed

    def build(self, outdir):
        rng = np.random.default_rng(self.seed)
        fs, T = float(self.fs), float(self.dur_s)
        n = int(round(fs * T))
        dt = 1.0 / fs
        t = np.arange(n) * dt
        unit = "deg/h" if fs <= 10 else "deg/s"
        # base sensor: constant bias, white noise, flicker bias instability
        nd = float(rng.uniform(0.1, 0.8)) if unit == "deg/h" else float(rng.uniform(0.002, 0.015))
        c0 = nd * float(rng.uniform(-3, 3))
        tau_c = float(rng.uniform(100, 1000))      # where the flicker floor meets the white noise
        b = nd / math.sqrt(tau_c) / 0.664
        sig_s = nd / math.sqrt(dt)                 # per-sample white noise std

        def sig_L(L):                              # noise of an L-second mean
            return math.sqrt(nd * nd / L + (0.664 * b) ** 2)

        s = self.size
        if "constant_bias" in self.withheld():
            # a withheld bias is sized like every other effect (at least s x 8 sd of a
            # block mean), not left at the base's few n
            c0 = math.copysign(max(abs(c0), s * 8 * sig_L(T / 8)), c0)
        temp = self.tprof is not None
        if temp:
            lo, hi = self.trange
            Ts, Tread, tau_th = temperature(rng, self.tprof, t, fs, lo, hi)
        x = np.zeros(n)
        white_scale = np.ones(n)
        spec = []     # truth components in contract form (those withheld removed later)
        truth = []    # every effect beyond the base with its true parameters
        post = []     # output path: filters then quantizer

        spec_base = [
            ("constant_bias", {"kind": "constant_bias", "value": c0}),
            ("white_noise", {"kind": "white_noise", "n": nd}),
            ("bias_instability", {"kind": "bias_instability", "b": b, "tau_min_s": dt, "tau_max_s": T}),
        ]
        kinds = [k for k, _ in self.effects]
        withheld = set(self.withheld())
        wcomp = {}   # the contract form of each withheld effect (for the detectability specs)
        # the base, with constant_bias / bias_instability possibly withheld
        x += c0
        x += flicker(rng, n, fs, b, 1.0 / T)
        base_truth = {"constant_bias": {"value": c0}, "white_noise": {"n": nd},
                      "bias_instability": {"b": b, "form": "1/f noise shaped by FFT, f >= 1/duration"}}
        for k, c in spec_base:
            if k == "constant_bias" and "constant_bias" in withheld:
                truth.append({"kind": k, "params": {"value": c0}, "form": "constant"})
                wcomp[k] = c
                continue
            if k == "bias_instability" and "bias_instability" in withheld:
                # the withheld flicker is larger than the base one
                b2 = b * (1 + 2.5 * s)
                x += flicker(rng, n, fs, math.sqrt(b2 * b2 - b * b), 1.0 / T)
                wcomp[k] = {"kind": k, "b": b2, "tau_min_s": dt, "tau_max_s": T}
                truth.append({"kind": k, "params": {"b": b2, "tau_min_s": dt, "tau_max_s": T},
                              "form": "1/f noise shaped by FFT (not a Gauss-Markov bank)"})
                continue
            spec.append(c)

        for kind, var in self.effects:
            p = {}
            form = ""
            comp = None
            if kind == "constant_bias":
                continue  # handled with the base
            if kind == "bias_instability":
                continue
            if kind == "temperature_bias":
                c1 = s * 16 * sig_L(T / 16) / (hi - lo) * float(rng.choice([-1, 1]))
                c2 = (0.15 * c1 / 30.0 * float(rng.choice([-1, 1]))) if var == "quad" else 0.0
                ref = 25.0
                x += c1 * (Ts - ref) + c2 * (Ts - ref) ** 2
                p = {"coeffs": [c1, c2] if c2 else [c1], "reference_c": ref,
                     "mean_temp_c": float(Tread.mean())}
                form = "c1 (T - 25) + c2 (T - 25)^2 on the sensor temperature, not centred at the mean"
                comp = {"kind": "temperature_bias", "coeffs": p["coeffs"], "reference_c": ref}
            elif kind == "thermal_rate":
                tau_l = float(rng.uniform(30, 200))
                dT = np.gradient(lowpass1(Ts, tau_l, fs), dt)
                k = s * 12 * sig_L(tau_l) / max(np.abs(dT).max(), 1e-6) * float(rng.choice([-1, 1]))
                x += k * dT
                p = {"coeff": k, "smoothing_s": tau_l}
                form = "coeff * d/dt of the temperature through a first-order lag (tau = smoothing_s)"
                comp = {"kind": "thermal_rate", "coeff": k, "smoothing_s": tau_l}
            elif kind == "heteroskedastic":
                slope = s * 1.2 / (hi - lo)
                sc = 1 + slope * (Ts - 25.0)
                sc = np.maximum(sc, 0.15)
                white_scale = sc
                rms = float(np.sqrt(np.mean(sc ** 2)))
                tm = float(Tread.mean())
                p = {"of": "white_noise", "slope_per_degC_about_25C": slope,
                     "scale_floor": 0.15, "share_at_floor": float(np.mean(sc <= 0.15)),
                     "slope_about_mean": slope / (1 + slope * (tm - 25.0)) / 1.0,
                     "white_noise_n_in_spec_is_rms": nd * rms, "mean_temp_c": tm}
                form = "white noise std * max(1 + slope (T - 25 degC), 0.15); the spec's n is its RMS"
                # the spec's white noise becomes the RMS level
                for c in spec:
                    if c["kind"] == "white_noise":
                        c["n"] = nd * rms
                comp = {"kind": "heteroskedastic", "of": "white_noise", "slope": p["slope_about_mean"]}
            elif kind == "warmup":
                tau_w = float(rng.uniform(60, 240)) if var == "short" else float(rng.uniform(600, 1800))
                tau_w = min(tau_w, T / 4)
                A = s * 25 * sig_L(tau_w / 2) * float(rng.choice([-1, 1]))
                if var == "exact":
                    x += A * np.exp(-t / tau_w)
                    form = "A exp(-t / tau)"
                else:
                    x += A * (0.75 * np.exp(-t / tau_w) + 0.25 * np.exp(-t / (tau_w / 5)))
                    form = "A (0.75 exp(-t / tau) + 0.25 exp(-5 t / tau)): two time constants"
                p = {"amplitude": A, "tau_s": tau_w}
                comp = {"kind": "warmup", "amplitude": A, "tau_s": tau_w}
            elif kind == "rate_ramp":
                r = s * 10 * sig_L(T / 8) / T * float(rng.choice([-1, 1]))
                x += r * t
                p = {"r": r}
                form = "r t from the log's start (aging)"
                comp = {"kind": "rate_ramp", "r": r}
            elif kind == "sinusoid":
                f0 = float(np.exp(rng.uniform(math.log(0.02), math.log(min(2.0, 0.2 * fs)))))
                A = s * 30 * nd / math.sqrt(T)
                A = max(A, s * 3 * sig_L(1.0 / f0) if f0 < 0.1 else A)
                ph = float(rng.uniform(0, 2 * math.pi))
                am = 1 + (0.1 * np.sin(2 * np.pi * t / (T / 1.7)) if var != "exact" else 0)
                x += A * am * np.sin(2 * np.pi * f0 * t + ph)
                p = {"amplitude": A, "freq_hz": f0, "phase_rad": ph}
                form = "A (1 + 0.1 sin(slow)) sin(2 pi f t + phase)" if var != "exact" else "A sin(2 pi f t + phase)"
                comp = {"kind": "sinusoid", "amplitude": A, "freq_hz": f0, "phase_rad": ph}
            elif kind == "gauss_markov":
                tau = float(np.exp(rng.uniform(math.log(5), math.log(min(300, T / 20)))))
                sig = s * 4 * sig_L(tau)
                x += gauss_markov(rng, n, fs, sig, tau)
                p = {"sigma": sig, "tau_s": tau}
                form = "exact discrete AR(1) of a first-order Gauss-Markov process"
                comp = {"kind": "gauss_markov", "sigma": sig, "tau_s": tau}
            elif kind == "rate_random_walk":
                k = s * 3 * sig_L(T / 8) / math.sqrt(T / 24)
                x += np.cumsum(rng.standard_normal(n)) * k * math.sqrt(dt)
                p = {"k": k}
                form = "cumulative sum of white noise from 0 at the start"
                comp = {"kind": "rate_random_walk", "k": k}
            elif kind == "outliers":
                rate = s * 40 / T
                scale = 15 * sig_s
                x += student_spikes(rng, n, fs, rate, scale)
                p = {"rate_hz": rate, "scale": scale}
                form = "Poisson times, Student-t(3) amplitudes with std = scale"
                comp = {"kind": "outliers", "rate_hz": rate, "scale": scale}
            elif kind == "quantization":
                if var == "angle":
                    dth = s * 1.5 * nd * math.sqrt(dt)           # angle quantum [u s]
                    post.append(("quant_angle", dth))
                    p = {"q": dth / math.sqrt(12), "angle_quantum": dth, "rate_lsb": dth / dt}
                    form = "integrated angle rounded to a quantum and differenced (rate on a grid of quantum/dt)"
                else:
                    lsb = s * 1.0 * sig_s
                    post.append(("quant_rate", lsb))
                    p = {"q": lsb * dt / math.sqrt(12), "rate_lsb": lsb}
                    form = "rate rounded to an LSB each sample"
                comp = {"kind": "quantization", "q": p["q"]}
            elif kind == "output_filter":
                order = 2 if var == "2" else 1
                fc = fs / (4 + 4 * s)
                post.insert(0, ("filter", (order, fc)))
                p = {"order": order, "cutoff_hz": fc}
                form = f"Butterworth low-pass of order {order} on the whole output"
                comp = None  # not a contract kind yet
            elif kind == "bias_step":
                t0 = float(rng.uniform(0.3, 0.7)) * T
                D = s * 16 * sig_L(T / 8) * float(rng.choice([-1, 1]))
                x += np.where(t >= t0, D, 0.0)
                p = {"at_s": t0, "step": D}
                form = "bias step at one moment"
            elif kind == "burst":
                nb = int(rng.integers(3, 7))
                bs = s * 4 * sig_s
                spans = []
                for _ in range(nb):
                    L = float(rng.uniform(30, 300))
                    a = float(rng.uniform(0, T - L))
                    m = (t >= a) & (t < a + L)
                    x[m] += bs * rng.standard_normal(int(m.sum()))
                    spans.append([a, a + L])
                p = {"bursts": spans, "std": bs}
                form = "bursts of extra white noise"
            elif kind == "telegraph":
                D = s * 12 * sig_L(T / 8)
                dwell = T / 10
                sw = np.cumsum(rng.random(n) < dt / dwell) % 2
                x += D * (sw - 0.5)
                p = {"levels": [-D / 2, D / 2], "mean_dwell_s": dwell}
                form = "random telegraph (popcorn) bias between two levels"
            else:
                raise ValueError(kind)
            rec = {"kind": kind, "params": p, "form": form, "variant": var}
            if kind in withheld or kind in ("bias_step", "burst", "telegraph"):
                wcomp[kind] = comp
                truth.append(rec)
            elif comp is not None:
                spec.append(comp)   # a truth component the spec keeps
            else:
                raise ValueError(f"{kind} cannot be in a spec")

        # white noise (heteroskedastic scale), then the output path
        x += nd / math.sqrt(dt) * white_scale * rng.standard_normal(n)
        for what, arg in post:
            if what == "filter":
                order, fc = arg
                bb, aa = signal.butter(order, fc, fs=fs)
                zi = signal.lfilter_zi(bb, aa) * x[0]
                x, _ = signal.lfilter(bb, aa, x, zi=zi)
            elif what == "quant_rate":
                x = np.round(x / arg) * arg
            elif what == "quant_angle":
                ang = np.concatenate([[0.0], np.cumsum(x) * dt])
                qa = np.round(ang / arg) * arg
                x = np.diff(qa) / dt

        d = os.path.join(outdir, self.part, self.name)
        os.makedirs(d, exist_ok=True)
        cols = {"time_s": pa.array(t), "rate": pa.array(x)}
        if temp:
            cols["temp_c"] = pa.array(Tread)
        tbl = pa.table(cols).replace_schema_metadata({"sample_rate_hz": repr(fs), "unit_rate": unit})
        pq.write_table(tbl, os.path.join(d, "real.parquet"), compression="zstd")
        note = f"{self.part}/{self.name}: {self.category}, withheld {self.withheld() or 'nothing'}"
        with open(os.path.join(d, "spec.toml"), "w") as f:
            f.write(spec_toml(fs, unit, temp, spec, note))
        # detectability of each member of a pair: the truth minus that member alone
        # (spec_only_<kind>.toml; `score.py --oracle` runs them), where the other
        # member has a contract form
        oracle = {}
        if self.category == "pair":
            for k in self.withheld():
                others = [wcomp.get(o) for o in self.withheld() if o != k]
                if any(o is None for o in others):
                    continue
                fn = f"spec_only_{k}.toml"
                with open(os.path.join(d, fn), "w") as f:
                    f.write(spec_toml(fs, unit, temp, spec + others,
                                      f"{self.part}/{self.name}: detectability of {k} alone (the other member in the spec)"))
                oracle[k] = fn
        # the truth in contract form: the spec with every withheld effect added in the
        # form the simulator has (spec_truth.toml, when each has one; `score.py --oracle`
        # runs it): whether a diagnosis that found the effects exactly could pass
        truth_spec = None
        if self.withheld() and all(wcomp.get(k) is not None for k in self.withheld()):
            truth_spec = "spec_truth.toml"
            with open(os.path.join(d, truth_spec), "w") as f:
                f.write(spec_toml(fs, unit, temp, spec + [wcomp[k] for k in self.withheld()],
                                  f"{self.part}/{self.name}: the truth in contract form"))
        if self.category == "correct":
            tk = ["none"]
        elif self.category == "non_candidate":
            tk = ["non_candidate"]
        else:
            tk = self.withheld()
        tj = {
            "case": self.name, "part": self.part, "category": self.category,
            "kinds": tk,
            "accept": {k: ACCEPT[k] for k in self.withheld()},
            "contract_kinds": all(k in CONTRACT_KINDS for k in self.withheld()),
            "withheld": truth,
            "spec_components": [c["kind"] for c in spec],
            "detectability_specs": oracle,
            "truth_spec": truth_spec,
            "base": base_truth,
            "rate_hz": fs, "duration_s": T, "n_samples": n, "unit": unit,
            "temperature": ({"profile": self.tprof, "range_c": list(self.trange),
                             "sensor_lag_s": tau_th, "reading": "sensor temperature + 0.02 degC noise, 1/16 degC steps"}
                            if temp else None),
            "size_factor": s, "seed": self.seed,
        }
        with open(os.path.join(d, "truth.json"), "w") as f:
            json.dump(tj, f, indent=1)
        return tj

    def withheld(self):
        if self.category in ("correct", "non_candidate"):
            return []
        return [k for k, _ in self.effects]


# --------------------------------------------------------------------------- the parts

NEEDS_TEMP = {"temperature_bias", "thermal_rate", "heteroskedastic"}

SINGLES = [("constant_bias", ""), ("temperature_bias", "lin"), ("temperature_bias", "quad"),
           ("thermal_rate", ""), ("heteroskedastic", ""), ("warmup", "short"), ("warmup", "long"),
           ("rate_ramp", ""), ("sinusoid", ""), ("gauss_markov", ""), ("rate_random_walk", ""),
           ("bias_instability", ""), ("quantization", "angle"), ("quantization", "rate"),
           ("outliers", ""), ("output_filter", "1"), ("output_filter", "2")]

PAIRS = {
    "dev": [[("temperature_bias", "lin"), ("rate_random_walk", "")],
            [("warmup", "long"), ("rate_ramp", "")],
            [("temperature_bias", "lin"), ("heteroskedastic", "")],
            [("gauss_markov", ""), ("sinusoid", "")],
            [("quantization", "angle"), ("output_filter", "1")],
            [("thermal_rate", ""), ("temperature_bias", "lin")],
            [("bias_instability", ""), ("warmup", "short")],
            [("constant_bias", ""), ("rate_random_walk", "")]],
    "heldout": [[("temperature_bias", "quad"), ("warmup", "short")],
                [("rate_random_walk", ""), ("rate_ramp", "")],
                [("heteroskedastic", ""), ("quantization", "rate")],
                [("sinusoid", ""), ("outliers", "")],
                [("gauss_markov", ""), ("temperature_bias", "lin")],
                [("output_filter", "2"), ("warmup", "long")],
                [("thermal_rate", ""), ("rate_random_walk", "")],
                [("bias_instability", ""), ("temperature_bias", "lin")]],
    # a second held-out draw (eleventh session): pairs that no other part has, each
    # member sized to be seen on its own (see size_for)
    "heldout2": [[("warmup", "short"), ("sinusoid", "")],
                 [("gauss_markov", ""), ("rate_ramp", "")],
                 [("heteroskedastic", ""), ("warmup", "long")],
                 [("thermal_rate", ""), ("constant_bias", "")],
                 [("quantization", "rate"), ("rate_random_walk", "")],
                 [("output_filter", "1"), ("temperature_bias", "quad")],
                 [("bias_instability", ""), ("sinusoid", "")],
                 [("outliers", ""), ("temperature_bias", "lin")]],
    # a second development draw: pairs that neither other part has
    "dev2": [[("temperature_bias", "quad"), ("gauss_markov", "")],
             [("warmup", "short"), ("rate_random_walk", "")],
             [("sinusoid", ""), ("constant_bias", "")],
             [("heteroskedastic", ""), ("rate_ramp", "")],
             [("quantization", "rate"), ("temperature_bias", "lin")],
             [("output_filter", "1"), ("constant_bias", "")],
             [("thermal_rate", ""), ("warmup", "long")],
             [("bias_instability", ""), ("rate_random_walk", "")]],
    # a third development draw (fifteenth session): pairs only, each member as large as
    # heldout2's (2.5-4), in combinations no other part has, to see what a large pair
    # does without looking at the held-out part
    "dev3": [[("temperature_bias", "quad"), ("rate_ramp", "")],
             [("gauss_markov", ""), ("warmup", "long")],
             [("heteroskedastic", ""), ("constant_bias", "")],
             [("thermal_rate", ""), ("sinusoid", "")],
             [("quantization", "angle"), ("temperature_bias", "lin")],
             [("output_filter", "2"), ("constant_bias", "")],
             [("bias_instability", ""), ("rate_ramp", "")],
             [("outliers", ""), ("rate_random_walk", "")],
             [("sinusoid", ""), ("rate_random_walk", "")],
             [("warmup", "short"), ("temperature_bias", "lin")]],
    # a fourth development draw (nineteenth session): non-candidates only
    "dev4": [],
    # a fifth development draw (twenty-second session): singles only, each kind twice
    "dev5": [],
    # held out from the output-path fit by simulation (twenty-second session, scored
    # once after it was written): a quantizer and a filter of every form together
    "path6": [[("quantization", "angle"), ("output_filter", "1")],
              [("quantization", "angle"), ("output_filter", "2")],
              [("quantization", "rate"), ("output_filter", "1")],
              [("quantization", "rate"), ("output_filter", "2")]] * 2,
    # a development draw of the same pairs (twenty-third session): other sizes, rates
    # and lengths than path6, to develop the pair of a coarse rounding and its filter on
    "dev6": [[("quantization", "rate"), ("output_filter", "1")],
             [("quantization", "rate"), ("output_filter", "2")],
             [("quantization", "angle"), ("output_filter", "1")],
             [("quantization", "angle"), ("output_filter", "2")]] * 2,
    # a seventh development draw (twenty-seventh session): dev3's and dev's pairs at
    # dev3's large sizes, every case longer than 2^17 samples and at most 2^20 (what
    # the default --max-samples 2^17 averages and 2^20 did not)
    "dev7": None,
    # a third held-out draw (twenty-eighth session, written before that session's changes
    # and scored once at its end): pairs that no other part has, sized as heldout2's
    "heldout3": [[("thermal_rate", ""), ("gauss_markov", "")],
                 [("heteroskedastic", ""), ("sinusoid", "")],
                 [("outliers", ""), ("warmup", "long")],
                 [("bias_instability", ""), ("constant_bias", "")],
                 [("rate_ramp", ""), ("sinusoid", "")],
                 [("quantization", "angle"), ("rate_ramp", "")],
                 [("output_filter", "2"), ("rate_random_walk", "")],
                 [("heteroskedastic", ""), ("rate_random_walk", "")]],
    # held out from the pair (twenty-third session, scored once after it was written)
    "path7": [[("quantization", "rate"), ("output_filter", "2")],
              [("quantization", "angle"), ("output_filter", "1")],
              [("quantization", "rate"), ("output_filter", "1")],
              [("quantization", "angle"), ("output_filter", "2")]] * 2,
}

PAIRS["dev7"] = PAIRS["dev3"] + PAIRS["dev"]


def draw_pairs(seed, n):
    """`n` distinct pairs of two different withheld kinds (each with one of its forms),
    drawn uniformly from the singles' kinds with numpy's generator seeded `seed`."""
    rng = np.random.default_rng(seed)
    kinds = sorted({k for k, _ in SINGLES})
    forms = {k: [v for kk, v in SINGLES if kk == k] for k in kinds}
    out, seen = [], set()
    while len(out) < n:
        a, b = (kinds[int(i)] for i in rng.choice(len(kinds), 2, replace=False))
        if frozenset((a, b)) in seen:
            continue
        seen.add(frozenset((a, b)))
        out.append([(a, forms[a][int(rng.integers(len(forms[a])))]),
                    (b, forms[b][int(rng.integers(len(forms[b])))])])
    return out


# an eighth development draw (twenty-ninth session): 16 pairs drawn at random from every
# kind, at the held-out pairs' sizes (2.5-4.0), to develop pairs on more than the fixed
# lists above; and a fourth held-out draw of 16 more, written beside it before that
# session changed anything, to score pairs on twice the held-out cases
PAIRS["dev8"] = draw_pairs(38_616_083, 16)
PAIRS["heldout4"] = draw_pairs(39_818_101, 16)
# a fifth held-out draw (thirty-third session, written before that session changed
# anything and scored once): every category, 16 pairs drawn at random from every kind,
# at sizes, rates, lengths and temperature profiles no other part has together
PAIRS["heldout5"] = draw_pairs(41_222_137, 16)
# a tenth development draw (same session), from heldout5's design with its own seeds,
# written after heldout5 was scored to develop on what heldout5 measures without
# reading its cases
PAIRS["dev10"] = draw_pairs(42_424_151, 16)
# a ninth development draw (twenty-ninth session): non-candidates only, as dev4's, at
# other sizes, rates and profiles, to see whether the joint pairs explain them
PAIRS["dev9"] = []

NONCAND = {"dev": [("bias_step", ""), ("bias_step", ""), ("burst", ""), ("burst", ""), ("telegraph", "")],
           "heldout": [("bias_step", ""), ("bias_step", ""), ("burst", ""), ("burst", ""), ("telegraph", "")],
           "dev2": [("bias_step", ""), ("burst", ""), ("telegraph", ""), ("bias_step", ""), ("burst", "")],
           "heldout2": [("burst", ""), ("bias_step", ""), ("telegraph", ""), ("burst", ""), ("bias_step", "")],
           "heldout3": [("telegraph", ""), ("bias_step", ""), ("burst", ""), ("bias_step", ""), ("burst", "")],
           "dev3": [],
           # a development part of non-candidates only, at sizes from small to large
           "dev4": [("bias_step", ""), ("burst", ""), ("telegraph", "")] * 4,
           "heldout5": [("telegraph", ""), ("burst", ""), ("bias_step", ""), ("telegraph", ""), ("burst", "")],
           "dev10": [("telegraph", ""), ("burst", ""), ("bias_step", ""), ("telegraph", ""), ("burst", "")],
           "dev5": [], "path6": [], "dev6": [], "path7": [], "dev7": [], "dev8": [], "heldout4": [],
           "dev9": [("bias_step", ""), ("burst", ""), ("telegraph", "")] * 5}

# correct specs: truth components in their exact contract forms, all in the spec
CORRECT = [[], [("temperature_bias", "exact")], [("warmup", "exact"), ("gauss_markov", "")],
           [("rate_random_walk", "")], [("sinusoid", "exact")], []]

# rates and lengths: the held-out part uses 1 kHz and lengths the dev part never has
GRID = {
    "dev": [(10, 1200), (10, 3600), (10, 7200), (100, 1200), (100, 2400)],
    "heldout": [(10, 4 * 3600), (10, 8 * 3600), (100, 1800), (10, 3 * 3600), (100, 1500)],
    "dev2": [(10, 5400), (10, 6 * 3600), (100, 3600), (100, 900), (10, 2700)],
    # the outside cases are 4 h at 10 Hz with a chamber temperature channel
    "heldout2": [(10, 4 * 3600), (10, 5 * 3600), (100, 2 * 3600), (10, 4 * 3600), (100, 2700)],
    "dev3": [(10, 3600), (10, 3 * 3600), (100, 1800), (10, 2 * 3600), (100, 1200)],
    "dev4": [(10, 2 * 3600), (10, 3 * 3600), (100, 1200), (10, 5400), (100, 1800)],
    # mostly the outside setting (4 h at 10 Hz with a chamber temperature)
    "dev5": [(10, 4 * 3600), (10, 4 * 3600), (10, 4 * 3600), (100, 3600), (10, 9000)],
    "path6": [(10, 3 * 3600), (100, 1800), (100, 3600), (10, 5400)],
    "dev6": [(100, 2400), (100, 1200), (10, 7200), (100, 5400)],
    "path7": [(100, 2700), (10, 4 * 3600), (100, 900), (10, 2 * 3600)],
    "dev7": [(10, 4 * 3600), (10, 6 * 3600), (100, 1800), (100, 3600), (10, 8 * 3600)],
    "heldout3": [(10, 3 * 3600), (10, 6 * 3600), (100, 3600), (100, 1200), (10, 2 * 3600)],
    "dev8": [(10, 3 * 3600), (10, 5 * 3600), (100, 2400), (100, 1800), (10, 4 * 3600)],
    "heldout4": [(10, 4 * 3600), (10, 7 * 3600), (100, 3000), (100, 1500), (10, 9000)],
    "dev9": [(10, 3 * 3600), (10, 4 * 3600), (100, 1200), (100, 2400), (10, 6 * 3600)],
    "heldout5": [(10, 9000), (10, 19800), (100, 2100), (100, 4500), (10, 8 * 3600)],
    "dev10": [(10, 9000), (10, 19800), (100, 2100), (100, 4500), (10, 8 * 3600)],
}
KHZ = {"dev": 0, "heldout": 2, "dev2": 1, "heldout2": 1, "dev3": 0, "dev4": 0, "dev5": 0, "path6": 0, "dev6": 1, "path7": 1, "dev7": 0, "heldout3": 1, "dev8": 1, "heldout4": 1, "dev9": 1, "heldout5": 2, "dev10": 2}      # cases at 1 kHz for 20 min (1.2e6 samples each)
PROFILES = {"dev": ["ramp", "steps", "drift"], "heldout": ["cycle", "soak_ramp", "rw_drift"],
            "dev2": ["drift", "ramp", "steps"], "heldout2": ["soak_ramp", "cycle", "rw_drift"],
            "dev3": ["steps", "drift", "ramp"], "dev4": ["drift", "steps", "ramp"],
            "dev5": ["sine", "ramp", "steps"], "path6": ["drift", "ramp", "steps"],
            "dev6": ["steps", "drift", "ramp"], "path7": ["cycle", "soak_ramp", "rw_drift"],
            "dev7": ["ramp", "steps", "sine"], "heldout3": ["rw_drift", "cycle", "soak_ramp"],
            "dev8": ["cycle", "rw_drift", "ramp"], "heldout4": ["soak_ramp", "sine", "steps"],
            "dev9": ["cycle", "sine", "drift"], "heldout5": ["cycle", "steps", "soak_ramp"],
            "dev10": ["cycle", "steps", "soak_ramp"]}
TRANGE = {"dev": [(-10, 40), (0, 50), (15, 45)], "heldout": [(-40, 85), (-20, 70), (20, 60)],
          "dev2": [(-25, 55), (5, 35), (-5, 60)], "heldout2": [(-30, 70), (10, 50), (-40, 60)],
          "dev3": [(-15, 45), (0, 40), (10, 55)], "dev4": [(-5, 45), (5, 40), (-20, 50)],
          "dev5": [(-20, 60), (0, 45), (-35, 75)], "path6": [(0, 40), (-10, 50), (10, 45)],
          "dev6": [(-5, 45), (5, 35), (-15, 55)], "path7": [(-30, 70), (0, 60), (15, 50)],
          "dev7": [(-15, 50), (0, 40), (-25, 65)], "heldout3": [(-35, 65), (-10, 60), (5, 45)],
          "dev8": [(-20, 55), (0, 45), (-30, 70)], "heldout4": [(-40, 70), (-5, 55), (10, 50)],
          "dev9": [(-10, 50), (-25, 60), (5, 40)],
          "heldout5": [(-30, 60), (-15, 75), (0, 55)],
          "dev10": [(-30, 60), (-15, 75), (0, 55)]}


def size_for(part, rng, category="single"):
    if part in ("dev3", "dev7"):
        return float(rng.uniform(2.5, 4.0))
    if part in ("dev4", "dev9"):
        return float(rng.uniform(0.6, 4.0))
    if part == "path6":
        return float(rng.uniform(0.8, 4.0))
    if part == "dev6":
        return float(rng.uniform(1.0, 3.5))
    if part == "path7":
        return float(rng.uniform(0.7, 4.0))
    if part == "dev5":
        # each kind once small and once large (make_part passes which)
        return float(rng.uniform(0.6, 0.9)) if category == "small" else float(rng.uniform(2.2, 4.0))
    if part in ("dev8", "heldout4"):
        return float(rng.uniform(2.5, 4.0))
    if part in ("heldout2", "heldout3"):
        # a pair's members share one size: the held-out's larger sizes only, so that
        # each member can show beside the other (the first held-out part's small pairs
        # mostly could not, BENCHMARKS "The tenth session"); the rest as the held-out's
        if category == "pair":
            return float(rng.uniform(2.5, 4.0))
        return float(rng.uniform(0.6, 0.85)) if rng.random() < 0.5 else float(rng.uniform(2.5, 4.0))
    if part in ("heldout5", "dev10"):
        # pairs 2.5-4.5; singles, non-candidates and correct specs 0.65-0.8 or 3.0-4.5
        if category == "pair":
            return float(rng.uniform(2.5, 4.5))
        return float(rng.uniform(0.65, 0.8)) if rng.random() < 0.5 else float(rng.uniform(3.0, 4.5))
    if part == "dev":
        return float(rng.uniform(1.0, 2.0))
    if part == "dev2":
        # between dev's sizes and the held-out's: 0.85-1.0 or 2.0-2.5
        return float(rng.uniform(0.85, 1.0)) if rng.random() < 0.5 else float(rng.uniform(2.0, 2.5))
    # held-out: smaller and larger than any dev case
    return float(rng.uniform(0.6, 0.85)) if rng.random() < 0.5 else float(rng.uniform(2.5, 4.0))


def make_part(part):
    rng = np.random.default_rng(PART_SEED[part])
    plan = []
    for k, v in (SINGLES if part not in ("dev3", "dev4", "path6", "dev6", "path7", "dev7", "dev8", "heldout4", "dev9") else []):
        plan.append(("single", [(k, v)], f"single_{k}" + (f"_{v}" if v else "")))
    if part == "dev5":
        plan = [(c, e, n + "_" + sz) for sz in ("small", "large") for c, e, n in plan]
    for pr in PAIRS[part]:
        plan.append(("pair", pr, "pair_" + "+".join(k for k, _ in pr)))
    for i, (k, v) in enumerate(NONCAND[part]):
        plan.append(("non_candidate", [(k, v)], f"noncand_{k}_{i}"))
    for i, eff in enumerate(CORRECT if part not in ("dev3", "dev4", "dev5", "path6", "dev6", "path7", "dev7", "dev8", "heldout4", "dev9") else []):
        plan.append(("correct", eff, f"correct_{i}" + ("_" + "+".join(k for k, _ in eff) if eff else "")))
    cases = []
    khz_left = KHZ[part]
    order = rng.permutation(len(plan))
    khz_pick = set(int(i) for i in order[:khz_left])
    for i, (cat, eff, name) in enumerate(plan):
        kinds = {k for k, _ in eff}
        if i in khz_pick:
            fs, dur = (1000, 600) if part in ("dev2", "dev6") else (1000, 1200)
        else:
            fs, dur = GRID[part][int(rng.integers(len(GRID[part])))]
        need = bool(kinds & NEEDS_TEMP)
        has_temp = need or rng.random() < 0.6 or part == "dev5"
        tprof = PROFILES[part][int(rng.integers(3))] if has_temp else None
        trange = TRANGE[part][int(rng.integers(3))]
        size = size_for(part, rng, name.rsplit("_", 1)[-1] if part == "dev5" else cat)
        seed = PART_SEED[part] * 1000 + i
        cases.append(Case(part, i, f"{i:02d}_{name}", cat, eff, fs, dur, tprof, size, trange, seed))
    return cases


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("outdir")
    ap.add_argument("--part", choices=["dev", "dev2", "dev3", "dev4", "dev5", "path6", "dev6", "path7", "dev7", "dev8", "dev9", "heldout", "heldout2", "heldout3", "heldout4", "heldout5", "dev10", "all"], default="all")
    ap.add_argument("--only", default=None, help="only cases whose name contains this")
    a = ap.parse_args()
    parts = ["dev", "dev2", "dev3", "dev4", "dev5", "heldout", "heldout2"] if a.part == "all" else [a.part]
    for part in parts:
        cases = make_part(part)
        index = []
        for c in cases:
            if a.only and a.only not in c.name:
                continue
            tj = c.build(a.outdir)
            index.append({k: tj[k] for k in ("case", "category", "kinds", "rate_hz", "duration_s", "n_samples")})
            print(f"{part}/{c.name}: {tj['n_samples']} samples at {tj['rate_hz']:g} Hz, "
                  f"{(tj['temperature'] or {}).get('profile', 'no temperature')}, size {tj['size_factor']:.2f}",
                  file=sys.stderr)
        with open(os.path.join(a.outdir, part, "cases.json"), "w") as f:
            json.dump(index, f, indent=1)


if __name__ == "__main__":
    main()
