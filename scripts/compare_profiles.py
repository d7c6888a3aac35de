#!/usr/bin/env python3
"""Compares bench results across planners and profiles, paired by start (scene and seed).

Usage: scripts/compare_profiles.py RESULTS.jsonl... > table.md

Reads the rows of one or more `tensorscout bench` folders (their `results.jsonl`) and prints, as
Markdown:
- Table 1 per planner and profile: explored volume eps, r_eps (eps over THP's of the same profile
  and start), path length L, completeness, simulated time, terminations, collisions, and runs that
  ended `complete` with observable frontiers left; mean +- the half-width of the Student-t 95 %
  interval over runs;
- paired differences against THP of the same profile, and between the two profiles of one planner:
  total path, the path to equal coverage (each run's path to 90 % of the smaller of the two final
  explored volumes, as in the THP paper's Fig. 6), completeness.
Only the standard library is used.
"""
import json
import math
import statistics
import sys
from collections import defaultdict


def t95(n):
    """Two-sided 95 % Student-t quantile for n - 1 degrees of freedom (Cornish-Fisher series)."""
    nu = n - 1
    z = 1.959963984540054
    return z + (z**3 + z) / (4 * nu) + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * nu**2) + (
        3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z
    ) / (384 * nu**3)


def ci(xs):
    xs = list(xs)
    m = statistics.fmean(xs)
    h = t95(len(xs)) * statistics.stdev(xs) / math.sqrt(len(xs)) if len(xs) > 1 else float("nan")
    return m, h


def fmt(xs, digits):
    m, h = ci(xs)
    return f"{m:.{digits}f} ± {h:.{digits}f}"


def path_to(result, volume):
    """Path length at which the run's explored volume first reached `volume` (interpolated)."""
    prev = None
    for s in result["curve"]:
        if s["explored_volume_m3"] >= volume:
            if prev is None or s["explored_volume_m3"] == prev["explored_volume_m3"]:
                return s["path_length_m"]
            f = (volume - prev["explored_volume_m3"]) / (
                s["explored_volume_m3"] - prev["explored_volume_m3"]
            )
            return prev["path_length_m"] + f * (s["path_length_m"] - prev["path_length_m"])
        prev = s
    return result["path_length_m"]


def main(paths):
    runs = {}
    for path in paths:
        for line in open(path):
            row = json.loads(line)
            if row.get("status") != "ok":
                continue
            r = row["result"]
            runs[(r["planner"], r.get("profile", "tensorscout"), row["scene_path"], row["seed"])] = r
    labels = sorted({(p, prof) for (p, prof, _, _) in runs}, key=lambda k: (k[1], k[0] != "thp", k[0]))
    starts = sorted({(s, seed) for (_, _, s, seed) in runs})
    name = lambda k: f"{k[0]}/{k[1]}"

    print("| planner/profile | runs | ε (m³) | r_ε (÷ THP, same profile and start) | L (m) | completeness | sim time (s) | complete / stuck / budget | collisions (runs) | `complete`, frontiers left |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for k in labels:
        rs = [runs[(k[0], k[1], s, seed)] for (s, seed) in starts if (k[0], k[1], s, seed) in runs]
        ratio = [
            runs[(k[0], k[1], s, seed)]["explored_volume_m3"] / runs[("thp", k[1], s, seed)]["explored_volume_m3"]
            for (s, seed) in starts
            if (k[0], k[1], s, seed) in runs and ("thp", k[1], s, seed) in runs
        ]
        term = defaultdict(int)
        for r in rs:
            term[r["termination"]] += 1
        left = sum(1 for r in rs if r["termination"] == "complete" and (r.get("frontiers_left") or 0) > 0)
        print(
            f"| {name(k)} | {len(rs)} | {fmt([r['explored_volume_m3'] for r in rs], 1)} | {fmt(ratio, 3)} | "
            f"{fmt([r['path_length_m'] for r in rs], 1)} | {fmt([r['completeness'] for r in rs], 4)} | "
            f"{fmt([r['sim_time_s'] for r in rs], 0)} | {term['complete']} / {term['stuck']} / {term['budget']} | "
            f"{sum(1 for r in rs if r['collisions'] > 0)} | {left} |"
        )

    pairs = [((p, prof), ("thp", prof)) for (p, prof) in labels if p != "thp"]
    profiles = sorted({prof for (_, prof) in labels})
    for p in sorted({p for (p, _) in labels}):
        if all((p, prof) in labels for prof in profiles) and len(profiles) == 2:
            pairs.append(((p, "tensorscout"), (p, "published")))
    if ("thp", "tensorscout") in labels and ("greedy", "published") in labels:
        pairs.append((("greedy", "published"), ("thp", "tensorscout")))
    print()
    print("| A against B (same start) | pairs | ΔL (m) | A shorter / longer | Δ path to equal coverage (m) | A shorter / longer | Δ completeness |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for a, b in pairs:
        dl, dp, dc = [], [], []
        for (s, seed) in starts:
            ra, rb = runs.get((a[0], a[1], s, seed)), runs.get((b[0], b[1], s, seed))
            if ra is None or rb is None:
                continue
            dl.append(ra["path_length_m"] - rb["path_length_m"])
            v = 0.9 * min(ra["explored_volume_m3"], rb["explored_volume_m3"])
            dp.append(path_to(ra, v) - path_to(rb, v))
            dc.append(ra["completeness"] - rb["completeness"])
        if not dl:
            continue
        sl = f"{sum(d < 0 for d in dl)} / {sum(d > 0 for d in dl)}"
        sp = f"{sum(d < 0 for d in dp)} / {sum(d > 0 for d in dp)}"
        print(f"| {name(a)} − {name(b)} | {len(dl)} | {fmt(dl, 2)} | {sl} | {fmt(dp, 2)} | {sp} | {fmt(dc, 4)} |")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
