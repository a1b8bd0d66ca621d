"""Tests of scripts/plot_report.py on a small report directory built by hand."""

from __future__ import annotations

import json
import math
import struct
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PLOT = ROOT / "scripts" / "plot_report.py"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
COLUMNS = ["chamfer_l1_sim_to_real", "chamfer_l2_sim_to_real", "chamfer_l1_real_to_sim",
           "one_sided_hausdorff_sim_to_real", "one_sided_hausdorff_real_to_sim", "sim_stability_score",
           "z_mean_error", "sim_time", "target_time"]


def sheet(n: int, phase: float) -> list[tuple[float, float, float]]:
    pts = []
    for i in range(n):
        for j in range(n):
            x, y = -0.3 + 0.6 * i / (n - 1), -0.3 + 0.6 * j / (n - 1)
            pts.append((x, y, 0.1 + 0.05 * math.sin(6 * x + phase) * math.cos(4 * y)))
    return pts


def write_ply(path: Path, pts, binary: bool) -> None:
    head = (f"ply\nformat {'binary_little_endian' if binary else 'ascii'} 1.0\nelement vertex {len(pts)}\n"
            "property float x\nproperty float y\nproperty float z\nend_header\n")
    with path.open("wb") as f:
        f.write(head.encode())
        for p in pts:
            f.write(struct.pack("<3f", *p) if binary else f"{p[0]} {p[1]} {p[2]}\n".encode())


def make_report(d: Path) -> None:
    lines = [",".join(COLUMNS)]
    for k in range(30):
        t = 0.1 * k
        vals = [0.02 + 0.01 * math.sin(t + i) ** 2 for i in range(7)]
        lines.append(",".join(f"{v!r}" for v in vals + [t + 0.05, t]))
    lines.append(",".join(["0.025"] * 7 + ["", ""]))
    lines.append(",".join(["0.004"] * 7 + ["", ""]))
    (d / "metrics.csv").write_text("\n".join(lines) + "\n")
    (d / "summary.json").write_text(json.dumps({
        "garment": "beige_hoodie", "action": "fling", "frames_in_window": 20,
        "window": {"start_record_time": 0, "end_record_time": 3, "start_calculate_time": 0.5,
                   "end_calculate_time": 2.5}}))
    (d / "comparison.csv").write_text(
        "garment,action,simulator,mode,n_samples,cd_l1_s2r,cd_l2_s2r,cd_l1_r2s,hd_s2r,hd_r2s,sim_stab,z_err\n"
        "beige_hoodie,fling,ours,fixed_point,1,0.025,0.025,0.025,0.025,0.025,0.025,0.025\n"
        "beige_hoodie,fling,isaacsim,fixed_point,3,0.0617,0.0479,0.0352,0.1906,0.1493,0.0167,0.0076\n"
        "beige_hoodie,fling,mujoco_style3d,fixed_point,3,0.0425,0.0332,0.0256,0.1409,0.1254,0.0166,0.0064\n")
    frames = d / "frames"
    frames.mkdir()
    index = []
    for k in range(3):
        write_ply(frames / f"sim_{k}.ply", sheet(25, 0.3 * k), binary=True)
        write_ply(frames / f"real_{k}.ply", sheet(40, 0.3 * k + 0.1), binary=(k != 1))
        index.append({"k": k, "row": 10 * k, "sim_time": 1.0 * k})
    (frames / "frames.json").write_text(json.dumps(index))


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(PLOT), *args], capture_output=True, text=True, timeout=180)


def test_plot_report_writes_both_pngs(tmp_path: Path) -> None:
    make_report(tmp_path)
    r = run(str(tmp_path))
    assert r.returncode == 0, r.stderr
    for name in ("metrics_over_time.png", "frames.png"):
        data = (tmp_path / name).read_bytes()
        assert data[:8] == PNG_MAGIC, name
        assert len(data) > 10_000, name


def test_plot_report_without_frames_or_summary(tmp_path: Path) -> None:
    make_report(tmp_path)
    for p in (tmp_path / "frames").iterdir():
        p.unlink()
    (tmp_path / "frames").rmdir()
    (tmp_path / "summary.json").unlink()
    r = run(str(tmp_path))
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "metrics_over_time.png").read_bytes()[:8] == PNG_MAGIC
    assert not (tmp_path / "frames.png").exists()


def test_plot_report_missing_dir_is_a_clear_error(tmp_path: Path) -> None:
    r = run(str(tmp_path / "nope"))
    assert r.returncode != 0
    assert "does not exist" in r.stderr
    r = run(str(tmp_path))
    assert r.returncode != 0
    assert "metrics.csv" in r.stderr
