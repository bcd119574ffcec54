#!/usr/bin/env bash
# The gap diagnosis's false-alarm rate (issue 27): logs simulated from a spec and
# diagnosed against that same spec, over SEEDS seeds; counts the runs declared
# significant, those that added an effect and those not `explained`. Two specs: the ADIS16405 datasheet
# (100 Hz, gyro_x_dps) and a MEMS-like gyro with a warm-up, a ramp and a Gauss-Markov
# term at 10 Hz written below. The diagnosis runs with its defaults and a seed of its
# own, so that its ensemble never shares the log's noise. Also prints, per spec, the
# median, 0.95 quantile and largest gap_before / gap_threshold (how near the threshold
# a correct spec comes: a threshold at the 95 % level puts that quantile near 1).
#   bash benches/gap_false_alarm.sh FARMA [SEEDS] [DURATION_S] [GAP_FLAGS]
# (GAP_FLAGS: extra flags of every diagnosis, e.g. "--max-samples 65536")
set -eu
farma=${1:?path of the farma binary}
seeds=${2:-20}
dur=${3:-3600}
flags=${4:-}
root=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cat > "$work/mems.toml" <<'TOML'
sample_rate_hz = 10.0
[[channel]]
name = "rate"
[[channel.component]]
kind = "white_noise"
n = 0.01
[[channel.component]]
kind = "bias_instability"
b = 0.002
[[channel.component]]
kind = "warmup"
amplitude = 0.05
tau_s = 600.0
[[channel.component]]
kind = "rate_ramp"
r = 2e-6
[[channel.component]]
kind = "gauss_markov"
sigma = 0.01
tau_s = 30.0
TOML
for pair in "$root/fixtures/specs/adis16405_datasheet.toml:gyro_x_dps" "$work/mems.toml:rate"; do
  spec=${pair%%:*}; ch=${pair##*:}
  name=$(basename "$spec" .toml)
  sig=0; add=0; unexp=0; runs=0
  for s in $(seq 1 "$seeds"); do
    log="$work/$name-$s.parquet"
    "$farma" simulate "$spec" --duration "$dur" --seed "$((1000 + s))" -o "$log" >/dev/null 2>&1 \
      || { echo "$name seed $s: simulate failed" >&2; continue; }
    out=$("$farma" gap --real "$log" --sim "$spec" --channel "$ch" --seed "$((5000 + s))" $flags --json --no-cache 2>/dev/null) \
      || { echo "$name seed $s: gap failed" >&2; continue; }
    runs=$((runs + 1))
    if echo "$out" | python3 -c 'import json,sys; sys.exit(0 if json.load(sys.stdin)["significant"] else 1)'; then sig=$((sig + 1)); fi
    if echo "$out" | python3 -c 'import json,sys; sys.exit(0 if json.load(sys.stdin)["added"] else 1)'; then add=$((add + 1)); fi
    if echo "$out" | python3 -c 'import json,sys; sys.exit(1 if json.load(sys.stdin)["explained"] else 0)'; then unexp=$((unexp + 1)); fi
    echo "$out" | python3 -c 'import json,sys; d=json.load(sys.stdin); print(d["gap_before"] / d["gap_threshold"])' >> "$work/$name-ratio.txt"
    rm -f "$log"
  done
  echo "$name ($ch, $dur s): $runs runs, significant $sig, added an effect $add, not explained $unexp"
  # how near the threshold the correct spec's gaps come: gap_before / gap_threshold
  python3 - "$work/$name-ratio.txt" <<'PY'
import sys
r = sorted(float(v) for v in open(sys.argv[1]))
q = lambda p: r[min(len(r) - 1, int(round(p * (len(r) - 1))))]
print(f"  gap_before / gap_threshold: median {q(0.5):.3f}, 0.95 quantile {q(0.95):.3f}, max {r[-1]:.3f}")
PY
done
