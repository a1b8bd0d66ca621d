#!/usr/bin/env python3
"""Run garment folds under small perturbations of their inputs and tabulate the outcomes.

A fold's final shape is chaotic: a millimetre of grasp point or a few percent of speed can
decide whether a half lands flat or stands as an arch. This script runs each fold at the
settings of tests/experiment/garment_tasks_test.cpp (dt 0.01 s, time scale 0.3, the page turn
in 2 s, 0.3 s settle) and under perturbations of them (grasp point +-5 mm, speed +-5%, the
mesh at twice the vertices), in parallel `gd run` processes, and prints one row per run
(docs/validation.md records the table).

    python3 scripts/fold_matrix.py --gd build/bin/gd --garments cake_skirt,towel --vertices 400
"""
import argparse
import concurrent.futures as cf
import json
import os
import subprocess
import sys
import time

# name -> (grasp_inset in metres, speed factor on the time scale, factor on --vertices)
PERTURBATIONS = {
    "nominal": (0.0, 1.0, 1),
    "inset-5mm": (-0.005, 1.0, 1),
    "inset+5mm": (0.005, 1.0, 1),
    "speed-5%": (0.0, 0.95, 1),
    "speed+5%": (0.0, 1.05, 1),
    "vertices-x2": (0.0, 1.0, 2),
}


def run_one(gd, garment, vertices, pert, out_root, threads):
    inset, speed, vertex_factor = PERTURBATIONS[pert]
    vertices *= vertex_factor
    time_scale = 0.3 * speed
    out = os.path.join(out_root, f"{garment}_{vertices}_{pert}")
    cmd = [gd, "run", "--garment", garment, "--task", "fold", "--vertices", str(vertices), "--dt", "0.01",
           "--time-scale", repr(time_scale), "--task-param", f"fold_duration={2.0 / time_scale!r}",
           "--task-param", f"grasp_inset={inset!r}", "--settle", "0.3", "--threads", str(threads),
           "--no-plots", "--out", out]
    t0 = time.time()
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        return {"garment": garment, "vertices": vertices, "perturbation": pert, "error": p.stderr[-500:]}
    s = json.load(open(os.path.join(out, "summary.json")))
    return {"garment": garment, "vertices": vertices, "perturbation": pert, "wall_s": time.time() - t0,
            "intersecting_pairs_max": s["intersecting_pairs_max"], "failed": s["failed"],
            "length": s["garment_length"], **{k: s["final"][k] for k in s["final"]}}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--gd", default="build/bin/gd")
    ap.add_argument("--garments", required=True, help="comma-separated garment types")
    ap.add_argument("--vertices", type=int, default=400)
    ap.add_argument("--perturbations", default=",".join(PERTURBATIONS), help="comma-separated names")
    ap.add_argument("--jobs", type=int, default=2, help="gd run processes at once (one thread each)")
    ap.add_argument("--out", default="fold_matrix_out")
    ap.add_argument("--json", help="write the rows here")
    a = ap.parse_args()
    perts = a.perturbations.split(",")
    unknown = [p for p in perts if p not in PERTURBATIONS]
    if unknown:
        ap.error(f"unknown perturbation(s) {', '.join(unknown)}; known: {', '.join(PERTURBATIONS)}")
    if not os.access(a.gd, os.X_OK):
        ap.error(f"--gd {a.gd} is not an executable; build it (scripts/build) or pass its path")
    jobs = [(g, p) for g in a.garments.split(",") for p in perts]
    rows = []
    with cf.ThreadPoolExecutor(a.jobs) as ex:
        futs = [ex.submit(run_one, a.gd, g, a.vertices, p, a.out, 1) for g, p in jobs]
        for i, f in enumerate(cf.as_completed(futs), 1):
            r = f.result()
            rows.append(r)
            print(f"[{i}/{len(jobs)}] {r['garment']} {r['perturbation']}: "
                  + (r["error"] if "error" in r else
                     f"max_z {100 * r['max_z']:.1f} cm, p95_z {100 * r['p95_z']:.1f} cm, mean_z "
                     f"{100 * r['mean_z']:.1f} cm, folded length {r['extent_x'] / r['length']:.2f}, "
                     f"pairs {r['intersecting_pairs_max']}, {r['wall_s']:.0f} s"), flush=True)
    rows.sort(key=lambda r: (r["garment"], list(PERTURBATIONS).index(r["perturbation"])))
    print("\n| garment | perturbation | max_z cm | p95_z cm | mean_z cm | folded length / length | pairs | wall s |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        if "error" in r:
            print(f"| {r['garment']} | {r['perturbation']} | error | | | | | |")
            continue
        print(f"| {r['garment']} | {r['perturbation']} | {100 * r['max_z']:.1f} | {100 * r['p95_z']:.1f} | "
              f"{100 * r['mean_z']:.1f} | {r['extent_x'] / r['length']:.2f} | {r['intersecting_pairs_max']} | "
              f"{r['wall_s']:.0f} |")
    if a.json:
        json.dump(rows, open(a.json, "w"), indent=1)
    return 1 if any("error" in r or r.get("failed") for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
