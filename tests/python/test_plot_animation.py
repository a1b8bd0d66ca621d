"""scripts/plot_animation.py on a report directory built by hand: animation.npy as `gd run` writes
it (float32 (F, N, 3)), the times in summary.json, and the trajectory CSV of the grippers."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "plot_animation.py"


def make_run(d: Path, frames: int = 12) -> None:
    g = np.linspace(-0.2, 0.2, 20)
    xx, yy = np.meshgrid(g + 0.4, g)
    flat = np.stack([xx.ravel(), yy.ravel(), np.zeros(xx.size)], axis=1)
    seq = []
    for k in range(frames):  # one edge lifted more each frame
        x = flat.copy()
        x[:, 2] = 0.3 * k / frames * np.clip((x[:, 1] + 0.2) / 0.4, 0, 1) ** 2
        seq.append(x)
    np.save(d / "animation.npy", np.asarray(seq, dtype=np.float32))
    times = [0.1 * k for k in range(frames)]
    (d / "summary.json").write_text(json.dumps({"garment": "towel", "task": "grasp", "mode": "pseudo",
                                                "animation": {"file": "animation.npy", "frames": frames,
                                                              "times": times}}))
    rows = ["# master_start_time = 0", "time,arm,x,y,z,qw,qx,qy,qz,gripper"]
    for t in (0.0, 0.5, 1.1):
        rows.append(f"{t},left,0.4,0.2,{0.3 * t},0,1,0,0,{0.035 if t < 0.4 else 0.0}")
        rows.append(f"{t},right,0.4,-0.2,0.1,0,1,0,0,0.035")
    (d / "trajectory.csv").write_text("\n".join(rows) + "\n")


def test_writes_an_animated_gif_with_a_frame_per_recorded_frame(tmp_path):
    make_run(tmp_path)
    proc = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    gif = tmp_path / "animation.gif"
    assert gif.read_bytes()[:6] in (b"GIF89a", b"GIF87a")
    from PIL import Image
    with Image.open(gif) as im:
        assert im.n_frames == 12
        im.seek(0)
        first = np.asarray(im.convert("RGB"), dtype=np.int32)
        im.seek(11)
        last = np.asarray(im.convert("RGB"), dtype=np.int32)
    assert np.abs(first - last).sum() > 0  # the lifted edge moved


def test_caps_the_frames_and_reports_a_missing_animation(tmp_path):
    make_run(tmp_path, frames=30)
    proc = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path), "--max-frames", "10"], capture_output=True,
                          text=True)
    assert proc.returncode == 0, proc.stderr
    from PIL import Image
    with Image.open(tmp_path / "animation.gif") as im:
        assert im.n_frames == 10
    empty = tmp_path / "empty"
    empty.mkdir()
    proc = subprocess.run([sys.executable, str(SCRIPT), str(empty)], capture_output=True, text=True)
    assert proc.returncode == 1 and "no" in proc.stderr


def test_writes_an_mp4_of_the_same_frames_with_an_ffmpeg(tmp_path):
    imageio_ffmpeg = __import__("pytest").importorskip("imageio_ffmpeg")
    make_run(tmp_path)
    proc = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    mp4 = tmp_path / "animation.mp4"
    assert mp4.read_bytes()[4:8] == b"ftyp"  # an MP4 container
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(mp4))
    assert frames == 12 and abs(seconds - 1.2) < 0.05  # 10 frames per second
    assert str(mp4) in proc.stdout.split()
    (tmp_path / "animation.mp4").unlink()
    proc = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path), "--no-mp4"], capture_output=True, text=True)
    assert proc.returncode == 0 and not mp4.exists()


def test_a_capture_runs_simulation_and_real_cloud_side_by_side(tmp_path):
    make_run(tmp_path)
    rng = np.random.default_rng(0)
    frames, points = 8, 500
    a = np.zeros((frames, 2, points, 3), dtype=np.float32)
    for k in range(frames):  # the simulated sheet rises; the "real" cloud lags it by 2 cm, with noise
        a[k, 0] = rng.uniform([0.2, -0.2, 0.0], [0.6, 0.2, 0.0], size=(points, 3))
        a[k, 0, :, 2] = 0.02 * k
        a[k, 1] = a[k, 0] + rng.normal(0.0, 0.003, size=(points, 3))
        a[k, 1, :, 2] -= 0.02
    np.save(tmp_path / "capture_animation.npy", a)
    summary = json.loads((tmp_path / "summary.json").read_text())
    summary["capture_animation"] = {"file": "capture_animation.npy", "frames": frames, "points": points,
                                    "times": [0.2 * k for k in range(frames)]}
    (tmp_path / "summary.json").write_text(json.dumps(summary))
    proc = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path), "--no-mp4"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    from PIL import Image
    with Image.open(tmp_path / "capture_animation.gif") as im:
        assert im.n_frames == frames
        im.seek(0)
        rgb = np.asarray(im.convert("RGB"), dtype=np.int32)
    blue = (rgb[..., 2] > 150) & (rgb[..., 0] < 100)    # tab:blue, the simulation
    orange = (rgb[..., 0] > 200) & (rgb[..., 2] < 80)   # tab:orange, the real cloud
    w = rgb.shape[1]
    # The simulation is drawn in the left panel, the real cloud in the middle one, both on the right
    # (the panels are about a third of the width each: a few pixels of a neighbour may fall inside).
    left, mid, right = slice(0, w // 3), slice(w // 3, 2 * w // 3), slice(2 * w // 3 + 20, w)
    assert blue[:, left].sum() > 200 and orange[:, left].sum() < 0.05 * blue[:, left].sum()
    assert orange[:, mid].sum() > 200 and blue[:, mid].sum() < 0.05 * orange[:, mid].sum()
    assert blue[:, right].sum() > 100 and orange[:, right].sum() > 100


def test_a_failing_ffmpeg_leaves_the_gif_and_says_why(tmp_path):
    # An ffmpeg on PATH that refuses at once (as one without an H.264 encoder does): the GIF is
    # still written, no MP4 is claimed, and stderr names the failure.
    make_run(tmp_path)
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    fake = bin_dir / "ffmpeg"
    fake.write_text("#!/bin/sh\necho 'Unknown encoder libx264' >&2\nexit 1\n")
    fake.chmod(0o755)
    env = dict(os.environ, PATH=f"{bin_dir}:{os.environ.get('PATH', '')}")
    proc = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path)], capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "animation.gif").read_bytes()[:6] in (b"GIF89a", b"GIF87a")
    assert "animation.mp4" not in proc.stdout
    assert "ffmpeg failed" in proc.stderr and "libx264" in proc.stderr
