#!/bin/bash
# The gap diagnosis of the ADIS16405 runs 1-4 against the datasheet spec (issue 27's
# real-data bar), then each spec_after.toml simulated and diagnosed again against itself.
# Usage: bash benches/gap_adis.sh BINARY OUTDIR [REALDATA_DIR] [GAP_FLAGS]
# (GAP_FLAGS: extra flags of both diagnoses, e.g. "--max-samples 65536")
# Prints one table row per run (README "Real data: the ADIS16405 datasheet ...").
set -euo pipefail
B=$1; O=$2; D=${3:-../shared/realdata/imudata-adis16405}; F=${4:-}
SPEC=$(dirname "$0")/../fixtures/specs/adis16405_datasheet.toml
mkdir -p "$O"
for r in 1 2 3 4; do
  /usr/bin/time -f "%e s %M KB" "$B" gap --real "$D/adis_16405_imu$r.parquet" --sim "$SPEC" \
      --channel gyro_x_dps --replicas 10 $F --json -q -o "$O/g$r" > "$O/g$r.json" 2> "$O/g$r.err"
  "$B" simulate "$O/g$r/spec_after.toml" --duration 10000 --seed 1234 -o "$O/s$r.parquet" 2>/dev/null
  "$B" gap --real "$O/s$r.parquet" --sim "$O/g$r/spec_after.toml" --channel gyro_x_dps \
      --replicas 10 $F --json -q -o "$O/re$r" > "$O/re$r.json" 2> "$O/re$r.err"
done
python3 - "$O" <<'PY'
import json, sys
o = sys.argv[1]
print("| run | gap (averaged; per-sample part) | floor | added: first pass, averaged, per-sample part; each by contribution (share of its part's final model) | explained | spec_after simulated, diagnosed again | time, peak RSS |")
print("|---|---|---|---|---|---|---|")
for r in [1, 2, 3, 4]:
    g = json.load(open(f"{o}/g{r}.json")); q = json.load(open(f"{o}/re{r}.json"))
    t = open(f"{o}/g{r}.err").read().strip().splitlines()[-1]
    def eff(a):
        p, k, x = a["params"], a["kind"], ""
        if k == "output_filter" and p.get("form") == "fir":
            x = f" fir theta {p['taps'][1] / p['taps'][0]:.3f}" if len(p["taps"]) == 2 else f" fir {len(p['taps'])} taps"
            if "white_noise_n" in p:
                x += f", white n {p['white_noise_n']:.4f}"
        elif k == "output_filter":
            x = f" order {p.get('order')} {p.get('discretization', 'zoh')} {p.get('bandwidth_hz', 0):.3g} Hz"
            if "white_noise_n" in p:
                x += f", white n {p['white_noise_n']:.4f}"
        elif k == "constant_bias":
            x = f" {p['value']:.3f}"
        elif k == "output_resolution":
            x = f" {p.get('quantum'):.3g}" + (" on the angle" if p.get("on_angle") else " on the rate")
        return f"{k}{x} ({a.get('contribution') or 0:.2f})"
    def part(a):
        return " [per-sample]" if a.get("part") == "per_sample" else ""
    added = "; ".join(eff(a) + part(a) for a in g["added_effects"])
    def gaps(d):
        s = f"{d['gap_before']:.2f} -> {d['gap_after']:.2f}"
        p = d.get("per_sample")
        return s + (f"; per-sample {p['gap_before']:.2f} -> {p['gap_after']:.2f}" if p else "")
    def floors(d):
        p = d.get("per_sample")
        return f"{d['noise_floor']:.2f}" + (f"; {p['noise_floor']:.2f}" if p else "")
    def again(q):
        p = q.get("per_sample")
        s = f"{q['gap_before']:.2f} (threshold {q['gap_threshold']:.2f})"
        return s + (f"; per-sample {p['gap_before']:.2f} (threshold {p['gap_threshold']:.2f})" if p else "")
    sig = "significant" if q["significant"] else "not significant"
    print(f"| {r} | {gaps(g)} | {floors(g)} | {added} | "
          f"{g.get('explained')} | {again(q)}, {sig}, "
          f"{len(q['added_effects'])} added | {t} |")
PY
