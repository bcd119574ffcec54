#!/usr/bin/env bash
# The near-unit-root check of the FARMA fit (issue 25): on the four ADIS16405 runs of
# ../shared/realdata (3 gyro axes x the 8 default orders each) and on a simulated
# datasheet gyro (white noise + bias instability, 1e6 samples at 100 Hz,
# fixtures/specs/adis16405_datasheet.toml), runs `farma select --bootstrap 0 --json`
# and `farma fit --json` at every order with one farma binary, and prints
#   - per fit whether it returned its linear ARMA start, and why (the report's
#     `returned_start_reason` where the binary writes one, else the fit's note),
#   - fits whose RSS overflowed on the way (a note with residuals that are not
#     finite, or an alternation that ended 1e3 times or more above its start),
#   - F-tests with a NaN or negative df, and pairs left untested (with the reason),
#   - the wall time of each `farma select` call.
#
#     bash benches/unit_root.sh BIN OUT        (OUT: a scratch folder, kept)
#     bash benches/unit_root.sh --summary OUT  (the tables again from OUT, no runs)
#
# Needs python3 (to read the JSON). About 2-4 minutes per binary on 2 cores.
set -euo pipefail

here="$(cd "$(dirname "$0")/.." && pwd)"
realdata="${FARMA_REALDATA:-$here/../shared/realdata/imudata-adis16405}"
out="$2"
summary_only=0
if [[ "$1" == "--summary" ]]; then
  summary_only=1
else
  bin="$(realpath "$1")"
fi
mkdir -p "$out"
out="$(realpath "$out")"
export FARMA_CACHE_DIR="${FARMA_CACHE_DIR:-$out/.cache}"
cd "$here"
chans=gyro_x_dps,gyro_y_dps,gyro_z_dps
orders="1,1,1 1,1,2 2,1,1 2,1,2 3,1,1 3,1,2 3,2,1 3,2,2"

ds="$out/datasheet.arrow"
if [[ $summary_only == 0 && ! -e "$ds" ]]; then
  "$bin" simulate fixtures/specs/adis16405_datasheet.toml --duration 10000 -q -o "$ds" >/dev/null
fi
logs=()
for k in 1 2 3 4; do
  f="$realdata/adis_16405_imu$k.parquet"
  [[ -e "$f" ]] && logs+=("imu$k=$f")
done
logs+=("datasheet=$ds")

for entry in "${logs[@]}"; do
  [[ $summary_only == 1 ]] && break
  name="${entry%%=*}"
  log="${entry#*=}"
  # the store once, so that the timing below is the selection's
  "$bin" info "$log" >/dev/null
  t0=$(date +%s.%N)
  "$bin" select "$log" --channel "$chans" --bootstrap 0 --json -q >"$out/select_$name.json" 2>"$out/select_$name.err" || true
  t1=$(date +%s.%N)
  echo "$name $(echo "$t1 - $t0" | bc)" >"$out/select_$name.time"
  for o in $orders; do
    "$bin" fit "$log" --channel "$chans" --order "$o" --json -q -o "$out/fit_${name}_${o//,/}" \
      >"$out/fit_${name}_${o//,/}.json" 2>"$out/fit_${name}_${o//,/}.err" || true
  done
done

python3 - "$out" <<'EOF'
import json, glob, os, re, sys
out = sys.argv[1]

def load(path):
    with open(path) as fh:
        txt = fh.read().strip()
    if not txt:
        return []
    try:
        d = json.loads(txt)
    except json.JSONDecodeError:
        # one object per line
        return [json.loads(l) for l in txt.splitlines() if l.strip()]
    return d if isinstance(d, list) else [d]

def channels(objs):
    for o in objs:
        if isinstance(o, dict) and "channels" in o and isinstance(o["channels"], list):
            yield from o["channels"]
        else:
            yield o

names = [os.path.basename(p)[len("select_"):-len(".json")]
         for p in sorted(glob.glob(os.path.join(out, "select_*.json")))]
tot = dict(fits=0, start=0, overflow=0, bad_df=0, ftests=0, untested=0)
reasons = {}
print(f"{'log':<10} {'channel':<11} {'fits':>4} {'start':>5} {'ovfl':>4} {'F':>3} {'badF':>4} {'untst':>5}  select s")
for name in names:
    sel = {c["channel"]: c for c in channels(load(os.path.join(out, f"select_{name}.json")))}
    with open(os.path.join(out, f"select_{name}.time")) as fh:
        secs = float(fh.read().split()[1])
    fits = {}
    for p in sorted(glob.glob(os.path.join(out, f"fit_{name}_*.json"))):
        for c in channels(load(p)):
            fits[(c["channel"], tuple(c["order"]) if isinstance(c["order"], list) else c["order"])] = c
    for ch in ["gyro_x_dps", "gyro_y_dps", "gyro_z_dps"]:
        s = sel.get(ch)
        if s is None:
            print(f"{name:<10} {ch:<11} select failed (see select_{name}.err)")
            continue
        n_start = n_ovf = 0
        for r in s["table"]:
            o = tuple(r["order"])
            p, q, d = o
            tot["fits"] += 1
            f = fits.get((ch, o)) or fits.get((ch, list(o).__str__()))
            notes = " ".join(f.get("notes", [])) if f else ""
            if "returned_start_reason" in r:
                is_start = r["returned_start_reason"] is not None
                why = r["returned_start_reason"]
            else:
                # a binary without the field: the linear start has trace p exactly,
                # df = p + q
                is_start = r["df"] == p + q
                why = None
            m = re.search(r"ended above its linear ARMA\(\d+,\d+\) start \(RSS (\S+) > (\S+)\)", notes)
            overflow = "not finite" in notes
            # the RSS on the way 1e3 times or more above the iterate it ended above
            for hi, lo in re.findall(r"ended above its .*?\(RSS (\S+) > (\S+?)\)", notes):
                try:
                    overflow |= not (float(hi) < 1e3 * float(lo))
                except ValueError:
                    overflow = True
            if is_start:
                n_start += 1
                detail = ""
                if m:
                    detail = " (RSS %s > %s%s)" % (m.group(1), m.group(2), ", overflow" if overflow else "")
                if why is None:
                    why = "ended above the start (this binary names no reason)" if m else "?"
                reasons.setdefault(why, []).append(f"{name}/{ch}/FARMA{p}{q}{d}{detail}")
                tot["start"] += 1
            if overflow:
                n_ovf += 1
                tot["overflow"] += 1
        bad = [t for t in s["ftests"] if t["df1"] is None or t["df2"] is None
               or not (t["df1"] > 0 and t["df2"] > 0) or t["f"] is None]
        unt = s.get("untested", [])
        tot["bad_df"] += len(bad); tot["ftests"] += len(s["ftests"]); tot["untested"] += len(unt)
        print(f"{name:<10} {ch:<11} {len(s['table']):>4} {n_start:>5} {n_ovf:>4} {len(s['ftests']):>3} {len(bad):>4} {len(unt):>5}  {secs:.2f}")
print(f"{'total':<22} {tot['fits']:>4} {tot['start']:>5} {tot['overflow']:>4} {tot['ftests']:>3} {tot['bad_df']:>4} {tot['untested']:>5}")
print("linear starts returned, by reason:")
for why, who in sorted(reasons.items()):
    print(f"  {len(who):>3}  {why}")
    for w in who:
        print(f"         {w}")
print("overflow: a fit whose RSS rose 1e3 times or more above an iterate on the way (or was not finite)")
EOF
