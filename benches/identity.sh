#!/usr/bin/env bash
# The byte-identity check of a refactor: run the commands whose tables must not change
# (fit, fit --index, update, check, analyze, select, simulate, gap) with one farma
# binary on the fixtures and, when ../shared/realdata is there, on two ADIS16405 runs,
# writing every output under OUT. Run it with the binary before a change and with the
# binary after, then compare the two folders:
#
#     bash benches/identity.sh run  BIN_BEFORE /tmp/id-before
#     bash benches/identity.sh run  BIN_AFTER  /tmp/id-after
#     bash benches/identity.sh diff /tmp/id-before /tmp/id-after
#
# `diff` compares every file with `cmp`, except the lines of wall-clock time that a
# command writes on purpose (the elapsed time in summary.txt, "timings" in JSON), which
# it removes from both sides first; it prints each file that differs and exits 1 if
# any does. `run` with FARMA_IDENTITY_SHORT=1 took under a minute per binary on 2 cores (2026-11-27, two runs back to back); the ADIS part adds more; set
# FARMA_IDENTITY_SHORT=1 to skip the real runs. Outputs record the paths and the
# modification times of the files they read: run both sides from one checkout, one
# after the other (the runs share a scratch folder).
set -euo pipefail

here="$(cd "$(dirname "$0")/.." && pwd)"
realdata="${FARMA_REALDATA:-$here/../shared/realdata/imudata-adis16405}"

run() {
  local bin final out
  bin="$(realpath "$1")"
  final="$2"
  # Outputs record the paths they were written to and read from (model folders,
  # specs): every run writes into the same scratch folder, then moves it to OUT.
  out="${TMPDIR:-/tmp}/farma-identity-scratch"
  rm -rf "$out" "$final"
  mkdir -p "$out" "$(dirname "$final")"
  export FARMA_CACHE_DIR="$out/.cache"
  cd "$here"
  local fx=fixtures/multiaxis.csv
  step() { # name, then the command's arguments; stdout to name.out
    local name="$1"
    shift
    echo "== $name: farma $*" >&2
    local rc=0
    "$bin" "$@" >"$out/$name.out" 2>"$out/$name.err" || rc=$?
    if [[ $rc != 0 ]]; then
      echo "   exit $rc (kept: the exit code and the message are part of the check)" >&2
    fi
    echo "exit $rc" >>"$out/$name.err"
  }
  # the fixture: every channel, both paths, both indexes, state and update
  step fit_fast fit "$fx" --channel all --order 2,1,1 --save-state --residuals --json -o "$out/fit_fast"
  step fit_direct fit "$fx" --channel gyro_x,gyro_y --order 1,1,1 --method direct --grid 41 --json -o "$out/fit_direct"
  step fit_literal fit "$fx" --channel gyro_x --order 2,1,1 --init literal --json -o "$out/fit_literal"
  step fit_q2 fit "$fx" --channel gyro_x,gyro_y --order 3,2,1 --save-state --json -o "$out/fit_q2"
  step fit_index fit "$fx" --channel gyro_x,gyro_y --order 2,1,1 --index lag,temp_c --index-grid 11,11 --json -o "$out/fit_index"
  step fit_index_res fit "$fx" --channel gyro_x --order 2,1,1 --index lag,temp_c --index-lag 2 --index-grid 7,9 --residuals --json -o "$out/fit_index_res"
  step update update "$out/fit_fast" fixtures/multiaxis.parquet --channel gyro_x,gyro_y --no-time-check --json -o "$out/update"
  step update_lambda update "$out/fit_q2" fixtures/multiaxis.parquet --channel gyro_x --no-time-check --forgetting 0.999 --json -o "$out/update_lambda"
  step check check "$out/fit_fast" "$fx" --json -o "$out/check"
  # a refusal (check takes the lag index alone): its message is compared too
  step check_index check "$out/fit_index" "$fx" --json -o "$out/check_index"
  step select select "$fx" --channel gyro_x --bootstrap 9 --grid 51 --json -o "$out/select"
  step analyze analyze "$fx" --bootstrap 19 --grid 51 --json -o "$out/analyze"
  step simulate simulate fixtures/specs/adis16405_datasheet.toml --duration 600 --seed 3 --json -o "$out/sim_adis.parquet"
  mkdir -p "$out/specs/fits"
  cp fixtures/specs/every_component.toml "$out/specs/"
  "$bin" fit "$fx" --channel gyro_y --order 2,1,1 -o "$out/specs/fits/gyro_y" >/dev/null 2>&1 || true
  step simulate_every simulate "$out/specs/every_component.toml" --duration 400 --like "$fx" --seed 5 --json -o "$out/sim_every.parquet"
  step gap gap --real "$fx" --sim "$out/specs/every_component.toml" --channel gyro_x --replicas 6 --json -o "$out/gap"
  if [[ -z "${FARMA_IDENTITY_SHORT:-}" && -d "$realdata" ]]; then
    for r in 1 2; do
      local log="$realdata/adis_16405_imu$r.parquet"
      step "adis${r}_fit" fit "$log" --channel gyro_x_dps,gyro_y_dps,gyro_z_dps --order 2,1,1 --save-state --json -o "$out/adis${r}_fit"
      step "adis${r}_check" check "$out/adis${r}_fit" "$log" --json -o "$out/adis${r}_check"
      step "adis${r}_analyze" analyze "$log" --channel gyro_z_dps --bootstrap 0 --orders "1,1,1;2,1,1" --json -o "$out/adis${r}_analyze"
      step "adis${r}_gap" gap --real "$log" --sim fixtures/specs/adis16405_datasheet.toml --channel gyro_x_dps --replicas 5 --max-effects 2 --json -o "$out/adis${r}_gap"
    done
    step adis_update update "$out/adis1_fit" "$realdata/adis_16405_imu2.parquet" --no-time-check --json -o "$out/adis_update"
  fi
  rm -rf "$out/.cache"
  mv "$out" "$final"
}

# A file's bytes with the wall-clock lines taken out.
scrub() {
  case "$1" in
    *.json | *.out) sed -E 's/"(total_s|elapsed_s|wall_s|[a-z_]*_s)":[-0-9.eE+]+/"\1":T/g; s/"timings":\{[^}]*\}/"timings":T/g' "$1" ;;
    *summary.txt | *.err) sed -E 's/[0-9]+(\.[0-9]+)? s\b/T s/g' "$1" ;;
    *) cat "$1" ;;
  esac
}

diff_dirs() {
  local a="$1" b="$2" bad=0 n=0
  while IFS= read -r f; do
    n=$((n + 1))
    if [[ ! -e "$b/$f" ]]; then
      echo "only before: $f"
      bad=1
    elif ! cmp -s "$a/$f" "$b/$f"; then
      if ! cmp -s <(scrub "$a/$f") <(scrub "$b/$f"); then
        echo "differs: $f"
        bad=1
      fi
    fi
  done < <(cd "$a" && find . -type f | sort)
  while IFS= read -r f; do
    [[ -e "$a/$f" ]] || { echo "only after: $f"; bad=1; }
  done < <(cd "$b" && find . -type f | sort)
  echo "$n files compared" >&2
  return $bad
}

case "${1:-}" in
  run) run "$2" "$3" ;;
  diff) diff_dirs "$2" "$3" ;;
  *)
    echo "usage: identity.sh run BIN OUT | identity.sh diff OUT_BEFORE OUT_AFTER" >&2
    exit 2
    ;;
esac
