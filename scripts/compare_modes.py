#!/usr/bin/env python3
"""Pseudo mode against robot mode on the same garment and tasks (docs/robot.md, "Pseudo and robot
mode side by side"): runs `gd run` for each task in both modes (the same generated trajectory:
robot mode aims the fingertips `grasp_depth` below the grasp points and its arms follow by inverse
kinematics), then compares the final shapes with `gd metrics` (Chamfer and Hausdorff distances
between the two final meshes) and prints a Markdown table; `--png` draws the final shapes of both
modes from above and from the side.

    build/venv/bin/python scripts/compare_modes.py --urdf ../shared/data/rgbench/piper_with_gripper.urdf \\
        --garment tshirt --vertices 5000 --tasks grasp,fold --jobs 2 --out out/modes --png out/modes.png

Each run is `gd run --threads 1` (two at a time with --jobs 2) plus the task parameters given
with --task-param (robot mode needs a lift the Piper can reach: lift_height=0.45 by default here).
`scripts/plot_modes_grid.py OUT:TASK ...` draws the final shapes of several such runs in one figure.
"""

import argparse
import json
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def run(gd, out: Path, garment, vertices, task, mode, urdf, params, threads, garment_params=(), position=None,
        grip_force=None, refine_grasp=None):
    cmd = [gd, "run", "--garment", garment, "--task", task, "--mode", mode, "--threads", str(threads), "--quiet",
           "--no-plots", "--out", str(out)]
    if not garment.endswith(".obj"):
        cmd += ["--vertices", str(vertices)]
    if mode == "robot":
        cmd += ["--urdf", urdf]
        if grip_force is not None:
            cmd += ["--grip-force", str(grip_force)]
    for kv in params:
        cmd += ["--task-param", kv]
    for kv in garment_params:
        cmd += ["--garment-param", kv]
    if position:
        cmd += ["--garment-position", *[str(v) for v in position]]
    if refine_grasp:  # both modes on the same mesh
        cmd += ["--refine-grasp", str(refine_grasp)]
    t0 = time.time()
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    seconds = time.time() - t0
    summary = json.loads((out / "summary.json").read_text()) if (out / "summary.json").exists() else None
    print(f"{task}/{mode}: exit {proc.returncode} in {seconds:.0f} s", file=sys.stderr, flush=True)
    if proc.returncode != 0 and summary is None:
        print(proc.stderr[-2000:], file=sys.stderr)
    return {"task": task, "mode": mode, "rc": proc.returncode, "seconds": seconds, "summary": summary, "out": out}


def metrics(gd, a: Path, b: Path):
    # --surface: also as surfaces (a robot run refined under the pads weighs the hands' regions more by
    # its vertices; docs/metrics.md)
    proc = subprocess.run([gd, "metrics", "--sim", str(a), "--real", str(b), "--json", "--surface", "20000"],
                          stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, text=True)
    return json.loads(proc.stdout) if proc.returncode == 0 else None


def read_obj(path: Path):
    import numpy as np
    v, f = [], []
    for line in path.read_text().splitlines():
        if line.startswith("v "):
            v.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("f "):
            f.append([int(x.split("/")[0]) - 1 for x in line.split()[1:4]])
    return np.array(v), np.array(f, dtype=int)


def draw(rows, png: Path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    tasks = sorted({r["task"] for r in rows}, key=[r["task"] for r in rows].index)
    fig, axes = plt.subplots(len(tasks), 2, figsize=(10, 4 * len(tasks)), squeeze=False)
    colors = {"pseudo": "tab:blue", "robot": "tab:red"}
    for i, task in enumerate(tasks):
        for r in rows:
            if r["task"] != task or not (r["out"] / "final.obj").exists():
                continue
            v, f = read_obj(r["out"] / "final.obj")
            for j, (a, b, name) in enumerate(((0, 1, "top (x, y)"), (0, 2, "side (x, z)"))):
                ax = axes[i][j]
                ax.triplot(v[:, a], v[:, b], f, color=colors[r["mode"]], lw=0.15, alpha=0.6)
                ax.plot([], [], color=colors[r["mode"]], label=r["mode"])
                ax.set_title(f"{task}: final shape, {name}")
                ax.set_aspect("equal")
                ax.legend(loc="upper right")
    fig.tight_layout()
    fig.savefig(png, dpi=120)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--gd", default=str(REPO / "build" / "bin" / "gd"))
    p.add_argument("--urdf", required=True)
    p.add_argument("--garment", default="tshirt")
    p.add_argument("--vertices", type=int, default=5000)
    p.add_argument("--tasks", default="grasp,fold,fling")
    p.add_argument("--task-param", action="append", default=None,
                   help="NAME=VALUE for both modes (default: lift_height=0.45 fling_height=0.45)")
    p.add_argument("--garment-param", action="append", default=[], help="NAME=VALUE: a generated garment's size")
    p.add_argument("--garment-position", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="where the garment goes (gd run --garment-position), m")
    p.add_argument("--grip-force", type=float, help="robot mode: the fingers' squeeze, N (default: the URDF's)")
    p.add_argument("--refine-grasp", type=float,
                   help="m: both modes' mesh refined to this edge near the grasp points (gd run --refine-grasp)")
    p.add_argument("--jobs", type=int, default=2, help="runs at once (each on one thread)")
    p.add_argument("--out", default="out/modes")
    p.add_argument("--png", help="draw the final shapes here")
    p.add_argument("--json", help="write the table's numbers here")
    args = p.parse_args()
    if args.png:  # known before the runs, not after them
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            p.error("--png needs matplotlib: run this script with the project's venv (build/venv/bin/python, "
                    "made by scripts/build) or pip install matplotlib")
    params = args.task_param if args.task_param is not None else ["lift_height=0.45", "fling_height=0.45"]
    out = Path(args.out)
    jobs = [(task, mode) for task in args.tasks.split(",") for mode in ("pseudo", "robot")]
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        rows = list(pool.map(lambda tm: run(args.gd, out / f"{tm[0]}_{tm[1]}", args.garment, args.vertices, tm[0],
                                            tm[1], args.urdf, params, 1, args.garment_param, args.garment_position,
                                            args.grip_force, args.refine_grasp), jobs))
    print("| task | mode | ms/step | final max z (cm) | mean z (cm) | extent x, y (cm) | intersecting pairs (max) "
          "| untangling runs | held at the end (left, right squeeze N) | CD L1 robot->pseudo / pseudo->robot (cm) "
          "| HD (cm) | surface CD robot->pseudo / pseudo->robot (cm) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    table = []
    for task in args.tasks.split(","):
        pair = {r["mode"]: r for r in rows if r["task"] == task}
        m = None
        if all(pair.get(k) and (pair[k]["out"] / "final.obj").exists() for k in ("pseudo", "robot")):
            m = metrics(args.gd, pair["robot"]["out"] / "final.obj", pair["pseudo"]["out"] / "final.obj")
        for mode in ("pseudo", "robot"):
            r = pair.get(mode)
            s = r["summary"] if r else None
            if not s:
                print(f"| {task} | {mode} | failed | | | | | | | | | |")
                continue
            fin = s.get("final", {})
            cd = hd = surf = ""
            if m and mode == "robot":  # gd metrics --sim robot --real pseudo
                cd = f"{100 * m['cd_l1_s2r']:.2f} / {100 * m['cd_l1_r2s']:.2f}"
                hd = f"{100 * m['hd_s2r']:.2f} / {100 * m['hd_r2s']:.2f}"
                surf = f"{100 * m['surface_cd_s2r']:.2f} / {100 * m['surface_cd_r2s']:.2f}"
            arms = (s.get("robot") or {}).get("arms")
            held = (f"{arms['left']['squeeze_final_n']:.1f}, {arms['right']['squeeze_final_n']:.1f}" if arms else "")
            print(f"| {task} | {mode} | {s.get('ms_per_step', 0):.0f} | {100 * fin.get('max_z', 0):.1f} | "
                  f"{100 * fin.get('mean_z', 0):.1f} | {100 * fin.get('extent_x', 0):.0f}, {100 * fin.get('extent_y', 0):.0f} "
                  f"| {s.get('intersecting_pairs_max')} | {s.get('untangle_runs')} | {held} | {cd} | {hd} | {surf} |")
            table.append({"task": task, "mode": mode, "summary_final": fin, "metrics_vs_pseudo": m if mode == "robot" else None,
                          "failed": s.get("failed"), "ms_per_step": s.get("ms_per_step")})
    if args.json:
        Path(args.json).write_text(json.dumps(table, indent=1) + "\n")
    if args.png:
        draw(rows, Path(args.png))


if __name__ == "__main__":
    main()
