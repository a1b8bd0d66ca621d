"""Tests of scripts/plot_modes_grid.py on compare_modes.py-shaped directories written by hand."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from png_size import png_size

ROOT = Path(__file__).resolve().parents[2]
PLOT = ROOT / "scripts" / "plot_modes_grid.py"


def write_square(path: Path, z: float) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"v 0 0 {z}\nv 0.1 0 {z}\nv 0.1 0.1 {z + 0.05}\nv 0 0.1 {z + 0.05}\nf 1 2 3\nf 1 3 4\n")


def test_one_panel_per_run_with_both_modes_and_the_incomplete_ones_left_out(tmp_path: Path) -> None:
    for garment, task in (("dress", "grasp"), ("skirt", "fling"), ("coat", "fold")):
        write_square(tmp_path / garment / f"{task}_pseudo" / "final.obj", 0.0)
        write_square(tmp_path / garment / f"{task}_robot" / "final.obj", 0.02)
    write_square(tmp_path / "hoodie" / "fling_pseudo" / "final.obj", 0.0)  # its robot run is missing
    out = tmp_path / "grid.png"
    r = subprocess.run([sys.executable, str(PLOT), f"{tmp_path / 'dress'}:grasp", f"{tmp_path / 'skirt'}:fling",
                        f"{tmp_path / 'coat'}:fold", f"{tmp_path / 'hoodie'}:fling", "--out", str(out),
                        "--columns", "2"], capture_output=True, text=True, check=True)
    assert "3 panels" in r.stdout
    assert "hoodie" in r.stderr and "left out" in r.stderr
    width, height = png_size(out)
    assert width > 700 and height > 600  # two columns, two rows


def test_no_complete_run_is_an_error_not_a_blank_figure(tmp_path: Path) -> None:
    write_square(tmp_path / "towel" / "grasp_pseudo" / "final.obj", 0.0)
    out = tmp_path / "grid.png"
    r = subprocess.run([sys.executable, str(PLOT), f"{tmp_path / 'towel'}:grasp", "--out", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 1
    assert "no run has both modes" in r.stderr
    assert not out.exists()


def test_an_argument_without_a_task_is_refused(tmp_path: Path) -> None:
    r = subprocess.run([sys.executable, str(PLOT), str(tmp_path), "--out", str(tmp_path / "x.png")],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert "expected DIR:TASK" in r.stderr


def test_no_columns_is_refused(tmp_path: Path) -> None:
    write_square(tmp_path / "towel" / "grasp_pseudo" / "final.obj", 0.0)
    write_square(tmp_path / "towel" / "grasp_robot" / "final.obj", 0.0)
    r = subprocess.run([sys.executable, str(PLOT), f"{tmp_path / 'towel'}:grasp", "--out", str(tmp_path / "x.png"),
                        "--columns", "0"], capture_output=True, text=True)
    assert r.returncode == 2
    assert "--columns must be at least 1" in r.stderr
