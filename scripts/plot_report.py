#!/usr/bin/env python3
"""Plots a gd_metrics evaluation report (sim vs real, RGBench metrics).

    plot_report.py REPORT_DIR [--frames N]

Reads REPORT_DIR/metrics.csv (RGBench's shape: per-frame rows, then the unlabelled mean and
std_dev rows), and when present summary.json (calculate window), comparison.csv (the paper's
baseline rows, RGBench by Hu et al., AAAI 2026) and frames/{sim,real}_<k>.ply (+ frames.json).
Writes REPORT_DIR/metrics_over_time.png (each metric against sim_time, the calculate window
shaded, the paper's baselines as horizontal lines) and, when frames exist, REPORT_DIR/frames.png
(sim and real points side by side, top and side views, at up to N frames).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

# (metrics.csv column, short key used in summary.json and paper_baselines.csv, title)
METRICS = [
    ("chamfer_l1_sim_to_real", "cd_l1_s2r", "CD L1 sim→real"),
    ("chamfer_l2_sim_to_real", "cd_l2_s2r", "CD L2 sim→real"),
    ("chamfer_l1_real_to_sim", "cd_l1_r2s", "CD L1 real→sim"),
    ("one_sided_hausdorff_sim_to_real", "hd_s2r", "HD sim→real"),
    ("one_sided_hausdorff_real_to_sim", "hd_r2s", "HD real→sim"),
    ("sim_stability_score", "sim_stab", "sim stability"),
    ("z_mean_error", "z_err", "z mean error"),
]
BASELINE_STYLE = {"pybullet": ("tab:orange", "--"), "isaacsim": ("tab:green", ":"),
                  "mujoco_style3d": ("tab:purple", "-.")}


def fail(msg: str) -> None:
    print(f"plot_report: {msg}", file=sys.stderr)
    sys.exit(2)


def read_metrics_csv(path: Path) -> tuple[dict[str, np.ndarray], dict[str, float] | None]:
    """Per-frame columns, and the mean row (metrics only) when the file has one."""
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        raise ValueError(f"{path}: empty file")
    header = rows[0]
    missing = [c for c, _, _ in METRICS if c not in header] + [c for c in ("sim_time", "target_time") if c not in header]
    if missing:
        raise ValueError(f"{path}: missing columns {', '.join(missing)}")
    body = [r for r in rows[1:] if any(x.strip() for x in r)]
    # Summary rows have an empty sim_time (RGBench writes them with to_csv(index=False)).
    it = header.index("sim_time")
    frames = [r for r in body if r[it].strip()]
    summary = [r for r in body if not r[it].strip()]

    def num(x: str) -> float:
        return float(x) if x.strip() else math.nan

    data = {name: np.array([num(r[i]) for r in frames], dtype=float) for i, name in enumerate(header)}
    mean = None
    if summary:
        mean = {key: num(summary[0][header.index(col)]) for col, key, _ in METRICS}
    return data, mean


def read_baselines(path: Path) -> list[dict[str, str]]:
    if not path.is_file():
        return []
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def read_ply(path: Path) -> np.ndarray:
    """x, y, z of the vertex element of an ascii or binary PLY (float/double properties)."""
    data = path.read_bytes()
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise ValueError(f"{path}: not a PLY file")
    body_start = data.index(b"\n", end) + 1
    header = data[:end].decode("ascii", "replace").splitlines()
    fmt, n, props, in_vertex = "ascii", 0, [], False
    types = {"float": "f4", "float32": "f4", "double": "f8", "float64": "f8", "uchar": "u1", "uint8": "u1",
             "char": "i1", "int8": "i1", "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
             "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4"}
    for line in header:
        w = line.split()
        if not w:
            continue
        if w[0] == "format":
            fmt = w[1]
        elif w[0] == "element":
            if in_vertex:
                break  # the vertex element is all we read; it has to come first
            in_vertex = w[1] == "vertex"
            n = int(w[2]) if in_vertex else n
        elif w[0] == "property" and in_vertex:
            if w[1] == "list":
                raise ValueError(f"{path}: list property in the vertex element")
            props.append((w[2], types[w[1]]))
    names = [p for p, _ in props]
    if not all(c in names for c in "xyz"):
        raise ValueError(f"{path}: vertex element lacks x, y or z")
    if fmt == "ascii":
        lines = data[body_start:].decode("ascii").split("\n")[:n]
        arr = np.array([[float(v) for v in ln.split()[: len(props)]] for ln in lines if ln.strip()], dtype=float)
        arr = arr.reshape(-1, len(props))
        return arr[:, [names.index(c) for c in "xyz"]]
    order = "<" if fmt == "binary_little_endian" else ">"
    dt = np.dtype([(p, order + t) for p, t in props])
    rec = np.frombuffer(data, dtype=dt, count=n, offset=body_start)
    return np.stack([rec[c].astype(float) for c in "xyz"], axis=1)


def plot_metrics(data: dict[str, np.ndarray], window: dict | None, mean: dict[str, float] | None,
                 baselines: list[dict[str, str]], out: Path, title: str) -> None:
    t = data["sim_time"]
    fig, axes = plt.subplots(4, 2, figsize=(12, 12), sharex=True)
    axes = axes.ravel()
    for ax, (col, key, label) in zip(axes, METRICS):
        ax.plot(t, data[col], "o-", ms=2.5, lw=1.2, color="tab:blue", label="ours (per frame)")
        if window:
            s, e = window.get("start_calculate_time"), window.get("end_calculate_time")
            if s is not None and e is not None and math.isfinite(s) and math.isfinite(e):
                ax.axvspan(s, e, color="0.85", zorder=0, label="calculate window")
        if mean and math.isfinite(mean.get(key, math.nan)):
            ax.axhline(mean[key], color="tab:blue", lw=1, alpha=0.6, label=f"ours mean {mean[key]:.4f}")
        for b in baselines:
            sim = b.get("simulator", "")
            if sim not in BASELINE_STYLE:
                continue
            try:
                v = float(b[key])
            except (KeyError, ValueError):
                continue
            color, ls = BASELINE_STYLE[sim]
            name = "paper GarmentDynamics" if sim == "mujoco_style3d" else f"paper {sim}"
            ax.axhline(v, color=color, ls=ls, lw=1.2, label=f"{name} ({b.get('mode', '')}) {v:.4f}")
        ax.set_title(label)
        ax.set_ylabel("m")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6, loc="best")
    axes[-1].axis("off")
    for ax in axes[-3:-1]:
        ax.set_xlabel("sim time (s)")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def plot_frames(frames_dir: Path, out: Path, max_frames: int) -> bool:
    sims = sorted(frames_dir.glob("sim_*.ply"), key=lambda p: int(p.stem.split("_")[1]))
    pairs = [(s, frames_dir / s.name.replace("sim_", "real_")) for s in sims]
    pairs = [(s, r) for s, r in pairs if r.is_file()]
    if not pairs:
        return False
    if len(pairs) > max_frames:
        idx = np.linspace(0, len(pairs) - 1, max_frames).round().astype(int)
        pairs = [pairs[i] for i in sorted(set(idx))]
    times = {}
    index = frames_dir / "frames.json"
    if index.is_file():
        times = {int(e["k"]): e.get("sim_time") for e in json.loads(index.read_text())}
    n = len(pairs)
    # One row per frame: sim (top view) | real (top view) | both from the side (x-z).
    fig, axes = plt.subplots(n, 3, figsize=(13, 3.9 * n), squeeze=False)
    for i, (s, r) in enumerate(pairs):
        sim, real = read_ply(s), read_ply(r)
        both = np.vstack([sim, real]) if len(sim) and len(real) else (sim if len(sim) else real)
        lo, hi = both.min(axis=0), both.max(axis=0)
        pad = 0.05 * max(float((hi - lo)[:2].max()), 1e-3)
        k = int(s.stem.split("_")[1])
        t = times.get(k)
        when = f"frame {k}" + (f", sim t = {t:.2f} s" if isinstance(t, (int, float)) else "")
        for j, (pts, color, name) in enumerate([(sim, "tab:red", "sim"), (real, "0.3", "real")]):
            ax = axes[i][j]
            ax.scatter(pts[:, 0], pts[:, 1], s=0.5, c=color, alpha=0.6, rasterized=True)
            ax.set_xlim(lo[0] - pad, hi[0] + pad)
            ax.set_ylim(lo[1] - pad, hi[1] + pad)
            ax.set_aspect("equal", adjustable="box")
            ax.set_title(f"{when}: {name}, top view ({len(pts)} points)", fontsize=9)
            ax.set_xlabel("x (m)")
            ax.set_ylabel("y (m)")
            ax.grid(alpha=0.3)
        ax = axes[i][2]
        ax.scatter(real[:, 0], real[:, 2], s=0.5, c="0.3", alpha=0.4, label="real", rasterized=True)
        ax.scatter(sim[:, 0], sim[:, 2], s=0.5, c="tab:red", alpha=0.6, label="sim", rasterized=True)
        ax.set_title(f"{when}: side view (x-z)", fontsize=9)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("z (m)")
        ax.grid(alpha=0.3)
        ax.legend(markerscale=12, fontsize=8, loc="best")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return True


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("report_dir", type=Path)
    p.add_argument("--frames", type=int, default=4, help="at most this many frames in frames.png")
    args = p.parse_args(argv)
    d: Path = args.report_dir
    if not d.is_dir():
        fail(f"report directory '{d}' does not exist")
    csv_path = d / "metrics.csv"
    if not csv_path.is_file():
        fail(f"'{csv_path}' not found: is '{d}' a gd metrics report directory?")
    try:
        data, mean = read_metrics_csv(csv_path)
    except ValueError as e:
        fail(str(e))
    if data["sim_time"].size == 0:
        fail(f"'{csv_path}' has no per-frame rows")
    window, title = None, d.name
    summary = d / "summary.json"
    if summary.is_file():
        s = json.loads(summary.read_text())
        window = s.get("window")
        parts = [str(s[k]) for k in ("garment", "action", "sample", "simulator") if s.get(k)]
        if parts:
            title = " / ".join(parts)
        if mean is None and isinstance(s.get("mean"), dict):
            mean = {k: (v if v is not None else math.nan) for k, v in s["mean"].items()}
    rows = read_baselines(d / "comparison.csv")
    baselines = [b for b in rows if b.get("simulator") in BASELINE_STYLE]
    if any(r.get("capture") == "synthetic" for r in rows):
        # ours was measured against a capture a simulator made: say so beside the paper's lines
        title += " (ours vs a synthetic capture; paper lines vs real ones)"
    plot_metrics(data, window, mean, baselines, d / "metrics_over_time.png", title)
    written = ["metrics_over_time.png"]
    if (d / "frames").is_dir():
        try:
            if plot_frames(d / "frames", d / "frames.png", max(1, args.frames)):
                written.append("frames.png")
        except ValueError as e:
            fail(str(e))
    print(f"plot_report: wrote {', '.join(str(d / w) for w in written)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
