"""Tests of scripts/plot_convergence.py on a convergence.csv written by hand (gd converge's shape)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from png_size import png_size

ROOT = Path(__file__).resolve().parents[2]
PLOT = ROOT / "scripts" / "plot_convergence.py"


def test_draws_one_line_per_time_and_the_final_shapes(tmp_path: Path) -> None:
    rows = ["vertices,reference_vertices,t,final,cd,hd"]
    for t in (0.0, 2.0):
        for n, cd in ((1000, 0.004), (2000, 0.002), (4000, 0.001)):
            rows.append(f"{n},8000,{t},0,{cd},{10 * cd}")
    for n, cd in ((1000, 0.03), (2000, 0.02), (4000, 0.01)):
        rows.append(f"{n},8000,11.6,1,{cd},{8 * cd}")
    (tmp_path / "convergence.csv").write_text("\n".join(rows) + "\n")
    subprocess.run([sys.executable, str(PLOT), str(tmp_path)], check=True)
    width, height = png_size(tmp_path / "convergence.png")
    assert width > 1000 and height > 400


def test_an_empty_study_is_an_error_not_a_blank_plot(tmp_path: Path) -> None:
    (tmp_path / "convergence.csv").write_text("vertices,reference_vertices,t,final,cd,hd\n")
    r = subprocess.run([sys.executable, str(PLOT), str(tmp_path)], capture_output=True, text=True)
    assert r.returncode == 1
    assert "no rows" in r.stderr
    assert not (tmp_path / "convergence.png").exists()


def test_a_time_step_study_is_drawn_against_the_step(tmp_path: Path) -> None:
    header = "vertices,reference_vertices,t,final,cd,hd,cd_floor,hd_floor,ref_cd_floor,ref_hd_floor,dt,reference_dt"
    rows = [header]
    for dt, cd in ((0.01, 0.02), (0.005, 0.01)):
        rows.append(f"2000,2000,0.000,0,{cd / 10},{cd},,,,,{dt},0.0025")
        rows.append(f"2000,2000,13.7,1,{cd},{8 * cd},0.009,0.1,0.008,0.09,{dt},0.0025")
    (tmp_path / "convergence.csv").write_text("\n".join(rows) + "\n")
    subprocess.run([sys.executable, str(PLOT), str(tmp_path)], check=True)
    width, height = png_size(tmp_path / "convergence.png")
    assert width > 1000 and height > 400
