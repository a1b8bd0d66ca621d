#!/usr/bin/env python3
"""Draws a run's animation: REPORT_DIR/animation.gif from REPORT_DIR/animation.npy.

    plot_animation.py REPORT_DIR [--fps 10] [--max-frames 120]

`gd run` (and the server's jobs with --plots) writes animation.npy (float32 (F, N, 3): the garment's
vertices, world frame, at the times listed in summary.json "animation") and calls this script.
Each GIF frame shows the garment from the front (y, z: the arms at y = +/-0.25 face the viewer)
and from above (x, y): its triangles (from initial.obj) drawn far to near, coloured by height, the
table line, and the grippers from trajectory.csv (green open, purple closed).
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.animation import FuncAnimation, PillowWriter  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402


def read_triangles(path: Path):
    """The faces of an OBJ (0-based, triangles), or None."""
    if not path.exists():
        return None
    faces = [[int(w.split("/")[0]) - 1 for w in line.split()[1:4]]
             for line in path.read_text().splitlines() if line.startswith("f ")]
    return np.array(faces, dtype=int) if faces else None


def read_trajectory(path: Path):
    """Our trajectory CSV (time, arm, x, y, z, qw..qz, gripper) -> {arm: (times, xyz, gripper)}."""
    if not path.exists():
        return {}
    rows: dict = {}
    with path.open() as f:
        for r in csv.DictReader(line for line in f if not line.startswith("#")):
            rows.setdefault(r["arm"], []).append((float(r["time"]), float(r["x"]), float(r["y"]), float(r["z"]),
                                                  float(r["gripper"])))
    out = {}
    for arm, rs in rows.items():
        a = np.array(rs)
        out[arm] = (a[:, 0], a[:, 1:4], a[:, 4])
    return out


def arm_at(track, t: float):
    times, xyz, grip = track
    return np.array([np.interp(t, times, xyz[:, k]) for k in range(3)]), float(np.interp(t, times, grip))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("report_dir")
    p.add_argument("--fps", type=float, default=10.0)
    p.add_argument("--max-frames", type=int, default=120)
    args = p.parse_args()
    d = Path(args.report_dir)
    npy = d / "animation.npy"
    if not npy.exists():
        print(f"plot_animation: no {npy}", file=sys.stderr)
        return 1
    x = np.load(npy)  # (F, N, 3)
    summary = json.loads((d / "summary.json").read_text()) if (d / "summary.json").exists() else {}
    times = np.asarray(summary.get("animation", {}).get("times", np.arange(len(x)) * 0.1), dtype=float)
    if len(times) != len(x):
        times = np.arange(len(x)) * 0.1
    pick = np.unique(np.linspace(0, len(x) - 1, min(len(x), args.max_frames)).round().astype(int))
    traj = read_trajectory(d / "trajectory.csv")
    prepare = float(summary.get("sim_prepare_time", 0.0) or 0.0)
    lo, hi = x.reshape(-1, 3).min(axis=0), x.reshape(-1, 3).max(axis=0)
    for track in traj.values():
        lo = np.minimum(lo, track[1].min(axis=0))
        hi = np.maximum(hi, track[1].max(axis=0))
    pad = 0.05
    lo, hi = lo - pad, hi + pad
    lo[2] = min(lo[2], -0.02)
    fig, (front, top) = plt.subplots(1, 2, figsize=(10, 4.6))
    title = f"{summary.get('garment', '')} {summary.get('task', '')} ({summary.get('mode', '')} mode)".strip()
    norm = plt.Normalize(vmin=lo[2], vmax=hi[2])
    cmap = plt.get_cmap("viridis")
    tris = read_triangles(d / "initial.obj")
    if tris is not None and tris.max() >= x.shape[1]:
        tris = None

    def surface(ax, p, a: int, b: int, depth: np.ndarray):
        """The triangles projected on axes (a, b), far ones first; points when there are none."""
        if tris is None:
            ax.scatter(p[:, a], p[:, b], c=p[:, 2], cmap=cmap, norm=norm, s=1.5, linewidths=0)
            return
        order = np.argsort(depth[tris].mean(axis=1))
        t = tris[order]
        polys = p[t][:, :, [a, b]]
        ax.add_collection(PolyCollection(polys, facecolors=cmap(norm(p[t, 2].mean(axis=1))), edgecolors="none",
                                         antialiased=False))

    def draw(k):
        i = pick[k]
        t = times[i]
        for ax in (front, top):
            ax.clear()
        surface(front, x[i], 1, 2, x[i, :, 0])   # seen from +x: the largest x nearest
        front.axhline(0.0, color="0.6", lw=1)
        surface(top, x[i], 0, 1, x[i, :, 2])     # seen from above: the highest nearest
        for arm, track in traj.items():
            pos, grip = arm_at(track, t - prepare)
            color = "tab:green" if grip > 0.01 else "tab:purple"
            front.plot(pos[1], pos[2], "o", color=color, ms=7)
            top.plot(pos[0], pos[1], "o", color=color, ms=7)
        front.set_xlim(hi[1], lo[1])  # seen from the front (+x looks back at the robots): y to the left
        front.set_ylim(lo[2], hi[2])
        top.set_xlim(lo[0], hi[0])
        top.set_ylim(lo[1], hi[1])
        for ax, name in ((front, "front (y, z)"), (top, "top (x, y)")):
            ax.set_aspect("equal")
            ax.set_title(name, fontsize=9)
            ax.tick_params(labelsize=7)
        fig.suptitle(f"{title}   t = {t:5.2f} s", fontsize=10)
        return []

    anim = FuncAnimation(fig, draw, frames=len(pick), blit=False)
    out = d / "animation.gif"
    anim.save(out, writer=PillowWriter(fps=args.fps), dpi=72)
    plt.close(fig)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
