#!/usr/bin/env bash
# The resume check of `farma batch` (issue 26): NLOGS simulated 3-axis logs (the
# ADIS16405 datasheet spec, SECONDS s at 100 Hz, seeds 1..NLOGS) and two bad ones;
# a fit and a select task per log. Runs the job once cleanly, then again into a
# second root killed with SIGKILL at KILLS random moments and resumed after each,
# then 4 shards at once into a third root; compares every dataset file (the manifest
# aside) of the three with cmp, and reports wall times.
#
#     bash benches/batch_kill.sh [BIN]      # NLOGS=20 SECONDS=2000 KILLS=3 by default
set -euo pipefail
bin="$(realpath "${1:-target/release/farma}")"
here="$(cd "$(dirname "$0")/.." && pwd)"
n="${NLOGS:-20}"
secs="${SECONDS_PER_LOG:-2000}"
kills="${KILLS:-3}"
w="${TMPDIR:-/tmp}/farma-batch-kill"
rm -rf "$w"
mkdir -p "$w/logs"
export FARMA_CACHE_DIR="$w/cache"
for i in $(seq 1 "$n"); do
  "$bin" simulate "$here/fixtures/specs/adis16405_datasheet.toml" --duration "$secs" --seed "$i" -q -o "$w/logs/sim$i.parquet" >/dev/null 2>&1
done
cp "$here/fixtures/bad/nan_inf.csv" "$here/fixtures/bad/truncated.parquet" "$w/logs/"
cat >"$w/job.toml" <<JOB
[[inputs]]
paths = ["logs/"]
[[tasks]]
kind = "fit"
order = "2,1,1"
[[tasks]]
kind = "select"
orders = "1,1,1;2,1,1"
bootstrap = 0
JOB
t0=$(date +%s.%N)
if [[ -x /usr/bin/time ]]; then
  /usr/bin/time -f "%M" -o "$w/clean.maxrss" "$bin" batch "$w/job.toml" -o "$w/clean" --json >"$w/clean.json" 2>/dev/null || true
  echo "clean run peak RSS: $(cat "$w/clean.maxrss" | tail -1) KiB"
else
  "$bin" batch "$w/job.toml" -o "$w/clean" --json >"$w/clean.json" 2>/dev/null || true
fi
t1=$(date +%s.%N)
echo "clean run: $(echo "$t1 - $t0" | bc) s: $(cat "$w/clean.json")"
for k in $(seq 1 "$kills"); do
  "$bin" batch "$w/job.toml" -o "$w/killed" >/dev/null 2>&1 &
  pid=$!
  # a random moment within the clean run's length
  sleep "$(awk -v s=$RANDOM -v t="$(echo "$t1 - $t0" | bc)" 'BEGIN{srand(s); printf "%.2f", 0.1 + rand() * 0.9 * t}')"
  kill -9 "$pid" 2>/dev/null || true
  wait "$pid" 2>/dev/null || true
  echo "kill $k: $(ls "$w/killed/_manifest" 2>/dev/null | wc -l) unit rows after the kill"
done
"$bin" batch "$w/job.toml" -o "$w/killed" --json >"$w/resume.json" 2>/dev/null || true
echo "resume: $(cat "$w/resume.json")"
for s in 1 2 3 4; do
  "$bin" batch "$w/job.toml" -o "$w/sharded" --shard "$s/4" >/dev/null 2>&1 &
done
wait || true
"$bin" batch "$w/job.toml" -o "$w/sharded" --status
same() {
  local a="$1" b="$2" bad=0
  while IFS= read -r f; do
    cmp -s "$a/$f" "$b/$f" || { echo "differs: $f"; bad=1; }
  done < <(cd "$a" && find . -type f -not -path './_manifest/*' -not -name manifest.parquet | sort)
  diff <(cd "$a" && find . -type f -not -path './_manifest/*' -not -name manifest.parquet -not -path './.staging/*' | sort) \
       <(cd "$b" && find . -type f -not -path './_manifest/*' -not -name manifest.parquet -not -path './.staging/*' | sort) >/dev/null || { echo "file lists differ"; bad=1; }
  return $bad
}
same "$w/clean" "$w/killed" && echo "killed and resumed: identical to the clean run"
same "$w/clean" "$w/sharded" && echo "4 shards: identical to the clean run"
