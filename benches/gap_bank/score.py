#!/usr/bin/env python3
"""Run `farma gap` on every case of the independent bank and score it (issue 27).

Usage:
    python3 score.py FARMA BANKDIR [--part dev|dev2|dev3|dev4|heldout|heldout2|all] [--jobs N] [--timeout S]
                     [--out RESULTS] [--only SUBSTRING] [--rescore] [--oracle] [--cases]
                     [-- EXTRA farma gap ARGS]

BANKDIR is what generate.py wrote (BANKDIR/<part>/<case>/{real.parquet,spec.toml,truth.json}).
For each case it runs, under /usr/bin/time -f "%e %M" (seconds, peak RSS in KiB):
    FARMA gap --real real.parquet --sim spec.toml --channel rate --json [EXTRA]
saving RESULTS/<part>/<case>.json (stdout), .stderr and .time; RESULTS defaults to
BANKDIR/results. --rescore scores the saved JSONs again without running farma.

Rules (threshold = the JSON's gap_threshold when present, else 2 x noise_floor):
- single: right if added[0] is the withheld kind (or a name accepted for it, truth.json
  "accept") AND gap_after <= 2 x noise_floor;
- pair: right if both withheld kinds are among added AND gap_after <= threshold (the
  JSON's explained_threshold when present: the gap threshold, or above it 1.1 x the
  largest gap after of simulations of the spec after diagnosed again, at most 2 x the
  noise floor);
- non_candidate: right if the diagnosis does not declare it explained: the JSON's
  `explained` when present (right if false); otherwise right if nothing was added or
  gap_after > threshold;
- correct: right if nothing is significant (`significant` when present, else
  gap_before <= threshold) AND nothing was added.
A run that fails, times out or prints no JSON is wrong.

Prints a table per part and category, and each case of the development parts (a
held-out part, heldout, heldout2, heldout3, heldout4, heldout5 or path7, prints its aggregates only unless --cases), and
writes RESULTS/scores.csv (one row per case; scores_<part>.csv with --part).
"""

import argparse
import csv
import json
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

CATS = ["single", "pair", "non_candidate", "correct"]


def names(truth, kind):
    return set(truth.get("accept", {}).get(kind, [kind]))


def score_case(truth, d):
    """(right, why) for one case's truth and JSON (None when the run failed)."""
    if d is None:
        return False, "no JSON (failed or timed out)"
    added = list(d.get("added") or [])
    floor = float(d.get("noise_floor") or 0.0)
    after = d.get("gap_after")
    after = float(after) if after is not None else float("inf")
    before = float(d.get("gap_before") or 0.0)
    thr = d.get("gap_threshold")
    thr = float(thr) if thr is not None else 2.0 * floor
    cat = truth["category"]
    if cat == "single":
        k = truth["kinds"][0]
        first = added[0] if added else None
        ok_kind = first in names(truth, k)
        ok_gap = after <= 2.0 * floor
        why = f"first={first} want={k}; after {after:.3g} vs 2*floor {2 * floor:.3g}"
        return ok_kind and ok_gap, why
    if cat == "pair":
        ks = truth["kinds"]
        got = [any(a in names(truth, k) for a in added) for k in ks]
        # the gap closed: within the threshold `explained` is judged against (the gap
        # threshold, or above it what re-estimating the added effects on simulations of
        # the spec after leaves), when the JSON has it
        thr = float(d.get("explained_threshold") or thr)
        ok_gap = after <= thr
        why = f"added={added} want={ks}; after {after:.3g} vs thr {thr:.3g}"
        return all(got) and ok_gap, why
    if cat == "non_candidate":
        if "explained" in d:
            return (not bool(d["explained"])), f"explained={d['explained']} added={added}"
        ok = (not added) or after > thr
        return ok, f"added={added}; after {after:.3g} vs thr {thr:.3g}"
    if cat == "correct":
        sig = bool(d["significant"]) if "significant" in d else before > thr
        return (not sig) and not added, f"significant={sig} before {before:.3g} thr {thr:.3g} added={added}"
    raise ValueError(cat)


def run_case(farma, case_dir, out_base, timeout, extra, spec="spec.toml"):
    json_p, err_p, time_p = out_base + ".json", out_base + ".stderr", out_base + ".time"
    cmd = ["nice", "/usr/bin/time", "-f", "%e %M", "-o", time_p, farma, "gap",
           "--real", os.path.join(case_dir, "real.parquet"),
           "--sim", os.path.join(case_dir, spec), "--channel", "rate", "--json"] + extra
    t0 = time.time()
    status = "ok"
    with open(json_p, "w") as fo, open(err_p, "w") as fe:
        try:
            p = subprocess.run(cmd, stdout=fo, stderr=fe, timeout=timeout)
            if p.returncode != 0:
                status = f"exit {p.returncode}"
        except subprocess.TimeoutExpired:
            status = "timeout"
    wall = time.time() - t0
    return status, wall


def read_time(p):
    try:
        # /usr/bin/time writes "Command exited with non-zero status N" first on failure
        line = [x for x in open(p).read().split("\n") if x.strip()][-1]
        e, m = line.split()
        return float(e), int(m)
    except Exception:
        return None, None


def load_json(p):
    try:
        txt = open(p).read().strip()
        if not txt:
            return None
        return json.loads(txt.splitlines()[0])
    except Exception:
        return None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("farma")
    ap.add_argument("bank")
    ap.add_argument("--part", choices=["dev", "dev2", "dev3", "dev4", "dev5", "path6", "dev6", "path7", "dev7", "dev8", "dev9", "heldout", "heldout2", "heldout3", "heldout4", "heldout5", "dev10", "all"], default="all")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per case")
    ap.add_argument("--out", default=None)
    ap.add_argument("--only", default=None)
    ap.add_argument("--rescore", action="store_true")
    ap.add_argument("--cases", action="store_true",
                    help="print the held-out parts' cases too (by default a held-out part, "
                         "heldout, heldout2, heldout3, heldout4, heldout5 or path7, prints its aggregates only: tuning must not "
                         "read them)")
    ap.add_argument("--oracle", action="store_true",
                    help="also check each pair member's detectability: run the pair's "
                         "spec_only_<kind>.toml (the truth minus that member alone) and "
                         "report whether its gap is significant (runs only those not saved "
                         "yet: --rescore --oracle runs just them); and each case's "
                         "spec_truth.toml (the truth in contract form), reporting whether "
                         "a diagnosis that found the withheld effects exactly would pass")
    # the extra arguments of farma gap follow "--" (split off here: argparse gives a
    # trailing nargs="*" positional nothing once the two before it are matched)
    argv = sys.argv[1:]
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    argv = argv[:argv.index("--")] if "--" in argv else argv
    a = ap.parse_args(argv)

    def shown(part):
        # a held-out part's cases are not printed unless asked for
        return a.cases or not (part.startswith("heldout") or part == "path7")
    a.extra = extra
    out = a.out or os.path.join(a.bank, "results")
    parts = ["dev", "dev2", "dev3", "dev4", "dev5", "heldout", "heldout2"] if a.part == "all" else [a.part]
    todo = []
    for part in parts:
        pdir = os.path.join(a.bank, part)
        if not os.path.isdir(pdir):
            print(f"no part {pdir}", file=sys.stderr)
            continue
        os.makedirs(os.path.join(out, part), exist_ok=True)
        for c in sorted(os.listdir(pdir)):
            cd = os.path.join(pdir, c)
            if not os.path.isfile(os.path.join(cd, "truth.json")):
                continue
            if a.only and a.only not in c:
                continue
            todo.append((part, c, cd, os.path.join(out, part, c)))

    statuses = {}
    if not a.rescore:
        def job(item):
            part, c, cd, ob = item
            st, wall = run_case(os.path.abspath(a.farma), cd, ob, a.timeout, a.extra)
            e, m = read_time(ob + ".time")
            print(f"{part}/{c}: {st}, {e if e is not None else wall:.1f} s, "
                  f"{(m or 0) / 1024:.0f} MiB", file=sys.stderr, flush=True)
            return (part, c), st
        with ThreadPoolExecutor(max_workers=max(1, a.jobs)) as ex:
            for key, st in ex.map(job, todo):
                statuses[key] = st

    if a.oracle:
        orows = []
        for part, c, cd, ob in todo:
            truth = json.load(open(os.path.join(cd, "truth.json")))
            for k, fn in (truth.get("detectability_specs") or {}).items():
                obk = f"{ob}.only_{k}"
                if load_json(obk + ".json") is None:   # run unless already saved
                    run_case(os.path.abspath(a.farma), cd, obk, a.timeout, a.extra, spec=fn)
                d = load_json(obk + ".json")
                if d is None:
                    orows.append((part, c, k, "failed", "", ""))
                    continue
                thr = d.get("gap_threshold", 2 * d.get("noise_floor", 0))
                sig = d.get("significant", d.get("gap_before", 0) > thr)
                orows.append((part, c, k, "significant" if sig else "NOT significant",
                              f"{d.get('gap_before', float('nan')):.3g} vs {thr:.3g}",
                              "+".join(d.get("added") or [])))
        # the truth in contract form: would the exact effects pass the case's gap rule?
        reach = {}
        for part, c, cd, ob in todo:
            truth = json.load(open(os.path.join(cd, "truth.json")))
            fn = truth.get("truth_spec")
            if not fn or truth["category"] not in ("single", "pair"):
                continue
            obk = f"{ob}.truth"
            if load_json(obk + ".json") is None:
                run_case(os.path.abspath(a.farma), cd, obk, a.timeout, a.extra, spec=fn)
            d = load_json(obk + ".json")
            if d is None:
                continue
            floor = float(d.get("noise_floor") or 0.0)
            thr = float(d.get("gap_threshold", 2 * floor))
            bar = 2.0 * floor if truth["category"] == "single" else thr
            reach[(part, c)] = float(d.get("gap_before", float("inf"))) <= bar
        rname = "reachable.csv" if a.part == "all" else f"reachable_{a.part}.csv"
        with open(os.path.join(out, rname), "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["part", "case", "truth_passes"])
            w.writerows([(p_, c_, int(v)) for (p_, c_), v in sorted(reach.items())])
        print("\n== detectability of each pair member alone (truth minus that member)")
        for r in orows:
            if shown(r[0]):
                print(f"{r[0]}/{r[1]:<46} {r[2]:<18} {r[3]:<16} gap {r[4]}  added={r[5]}")
        dname = "detectability.csv" if a.part == "all" else f"detectability_{a.part}.csv"
        with open(os.path.join(out, dname), "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["part", "case", "member", "verdict", "gap_before_vs_threshold", "added"])
            w.writerows(orows)

    rows = []
    for part, c, cd, ob in todo:
        truth = json.load(open(os.path.join(cd, "truth.json")))
        d = load_json(ob + ".json")
        right, why = score_case(truth, d)
        e, m = read_time(ob + ".time")
        st = statuses.get((part, c))
        if st is None:
            st = "ok" if d is not None else "failed"
        rows.append({
            "part": part, "case": c, "category": truth["category"],
            "kinds": "+".join(truth["kinds"]),
            "contract_kinds": truth.get("contract_kinds", True),
            "rate_hz": truth["rate_hz"], "duration_s": truth["duration_s"], "n_samples": truth["n_samples"],
            "temperature": (truth.get("temperature") or {}).get("profile", ""),
            "size_factor": round(truth.get("size_factor", 0), 3),
            "status": st, "right": int(right),
            "gap_before": d.get("gap_before") if d else "", "gap_after": d.get("gap_after") if d else "",
            "noise_floor": d.get("noise_floor") if d else "", "gap_threshold": d.get("gap_threshold", "") if d else "",
            "significant": d.get("significant", "") if d else "", "explained": d.get("explained", "") if d else "",
            "added": "+".join(d.get("added") or []) if d else "",
            "elapsed_s": e if e is not None else "", "peak_rss_mib": round(m / 1024, 1) if m else "",
            "why": why,
        })

    # pairs whose every member (with a contract form) gives a significant gap alone
    detect = {}
    for dname in sorted(os.listdir(out)) if os.path.isdir(out) else []:
        if not (dname.startswith("detectability") and dname.endswith(".csv")):
            continue
        for r in csv.DictReader(open(os.path.join(out, dname))):
            key = (r["part"], r["case"])
            detect[key] = detect.get(key, True) and r["verdict"] == "significant"
    for r in rows:
        r["members_detectable"] = detect.get((r["part"], r["case"]), "")
    # cases whose truth in contract form passes their own rule (`--oracle`)
    reachable = {}
    for rname in sorted(os.listdir(out)) if os.path.isdir(out) else []:
        if rname.startswith("reachable") and rname.endswith(".csv"):
            for r in csv.DictReader(open(os.path.join(out, rname))):
                reachable[(r["part"], r["case"])] = r["truth_passes"] == "1"

    for part in parts:
        pr = [r for r in rows if r["part"] == part]
        if not pr:
            continue
        print(f"\n== {part}: {sum(r['right'] for r in pr)}/{len(pr)} right")
        print(f"{'category':<28}{'right':>6}{'cases':>6}{'share':>8}")
        for cat in CATS:
            cr = [r for r in pr if r["category"] == cat]
            if cr:
                k = sum(r["right"] for r in cr)
                print(f"{cat:<28}{k:>6}{len(cr):>6}{k / len(cr):>8.0%}")
            if cat == "pair" and cr and detect:
                dc = [r for r in cr if detect.get((part, r["case"])) is True]
                k = sum(r["right"] for r in dc)
                if dc:
                    print(f"{'  members detectable alone':<28}{k:>6}{len(dc):>6}{k / len(dc):>8.0%}")
            if cat in ("single", "pair") and cr and reachable:
                # reachable: the gap before is significant and the truth in contract
                # form passes the case's rule (with members detectable alone, for pairs)
                def ok(r):
                    return (reachable.get((part, r["case"])) is True
                            and r["significant"] in (True, "True")
                            and (cat == "single" or detect.get((part, r["case"])) is True))
                rc = [r for r in cr if ok(r)]
                k = sum(r["right"] for r in rc)
                n_known = sum((part, r["case"]) in reachable for r in cr)
                print(f"{'  reachable':<28}{k:>6}{len(rc):>6}"
                      f"{(k / len(rc) if rc else 0):>8.0%}  (of {n_known} with a contract form)")
            if cat == "non_candidate" and cr:
                # an effect whose gap is not significant cannot be told from a right spec
                sc = [r for r in cr if r["significant"] in (True, "True")]
                k = sum(r["right"] for r in sc)
                if sc:
                    print(f"{'  gap before significant':<28}{k:>6}{len(sc):>6}{k / len(sc):>8.0%}")
            if cat == "single" and cr:
                cc = [r for r in cr if r["contract_kinds"] in (True, "True")]
                k = sum(r["right"] for r in cc)
                if cc:
                    print(f"{'  of contract kinds':<28}{k:>6}{len(cc):>6}{k / len(cc):>8.0%}")
                # the singles a diagnosis can see at all: the gap before significant
                sc = [r for r in cr if r["significant"] in (True, "True")]
                k = sum(r["right"] for r in sc)
                if sc:
                    print(f"{'  gap before significant':<28}{k:>6}{len(sc):>6}{k / len(sc):>8.0%}")
        times = [r["elapsed_s"] for r in pr if r["elapsed_s"] != ""]
        rss = [r["peak_rss_mib"] for r in pr if r["peak_rss_mib"] != ""]
        if times:
            times_s = sorted(times)
            print(f"time per case: median {times_s[len(times_s) // 2]:.1f} s, max {max(times):.1f} s, "
                  f"total {sum(times):.0f} s; peak RSS median {sorted(rss)[len(rss) // 2]:.0f} MiB, max {max(rss):.0f} MiB")
        if not shown(part):
            print(f"(a held-out part: aggregates only; --cases prints its cases, which a "
                  f"development step must not read; the CSV has them)")
            continue
        print(f"{'case':<48}{'ok':>3}  why")
        for r in pr:
            print(f"{r['case']:<48}{'Y' if r['right'] else '-':>3}  [{r['status']}] {r['why']}")
    os.makedirs(out, exist_ok=True)
    csv_p = os.path.join(out, "scores.csv" if a.part == "all" else f"scores_{a.part}.csv")
    if rows:
        with open(csv_p, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    print(f"\nwrote {csv_p}")


if __name__ == "__main__":
    main()
