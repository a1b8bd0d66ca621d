#!/usr/bin/env python3
"""Draws a run's animation: REPORT_DIR/animation.gif (and .mp4) from REPORT_DIR/animation.npy, and
for a capture run REPORT_DIR/capture_animation.gif (and .mp4) from capture_animation.npy.

    plot_animation.py REPORT_DIR [--fps 10] [--max-frames 120] [--no-mp4]

`gd run` (and the server's jobs with --plots) writes animation.npy (float32 (F, N, 3): the garment's
vertices, world frame, at the times listed in summary.json "animation") and calls this script.
Each GIF frame shows the garment from the front (y, z: the arms at y = +/-0.25 face the viewer)
and from above (x, y): its triangles (from initial.obj) drawn far to near, coloured by height, the
table line, and the grippers from trajectory.csv (green open, purple closed).

A capture run (`gd run --capture`) also writes capture_animation.npy (float32 (F, 2, P, 3): the
simulated vertices and the real capture's points, each resampled to P points, world frame, at the
evaluated frames listed in summary.json "capture_animation"); its animation shows the simulation and
the real cloud side by side from the front, and both from above.

The MP4s (H.264) are written where an ffmpeg is found: on PATH, else the one the PyPI package
imageio-ffmpeg ships (scripts/requirements.txt has it). Each frame is drawn once for both files.
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import subprocess
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from PIL import Image  # noqa: E402


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


def ffmpeg_exe():
    """An ffmpeg binary: on PATH, else imageio-ffmpeg's; None without either."""
    exe = shutil.which("ffmpeg")
    if exe:
        return exe
    try:
        import imageio_ffmpeg
        return imageio_ffmpeg.get_ffmpeg_exe()
    except Exception:  # not installed, or its binary missing
        return None


class Movie:
    """A figure's frames to STEM.gif (Pillow) and, with an ffmpeg, STEM.mp4 (H.264): add() after
    drawing each frame, close() writes them and returns the paths written."""

    def __init__(self, fig, stem: Path, fps: float, mp4: bool):
        self.fig, self.stem, self.fps = fig, stem, fps
        self.frames: list = []
        self.proc = None
        self.exe = ffmpeg_exe() if mp4 else None

    def add(self) -> None:
        self.fig.canvas.draw()
        rgb = np.ascontiguousarray(np.asarray(self.fig.canvas.buffer_rgba())[..., :3])
        self.frames.append(Image.fromarray(rgb))
        if self.exe and self.proc is None:
            h, w = rgb.shape[:2]
            self.proc = subprocess.Popen(
                [self.exe, "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{w}x{h}",
                 "-r", f"{self.fps:g}", "-i", "-", "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-c:v", "libx264",
                 "-pix_fmt", "yuv420p", "-movflags", "+faststart", str(self.stem.with_suffix(".mp4"))],
                stdin=subprocess.PIPE, stderr=subprocess.PIPE)
        if self.proc is not None and self.proc.stdin is not None:
            try:
                self.proc.stdin.write(rgb.tobytes())
            except BrokenPipeError:  # ffmpeg gave up (e.g. no H.264 encoder): the GIF goes on, close() says why
                self.proc.stdin = None

    def close(self) -> list:
        out = []
        gif = self.stem.with_suffix(".gif")
        if self.frames:
            self.frames[0].save(gif, save_all=True, append_images=self.frames[1:],
                                duration=int(round(1000 / self.fps)), loop=0)
            out.append(gif)
        if self.proc is not None:
            if self.proc.stdin is not None:
                try:
                    self.proc.stdin.close()
                except BrokenPipeError:
                    pass
                self.proc.stdin = None
            _, err = self.proc.communicate()
            if self.proc.returncode == 0:
                out.append(self.stem.with_suffix(".mp4"))
            else:
                print(f"plot_animation: ffmpeg failed ({self.proc.returncode}): {err.decode(errors='replace')[-500:]}",
                      file=sys.stderr)
        return out


def capture_movie(d: Path, summary: dict, fps: float, mp4: bool) -> list:
    """capture_animation.{gif,mp4}: simulation and real capture side by side (front), both from above."""
    a = np.load(d / "capture_animation.npy")  # (F, 2, P, 3)
    times = np.asarray(summary.get("capture_animation", {}).get("times", np.arange(len(a)) * 0.1), dtype=float)
    if len(times) != len(a):
        times = np.arange(len(a)) * 0.1
    pts = a.reshape(-1, 3)
    lo, hi = pts.min(axis=0) - 0.03, pts.max(axis=0) + 0.03
    fig, (sim_ax, real_ax, top) = plt.subplots(1, 3, figsize=(13, 4.4), dpi=72)
    title = f"{summary.get('garment', '')} {summary.get('task', '')}: simulation and real capture".strip()
    movie = Movie(fig, d / "capture_animation", fps, mp4)
    for i in range(len(a)):
        for ax in (sim_ax, real_ax, top):
            ax.clear()
        sim, real = a[i, 0], a[i, 1]
        sim_ax.scatter(sim[:, 1], sim[:, 2], s=3, c="tab:blue", linewidths=0, zorder=2)
        real_ax.scatter(real[:, 1], real[:, 2], s=3, c="tab:orange", linewidths=0, zorder=2)
        top.scatter(real[:, 0], real[:, 1], s=3, c="tab:orange", linewidths=0, label="real")
        top.scatter(sim[:, 0], sim[:, 1], s=1.5, c="tab:blue", linewidths=0, label="simulation")
        for ax, name in ((sim_ax, "simulation, front (y, z)"), (real_ax, "real capture, front (y, z)")):
            ax.set_xlim(hi[1], lo[1])
            ax.set_ylim(lo[2], hi[2])
            ax.axhline(0.0, color="0.6", lw=1, zorder=1)  # the table
            ax.set_title(name, fontsize=9)
        top.set_xlim(lo[0], hi[0])
        top.set_ylim(lo[1], hi[1])
        top.set_title("both, top (x, y)", fontsize=9)
        top.legend(loc="upper right", fontsize=7, markerscale=6)
        for ax in (sim_ax, real_ax, top):
            ax.set_aspect("equal")
            ax.tick_params(labelsize=7)
        fig.suptitle(f"{title}   t = {times[i]:5.2f} s", fontsize=10)
        movie.add()
    plt.close(fig)
    return movie.close()


def arm_at(track, t: float):
    times, xyz, grip = track
    return np.array([np.interp(t, times, xyz[:, k]) for k in range(3)]), float(np.interp(t, times, grip))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("report_dir")
    p.add_argument("--fps", type=float, default=10.0)
    p.add_argument("--max-frames", type=int, default=120)
    p.add_argument("--no-mp4", action="store_true", help="only the GIFs, even where an ffmpeg is found")
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
    fig, (front, top) = plt.subplots(1, 2, figsize=(10, 4.6), dpi=72)
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

    movie = Movie(fig, d / "animation", args.fps, not args.no_mp4)
    for k in range(len(pick)):
        draw(k)
        movie.add()
    plt.close(fig)
    written = movie.close()
    if (d / "capture_animation.npy").exists():
        written += capture_movie(d, summary, args.fps, not args.no_mp4)
    for path in written:
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
