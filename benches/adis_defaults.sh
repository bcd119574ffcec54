#!/bin/bash
# The noise-term defaults on the real ADIS16405 runs (issue 28's bar): per run and
# gyro axis, the bias instability b found by `farma adev` with its defaults, b with
# --fit-tau-min 0.08, their ratio, the ratio to the published Allan curve of run 1
# (../shared/realdata/avar-allan-curves/adis_av.csv, b = its minimum / 0.664; run 1
# only), the first tau the defaults chose and the warnings they printed; then the
# curve-minimum reading (`bias_instability_reading`: min ADEV / 0.664, as datasheets
# and the published curve read it) and its ratio to the published value.
# Usage: bash benches/adis_defaults.sh [FARMA_BINARY]   (prints a markdown table)
set -euo pipefail
F=${1:-target/release/farma}
D=${REALDATA:-../shared/realdata}
echo "| run | axis | b default [deg/s] | b at --fit-tau-min 0.08 | ratio | b published (run 1) | ratio | tau_min chosen [s] | dispersion | other terms (default) | warnings (default) | reading [deg/s] (tau) | reading / published |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|"
for r in 1 2 3 4; do
  for a in x y z; do
    log=$D/imudata-adis16405/adis_16405_imu$r.parquet
    def=$("$F" adev "$log" --channel gyro_${a}_dps --json 2>/tmp/adis_defaults.err.$$)
    warn=$(grep -c '^farma: warning' /tmp/adis_defaults.err.$$ || true)
    at=$("$F" adev "$log" --channel gyro_${a}_dps --json --fit-tau-min 0.08 2>/dev/null)
    A=$(echo $a | tr xyz XYZ)
    pub=""
    [ "$r" = 1 ] && pub=$(awk -F, -v ch="Gyro. $A" '$4==ch{if(m==""||$6<m)m=$6}END{printf "%.6f", m/0.664}' $D/avar-allan-curves/adis_av.csv)
    python3 - "$r" "$a" "$def" "$at" "$pub" "$warn" <<'PY'
import json, sys
r, a, d, t, pub, warn = sys.argv[1:]
d, t = json.loads(d), json.loads(t)
def b(o):
    bi = (o.get("terms") or {}).get("bias_instability")
    return (bi["b"], bi["b_unc"]) if bi else (None, None)
bd, ud = b(d); bt, ut = b(t)
fmt = lambda v, u: "-" if v is None else f"{v:.5f} ± {u:.5f}"
ratio = lambda x, y: "-" if x is None or y is None else f"{x / y:.2f}"
pubv = float(pub) if pub else None
others = ", ".join(k for k in (d.get("terms") or {}) if k != "bias_instability")
rd = d.get("bias_instability_reading")
rdv = None if rd is None else rd["b"]
rds = "-" if rd is None else f"{rd['b']:.5f} ± {rd['b_unc']:.5f} ({rd['tau_s']:g} s{', last tau' if rd['at_last_tau'] else ''})"
print(f"| {r} | {a} | {fmt(bd, ud)} | {fmt(bt, ut)} | {ratio(bd, bt)} | "
      f"{'-' if pubv is None else f'{pubv:.5f}'} | {ratio(bd, pubv)} | "
      f"{d['terms_fit']['tau_min_s']:g} | {d['terms_fit']['dispersion']:.2f} | {others} | {warn} | "
      f"{rds} | {ratio(rdv, pubv)} |")
PY
  done
done
rm -f /tmp/adis_defaults.err.$$
