#!/usr/bin/env python3
"""The final shapes of several `scripts/compare_modes.py` runs in one figure (docs/robot.md, "Pseudo
and robot mode side by side"): one panel per garment and task, seen from the side (x, z), pseudo
mode in blue and robot mode in red.

    build/venv/bin/python scripts/plot_modes_grid.py out/modes/dress:grasp out/modes/skirt:fling \\
        --out docs/img/robot_vs_pseudo_default.png

Each argument is DIR:TASK, DIR being a compare_modes.py --out directory (it holds TASK_pseudo/ and
TASK_robot/, each with final.obj); a panel whose runs are missing is left out.
"""

import argparse
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from compare_modes import read_obj  # noqa: E402  (the same OBJ reading as compare_modes.py's own figure)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("runs", nargs="+", metavar="DIR:TASK")
    p.add_argument("--out", required=True, help="PNG to write")
    p.add_argument("--columns", type=int, default=4)
    args = p.parse_args()
    if args.columns < 1:
        p.error("--columns must be at least 1")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = []
    for spec in args.runs:
        d, _, task = spec.rpartition(":")
        if not d or not task:
            p.error(f"{spec}: expected DIR:TASK")
        finals = {m: Path(d) / f"{task}_{m}" / "final.obj" for m in ("pseudo", "robot")}
        if not all(f.exists() for f in finals.values()):
            print(f"{spec}: no final.obj for both modes, left out", file=sys.stderr)
            continue
        panels.append((f"{Path(d).name.replace('_', ' ')}, {task}", finals))
    if not panels:
        sys.exit("no run has both modes' final shapes")
    cols = min(args.columns, len(panels))
    rows = math.ceil(len(panels) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 3.2 * rows), squeeze=False)
    colors = {"pseudo": "tab:blue", "robot": "tab:red"}
    for ax, (title, finals) in zip(axes.flat, panels):
        for mode, path in finals.items():
            v, f = read_obj(path)
            ax.triplot(v[:, 0], v[:, 2], f, color=colors[mode], lw=0.12, alpha=0.5)
            ax.plot([], [], color=colors[mode], label=mode)
        ax.set_title(title, fontsize=10)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("z (m)")
        ax.legend(loc="upper right", fontsize=8)
    for ax in list(axes.flat)[len(panels):]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out} ({len(panels)} panels)")


if __name__ == "__main__":
    main()
