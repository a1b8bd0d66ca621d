#!/usr/bin/env python3
"""Plots the Cusick drape against measured fabrics, as written by `gd-validate --drape-reference --json`.

    gd-validate --drape-reference --json > drape_reference.json
    plot_drape_reference.py drape_reference.json OUT.png

One point per fabric: the measured drape coefficient (x) against ours (filled) and CLO3D's from
the same parameters (open, the reference file's peer), with the line where simulated equals
measured (docs/validation.md, "Drape against measured fabrics").
"""

from __future__ import annotations

import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def short(name: str) -> str:
    # petrak2025_m6_cotton_blend_twill -> m6 (docs/validation.md's table names each)
    return name.split("_", 1)[-1].split("_", 1)[0]


def main() -> int:
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    study = json.load(open(sys.argv[1]))
    rows = [r for r in study["fabrics"] if r.get("simulated") is not None]
    if not rows:
        print(f"{sys.argv[1]}: no fabric has a simulated coefficient", file=sys.stderr)
        return 1
    fig, ax = plt.subplots(figsize=(6.4, 5.6))
    lo, hi = 0.1, 0.7
    ax.plot([lo, hi], [lo, hi], color="0.6", lw=1, ls="--", label="simulated = measured")
    x = [r["measured"] for r in rows]
    rho = study.get("rank_correlation")
    ax.scatter(x, [r["simulated"] for r in rows], color="tab:blue", zorder=3,
               label="GarmentDynamics" + (f" (Spearman {rho:.2f})" if rho is not None else ""))
    peers = [(r["measured"], r["clo3d"]) for r in rows if r.get("clo3d") is not None]
    if peers:
        ax.scatter(*zip(*peers), facecolors="none", edgecolors="tab:orange", zorder=3,
                   label="CLO3D, same parameters (paper)")
    for r in rows:
        ax.annotate(short(r["material"]), (r["measured"], r["simulated"]), fontsize=8,
                    xytext=(5, -3), textcoords="offset points")
        if r.get("clo3d") is not None:  # the same fabric's two simulations
            ax.plot([r["measured"]] * 2, [r["simulated"], r["clo3d"]], color="0.85", lw=1, zorder=1)
    ax.set_xlim(lo, hi)
    ax.set_ylim(lo, hi)
    ax.set_aspect("equal")
    ax.set_xlabel("measured drape coefficient (Cusick)")
    ax.set_ylabel("simulated drape coefficient")
    ax.set_title("Cusick drape of six woven fabrics (Petrak et al. 2025)", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)
    print(f"wrote {sys.argv[2]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
