#!/usr/bin/env bash
# The resume check of `farma batch` (issue 26). Two jobs:
# - MODE=small (default): NLOGS simulated 3-axis logs (the ADIS16405 datasheet spec,
#   SECONDS_PER_LOG s at 100 Hz, seeds 1..NLOGS) and two bad ones; a fit and a select
#   task per log (NLOGS=20 SECONDS_PER_LOG=2000 by default);
# - MODE=bar: the issue's job: NLOGS (default 50) 6-channel logs of SECONDS_PER_LOG
#   (default 10000: 1e6 samples at 100 Hz) from a spec per log with varied parameters
#   (three gyro axes, white noise n and bias instability b varied with the log's
#   index, a rate random walk on every third log; a temperature channel; two
#   accelerometer axes), two bad logs among them; the tasks analyze (every default:
#   the gyro axes) and adev.
# Runs the job once cleanly, then again into a second root killed with SIGKILL at KILLS
# random moments (each drawn within the work left: the clean run's time times the
# share of units not yet done) and resumed after each, then 4 shards at once into a
# third root; compares every dataset file (the manifest aside) of the three with cmp,
# and reports wall times, the clean run's peak RSS and whether each kill interrupted.
#
#     bash benches/batch_kill.sh [BIN]      # MODE NLOGS SECONDS_PER_LOG KILLS THREADS ONLY_CLEAN
set -euo pipefail
# seconds from $1 to $2 (default: now), without bc
since() { awk -v a="$1" -v b="${2:-$(date +%s.%N)}" 'BEGIN{printf "%.2f", b - a}'; }
bin="$(realpath "${1:-target/release/farma}")"
here="$(cd "$(dirname "$0")/.." && pwd)"
mode="${MODE:-small}"
if [[ "$mode" == bar ]]; then
  n="${NLOGS:-50}"
  secs="${SECONDS_PER_LOG:-10000}"
else
  n="${NLOGS:-20}"
  secs="${SECONDS_PER_LOG:-2000}"
fi
kills="${KILLS:-3}"
threads=()
if [[ -n "${THREADS:-}" ]]; then threads=(--threads "$THREADS"); fi
w="${TMPDIR:-/tmp}/farma-batch-kill"
if [[ -n "${KEEP_LOGS:-}" && -d "$w/logs" ]]; then
  # the logs of an earlier run of the same MODE, NLOGS and SECONDS_PER_LOG, kept
  rm -rf "$w/clean" "$w/killed" "$w/sharded" "$w/cache"
else
  rm -rf "$w"
fi
mkdir -p "$w/logs" "$w/specs"
export FARMA_CACHE_DIR="$w/cache"
spec6() { # the bar's spec of log $1
  local i="$1"
  local nw b
  nw=$(awk -v i="$i" 'BEGIN{printf "%.6f", 0.02 + 0.001 * (i % 30)}')
  b=$(awk -v i="$i" 'BEGIN{printf "%.6f", 0.003 + 0.0002 * (i % 20)}')
  echo "sample_rate_hz = 100.0"
  echo "seed = $i"
  for ax in x y z; do
    echo "[[channel]]"
    echo "name = \"gyro_${ax}_dps\""
    echo "[[channel.component]]"
    echo "kind = \"white_noise\""
    echo "n = $nw"
    echo "[[channel.component]]"
    echo "kind = \"bias_instability\""
    echo "b = $b"
    if (( i % 3 == 0 )); then
      echo "[[channel.component]]"
      echo "kind = \"rate_random_walk\""
      echo "k = 0.0001"
    fi
  done
  echo "[[channel]]"
  echo "name = \"temp_c\""
  echo "[[channel.component]]"
  echo "kind = \"constant_bias\""
  echo "value = 25.0"
  echo "[[channel.component]]"
  echo "kind = \"gauss_markov\""
  echo "sigma = 0.5"
  echo "tau_s = 600.0"
  for ax in x y; do
    echo "[[channel]]"
    echo "name = \"accel_${ax}_g\""
    echo "[[channel.component]]"
    echo "kind = \"white_noise\""
    echo "n = 0.001"
  done
}
gen() {
  local i="$1"
  if [[ "$mode" == bar ]]; then
    spec6 "$i" >"$w/specs/log$i.toml"
    "$bin" --threads 1 simulate "$w/specs/log$i.toml" --duration "$secs" -q -o "$w/logs/sim$i.parquet" >/dev/null 2>&1
  else
    "$bin" --threads 1 simulate "$here/fixtures/specs/adis16405_datasheet.toml" --duration "$secs" --seed "$i" -q -o "$w/logs/sim$i.parquet" >/dev/null 2>&1
  fi
}
# the logs, as many at once as the machine has cores
jobs_at_once="$(nproc 2>/dev/null || echo 2)"
for i in $(seq 1 "$n"); do
  if [[ -n "${KEEP_LOGS:-}" && -s "$w/logs/sim$i.parquet" ]]; then continue; fi
  gen "$i" &
  if (( i % jobs_at_once == 0 )); then wait; fi
done
wait
cp "$here/fixtures/bad/nan_inf.csv" "$here/fixtures/bad/truncated.parquet" "$w/logs/"
if [[ "$mode" == bar ]]; then
  cat >"$w/job.toml" <<JOB
[[inputs]]
paths = ["logs/"]
[[tasks]]
kind = "analyze"
[[tasks]]
kind = "adev"
JOB
else
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
fi
echo "mode $mode: $n logs of $secs s at 100 Hz (+2 bad), generated in $w/logs"
t0=$(date +%s.%N)
if [[ -x /usr/bin/time ]]; then
  /usr/bin/time -f "%M" -o "$w/clean.maxrss" "$bin" "${threads[@]}" batch "$w/job.toml" -o "$w/clean" --json >"$w/clean.json" 2>"$w/clean.err" || true
  echo "clean run peak RSS: $(cat "$w/clean.maxrss" | tail -1) KiB"
else
  "$bin" "${threads[@]}" batch "$w/job.toml" -o "$w/clean" --json >"$w/clean.json" 2>"$w/clean.err" || true
fi
t1=$(date +%s.%N)
tclean=$(since "$t0" "$t1")
echo "clean run: $tclean s: $(cat "$w/clean.json")"
if [[ -n "${ONLY_CLEAN:-}" ]]; then exit 0; fi
units=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["units"])' "$w/clean.json" 2>/dev/null || echo 0)
for k in $(seq 1 "$kills"); do
  rows=$( (ls "$w/killed/_manifest" 2>/dev/null || true) | wc -l)
  # a random moment within the work left: the clean run's time times the share of
  # units without a manifest row yet (failed units have one too)
  left=$(awk -v u="$units" -v r="$rows" -v t="$tclean" 'BEGIN{ if (u > 0) printf "%.3f", t * (u - r) / u; else printf "%.3f", t }')
  at=$(awk -v s=$RANDOM -v t="$left" 'BEGIN{srand(s); printf "%.2f", 0.1 + rand() * 0.9 * t}')
  "$bin" "${threads[@]}" batch "$w/job.toml" -o "$w/killed" >/dev/null 2>&1 &
  pid=$!
  sleep "$at"
  if kill -9 "$pid" 2>/dev/null; then how="interrupted"; else how="the run had finished: not interrupted"; fi
  wait "$pid" 2>/dev/null || true
  echo "kill $k at $at s (of about $left s of work left): $how; $( (ls "$w/killed/_manifest" 2>/dev/null || true) | wc -l) of $units unit rows after it"
done
t2=$(date +%s.%N)
"$bin" "${threads[@]}" batch "$w/job.toml" -o "$w/killed" --json >"$w/resume.json" 2>/dev/null || true
echo "resume: $(since "$t2") s: $(cat "$w/resume.json")"
t3=$(date +%s.%N)
for s in 1 2 3 4; do
  "$bin" "${threads[@]}" batch "$w/job.toml" -o "$w/sharded" --shard "$s/4" >/dev/null 2>&1 &
done
wait || true
echo "4 shards at once: $(since "$t3") s"
"$bin" batch "$w/job.toml" -o "$w/sharded" --status
same() {
  local a="$1" b="$2" bad=0
  while IFS= read -r f; do
    if [[ "$f" == *.txt ]]; then
      # a text summary states its run's wall time: compared without it
      cmp -s <(sed -E 's/[0-9]+\.[0-9]+ s\)/T s)/' "$a/$f") <(sed -E 's/[0-9]+\.[0-9]+ s\)/T s)/' "$b/$f") || { echo "differs: $f"; bad=1; }
    else
      cmp -s "$a/$f" "$b/$f" || { echo "differs: $f"; bad=1; }
    fi
  done < <(cd "$a" && find . -type f -not -path './_manifest/*' -not -name manifest.parquet | sort)
  diff <(cd "$a" && find . -type f -not -path './_manifest/*' -not -name manifest.parquet -not -path './.staging/*' | sort) \
       <(cd "$b" && find . -type f -not -path './_manifest/*' -not -name manifest.parquet -not -path './.staging/*' | sort) >/dev/null || { echo "file lists differ"; bad=1; }
  return $bad
}
same "$w/clean" "$w/killed" && echo "killed and resumed: identical to the clean run"
same "$w/clean" "$w/sharded" && echo "4 shards: identical to the clean run"
