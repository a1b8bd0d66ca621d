#!/usr/bin/env python3
"""Plots the time series that gd-demo writes.

    plot_demo.py DIR [--out PATH]

Reads DIR/timeseries.csv (columns t,kinetic,stretch,bending,gravity,total,max_strain,
newton_iters,pcg_iters,ms) and writes DIR/demo.png (or PATH): two stacked panels sharing the
time axis, the energies (gravity and total relative to their initial values) and the largest
stretch strain in percent.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

REQUIRED = ("t", "kinetic", "stretch", "bending", "gravity", "total", "max_strain")


def read_timeseries(path: Path) -> dict[str, np.ndarray]:
    data = np.genfromtxt(path, delimiter=",", names=True, dtype=float, ndmin=1)
    if data.dtype.names is None:
        raise ValueError(f"{path}: no header row")
    missing = [c for c in REQUIRED if c not in data.dtype.names]
    if missing:
        raise ValueError(f"{path}: missing columns {', '.join(missing)}")
    if data.size == 0:
        raise ValueError(f"{path}: no data rows")
    return {name: np.atleast_1d(data[name]) for name in data.dtype.names}


def plot(ts: dict[str, np.ndarray], out: Path, title: str) -> None:
    t = ts["t"]
    fig, (ax_e, ax_s) = plt.subplots(2, 1, sharex=True, figsize=(9, 7), height_ratios=(2, 1))

    ax_e.plot(t, ts["kinetic"], label="kinetic")
    ax_e.plot(t, ts["stretch"], label="stretch (membrane)")
    ax_e.plot(t, ts["bending"], label="bending")
    ax_e.plot(t, ts["gravity"] - ts["gravity"][0], label="gravity − initial")
    ax_e.plot(t, ts["total"] - ts["total"][0], "k--", linewidth=1.5, label="total − initial")
    ax_e.axhline(0.0, color="0.7", linewidth=0.8)
    ax_e.set_ylabel("energy (J)")
    ax_e.legend(loc="best", fontsize=9)
    ax_e.grid(True, alpha=0.3)
    ax_e.set_title("Energies")

    ax_s.plot(t, 100.0 * ts["max_strain"], color="tab:red")
    ax_s.set_xlabel("time (s)")
    ax_s.set_ylabel("max stretch strain (%)")
    ax_s.grid(True, alpha=0.3)
    ax_s.set_title("Largest warp/weft strain over all triangles")

    fig.suptitle(title)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Plot gd-demo's timeseries.csv to demo.png")
    ap.add_argument("dir", type=Path, help="gd-demo output directory (holds timeseries.csv)")
    ap.add_argument("--out", type=Path, default=None, help="PNG path (default DIR/demo.png)")
    ap.add_argument("--title", default="Cotton square hanging from two corners (gd-demo)")
    args = ap.parse_args(argv)

    csv = args.dir / "timeseries.csv"
    if not csv.is_file():
        print(f"plot_demo.py: {csv} not found (run gd-demo --out {args.dir} first)", file=sys.stderr)
        return 2
    try:
        ts = read_timeseries(csv)
    except ValueError as e:
        print(f"plot_demo.py: {e}", file=sys.stderr)
        return 2
    out = args.out if args.out is not None else args.dir / "demo.png"
    plot(ts, out, args.title)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
