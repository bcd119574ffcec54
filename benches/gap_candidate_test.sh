#!/usr/bin/env bash
# The candidate test's null distribution (issue 27, CANDIDATE_TEST_D in
# src/diagnosis/mod.rs): logs simulated by `farma simulate` from a spec and diagnosed
# against that same spec; for each, the drop of the squared gap that the first round's
# best candidate gives on the withheld part (gap_before^2 - its gap_after^2). Logs:
# the two specs of gap_false_alarm.sh (1 h, 10 seeds each); the right specs of the
# bank's parts dev and dev2 (on their logs' time base and temperature, 3 seeds); every
# case spec of dev, dev2, dev3 and dev5 (one seed). Prints the drops' quantiles, the
# largest ones and how many runs the test made significant.
#   bash benches/gap_candidate_test.sh FARMA BANKDIR OUTDIR
set -eu
farma=${1:?farma binary}; bank=${2:?bank dir (generate.py)}; out=${3:?output dir}
root=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$out"
sed -n '/^sample_rate_hz = 10.0/,/^TOML/p' "$root/benches/gap_false_alarm.sh" | grep -v '^TOML' > "$out/mems.toml"
jobs=()
for p in dev dev2; do for c in $(ls "$bank/$p" | grep correct); do for s in 1 2 3; do
  jobs+=("$p-$c-$s|$bank/$p/$c/spec.toml|rate|--like $bank/$p/$c/real.parquet|$((1000 + s))|$((5000 + s))")
done; done; done
for p in dev dev2 dev3 dev5; do for c in $(ls "$bank/$p" | grep -v json); do
  jobs+=("case-$p-$c|$bank/$p/$c/spec.toml|rate|--like $bank/$p/$c/real.parquet|777|4242")
done; done
for s in $(seq 1 10); do
  jobs+=("adis-$s|$root/fixtures/specs/adis16405_datasheet.toml|gyro_x_dps|--duration 3600|$((1000 + s))|$((5000 + s))")
  jobs+=("mems-$s|$out/mems.toml|rate|--duration 3600|$((1000 + s))|$((5000 + s))")
done
printf '%s\n' "${jobs[@]}" | xargs -P2 -I{} bash -c '
IFS="|" read -r name spec ch like sim_seed gap_seed <<< "{}"
log=$(mktemp --suffix=.parquet)
"'"$farma"'" simulate "$spec" $like --seed $sim_seed -o $log -q >/dev/null 2>&1 || { echo "$name: simulate failed" >&2; rm -f $log; exit 0; }
"'"$farma"'" gap --real $log --sim "$spec" --channel $ch --seed $gap_seed --json -q --no-cache > "'"$out"'/$name.json" 2>/dev/null || echo "$name: gap failed" >&2
rm -f $log
'
python3 - "$out" <<'PY'
import glob, json, os, sys
rows = []
for f in sorted(glob.glob(os.path.join(sys.argv[1], "*.json"))):
    d = json.load(open(f))
    effs = [e for e in d["effects"] if e.get("gap_after") is not None]
    if not effs:
        continue
    b = min(effs, key=lambda e: e["gap_after"])
    rows.append((d["gap_before"] ** 2 - b["gap_after"] ** 2, os.path.basename(f)[:-5], b["kind"], d["significant"]))
rows.sort()
v = [r[0] for r in rows]
q = lambda p: v[min(len(v) - 1, int(p * len(v)))]
print(f"{len(v)} runs: drop median {q(0.5):.3f}, 0.95 quantile {q(0.95):.3f}, 0.99 quantile {q(0.99):.3f}; "
      f"significant {sum(r[3] for r in rows)}")
for r in rows[-5:]:
    print(f"  {r[1]}: {r[0]:.3f} ({r[2]})")
PY
