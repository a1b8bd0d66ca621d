#!/usr/bin/env python3
"""Plots a mesh-convergence study written by `gd converge`.

    plot_convergence.py STUDY_DIR

Reads STUDY_DIR/convergence.csv (vertices, reference_vertices, t, final, cd, hd per compared
shape, the floors of a study with several draws, and each run's time step: dt, reference_dt) and
writes STUDY_DIR/convergence.png: the symmetric Chamfer and Hausdorff distances of each run's
shapes to the finest run's, against the vertex count (log-log; a time-step study, `gd converge
--dts`: against the time step), one line per compared time (the final shapes drawn thick), and
with draws the final shapes' spread between draws of each resolution (dashed).
"""

from __future__ import annotations

import csv
import sys
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402


def main() -> int:
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    study = Path(sys.argv[1])
    rows = list(csv.DictReader(open(study / "convergence.csv")))
    if not rows:
        print(f"{study}/convergence.csv has no rows", file=sys.stderr)
        return 1
    # A time-step study varies dt at one vertex count: its runs are placed by their step (ms).
    by_dt = len({r.get("dt") for r in rows}) > 1
    def level(r, ref=False):
        if by_dt:
            return 1e3 * float(r["reference_dt" if ref else "dt"])
        return int(r["reference_vertices" if ref else "vertices"])

    series: dict[tuple[bool, float], list[tuple[float, float, float]]] = defaultdict(list)
    # With several draws per resolution (gd converge --draws): the final shapes' spread between
    # two draws of each resolution, the floor a distance between resolutions cannot go below.
    floors: list[tuple[int, float, float]] = []
    ref_floor = None
    for r in rows:
        key = (r["final"] == "1", float(r["t"]))
        series[key].append((level(r), float(r["cd"]), float(r["hd"])))
        if key[0] and r.get("cd_floor"):
            floors.append((level(r), float(r["cd_floor"]), float(r["hd_floor"])))
            if r.get("ref_cd_floor"):
                ref_floor = (level(r, ref=True), float(r["ref_cd_floor"]), float(r["ref_hd_floor"]))
    reference = (f"dt = {level(rows[0], ref=True):g} ms ({rows[0]['reference_vertices']} vertices)" if by_dt
                 else f"{rows[0]['reference_vertices']} vertices")
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for (final, t), pts in sorted(series.items()):
        pts.sort()
        n = [p[0] for p in pts]
        label = f"final (t = {t:.2f} s)" if final else f"t = {t:.2f} s"
        style = {"linewidth": 2.5, "color": "black"} if final else {"linewidth": 1, "alpha": 0.7}
        for ax, k in zip(axes, (1, 2)):
            ax.plot(n, [1e3 * p[k] for p in pts], marker="o", label=label, **style)
    if floors:
        if ref_floor:
            floors.append(ref_floor)
        floors.sort()
        for ax, k in zip(axes, (1, 2)):
            ax.plot([p[0] for p in floors], [1e3 * p[k] for p in floors], marker="s", linestyle="--", color="tab:red",
                    label="final: between draws of one " + ("time step" if by_dt else "resolution") + " (floor)")
    for ax, title in zip(axes, ("symmetric Chamfer distance", "symmetric Hausdorff distance")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        if by_dt:  # a step range of a few times: plain numbers, not powers of ten
            ax.xaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
            ax.xaxis.set_minor_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
        ax.set_xlabel("time step (ms)" if by_dt else "vertices")
        ax.set_ylabel("mm to the reference run")
        ax.set_title(f"{title} to {reference}", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(study / "convergence.png", dpi=120)
    return 0


if __name__ == "__main__":
    sys.exit(main())
