#!/usr/bin/env bash
# `farma fit` on a linear ARMA(2,1) of N samples (default 1e6) against statsmodels'
# ARIMA(x, order=(2,0,1), trend="n").fit() on the same series, in the same run (issue 25's
# bar: the whole farma process, from a Parquet file, no cache, >= 100x faster).
# The series: x_t = 0.5 x_{t-1} - 0.3 x_{t-2} + e_t + 0.4 e_{t-1}, unit Gaussian e
# (numpy, seed 1), written with pyarrow as the column `x` at 100 Hz (`time_s`).
#
#     bash benches/arma_peer.sh [BIN]        # N=1e6 REPS=3 (farma; statsmodels once)
# Needs python3 with numpy, pyarrow and statsmodels.
set -euo pipefail
bin="$(realpath "${1:-target/release/farma}")"
n="${N:-1000000}"
reps="${REPS:-3}"
w="${TMPDIR:-/tmp}/farma-arma-peer"
rm -rf "$w"; mkdir -p "$w"
python3 - "$n" "$w/arma21.parquet" <<'PY'
import sys, numpy as np, pyarrow as pa, pyarrow.parquet as pq
n = int(float(sys.argv[1])); rng = np.random.default_rng(1)
e = rng.standard_normal(n + 500); x = np.zeros(n + 500)
for t in range(2, n + 500):
    x[t] = 0.5 * x[t-1] - 0.3 * x[t-2] + e[t] + 0.4 * e[t-1]
x = x[500:]
pq.write_table(pa.table({"time_s": np.arange(n) / 100.0, "x": x}), sys.argv[2])
PY
best=""
for r in $(seq 1 "$reps"); do
  t0=$(date +%s.%N)
  "$bin" fit "$w/arma21.parquet" --channel x --order 2,1,1 --no-cache -q -o "$w/fit" 2>"$w/fit.err"
  t=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN{printf "%.3f", b - a}')
  echo "farma fit (whole process, Parquet, no cache) run $r: $t s"
  if [[ -z "$best" ]] || awk -v t="$t" -v b="$best" 'BEGIN{exit !(t < b)}'; then best="$t"; fi
done
grep -E "fit x:|ladder|linear start|GCV" "$w/fit.err" | head -5 || true
sm=$(python3 - "$w/arma21.parquet" <<'PY'
import sys, time, warnings, pyarrow.parquet as pq
from statsmodels.tsa.arima.model import ARIMA
x = pq.read_table(sys.argv[1]).column("x").to_numpy()
warnings.simplefilter("ignore")
t0 = time.perf_counter()
r = ARIMA(x, order=(2, 0, 1), trend="n").fit()
print(f"{time.perf_counter() - t0:.3f} {r.params[0]:.4f} {r.params[1]:.4f} {r.params[2]:.4f}")
PY
)
read -r smt a1 a2 b1 <<<"$sm"
echo "statsmodels ARIMA(2,0,1) fit: $smt s (ar $a1 $a2, ma $b1)"
echo "ratio (statsmodels / best farma): $(awk -v s="$smt" -v b="$best" 'BEGIN{printf "%.1f", s / b}')x"
