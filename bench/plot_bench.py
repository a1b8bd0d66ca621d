#!/usr/bin/env python3
"""Plots gd-bench --json results: ms per step against vertices, one line per backend and case kind
(drape, fold), log-log; and, for each file's largest cases, where a step's time goes (stage_ms).

    build/venv/bin/python bench/plot_bench.py RESULT.json [MORE.json ...] --png OUT.png
        [--label FILE=NAME ...] [--title TEXT]

Each file is one gd-bench --json array (lines starting with '==' are skipped, so a log that
wrapped the array can be read as it is). A file's label defaults to its backend and thread count
(`cuda`, `cpu 16 threads`); --label FILE=NAME overrides it. Also prints the table it plotted.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def load(path: Path) -> list[dict]:
    text = "".join(line for line in path.read_text().splitlines(keepends=True) if not line.startswith("=="))
    rows = json.loads(text)
    if not isinstance(rows, list):
        raise SystemExit(f"{path}: not a gd-bench --json array")
    return rows


def default_label(rows: list[dict]) -> str:
    r = rows[0]
    label = r.get("backend", "?")
    if label != "cuda" and r.get("threads"):
        label += f" {r['threads']} thread{'s' if r['threads'] != 1 else ''}"
    if r.get("deterministic"):
        label += " deterministic"
    return label


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("files", nargs="+", type=Path)
    ap.add_argument("--png", required=True)
    ap.add_argument("--label", action="append", default=[], help="FILE=NAME")
    ap.add_argument("--title", default="gd-bench: ms per 5 ms step")
    args = ap.parse_args()
    labels = dict(item.split("=", 1) for item in args.label)

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    series = []  # (label, kind, [(vertices, ms, row)])
    for f in args.files:
        rows = load(f)
        label = labels.get(str(f), labels.get(f.name, default_label(rows)))
        for kind in ("drape", "fold"):
            pts = sorted((r["vertices"], r["ms_per_step"], r) for r in rows if r["case"].startswith(kind + "/"))
            if pts:
                series.append((label, kind, pts))
    if not series:
        raise SystemExit("no drape/N or fold/N cases in the files")

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(13, 5))
    print(f"{'run':<22} {'case':<14} {'vertices':>9} {'ms/step':>9} {'Newton':>7} {'PCG':>7} {'converged':>9}")
    for label, kind, pts in series:
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o" if kind == "fold" else "s",
                linestyle="-" if kind == "fold" else "--", label=f"{label}: {kind}")
        for v, ms, r in pts:
            print(f"{label:<22} {r['case']:<14} {v:>9} {ms:>9.2f} {r.get('newton_iters', 0):>7.2f} "
                  f"{r.get('pcg_iters', 0):>7.1f} {r.get('converged', 0):>9.2f}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("vertices")
    ax.set_ylabel("ms per step")
    ax.set_title(args.title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)

    # Stages of each series' largest case, stacked.
    stages = ["predictor", "contacts", "assembly", "couplings", "precond", "pcg", "ccd", "line_search",
              "intersections", "untangle", "stopping"]
    picks = [(f"{label}\n{pts[-1][2]['case']}", pts[-1][2].get("stage_ms", {})) for label, _, pts in series]
    bottoms = [0.0] * len(picks)
    for s in stages:
        vals = [st.get(s, 0.0) for _, st in picks]
        if not any(v > 0 for v in vals):
            continue
        bx.bar(range(len(picks)), vals, bottom=bottoms, label=s)
        bottoms = [b + v for b, v in zip(bottoms, vals)]
    bx.set_xticks(range(len(picks)), [p[0] for p in picks], fontsize=7)
    bx.set_ylabel("ms per step")
    bx.set_yscale("linear")
    bx.set_title("where the largest case's step goes (stage_ms)")
    bx.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(args.png, dpi=110)
    print(f"wrote {args.png}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
