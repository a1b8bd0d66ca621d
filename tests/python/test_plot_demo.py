"""Tests of the demo tools: scripts/plot_demo.py on synthetic data, and a short gd-demo run."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PLOT = ROOT / "scripts" / "plot_demo.py"
BUILD = Path(os.environ.get("GD_BUILD_DIR", ROOT / "build"))
GD_DEMO = BUILD / "bin" / "gd-demo"

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def write_synthetic_timeseries(path: Path, n: int = 81, dt: float = 0.005) -> None:
    lines = ["t,kinetic,stretch,bending,gravity,total,max_strain,newton_iters,pcg_iters,ms"]
    for k in range(n):
        t = k * dt
        kin = 0.05 * math.sin(8 * t) ** 2 * math.exp(-t)
        stretch = 0.01 * (1 - math.exp(-5 * t))
        bend = 1e-4 * (1 - math.exp(-3 * t))
        grav = 1.2 - 0.06 * (1 - math.exp(-4 * t))
        total = kin + stretch + bend + grav
        strain = 0.02 * (1 - math.exp(-6 * t))
        lines.append(f"{t:.6f},{kin:.10e},{stretch:.10e},{bend:.10e},{grav:.10e},{total:.10e},{strain:.8e},3,40,12.5")
    path.write_text("\n".join(lines) + "\n")


def test_plot_demo_writes_png(tmp_path: Path) -> None:
    write_synthetic_timeseries(tmp_path / "timeseries.csv")
    r = subprocess.run([sys.executable, str(PLOT), str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    png = tmp_path / "demo.png"
    assert png.is_file()
    data = png.read_bytes()
    assert data[:8] == PNG_MAGIC
    assert len(data) > 10_000  # two panels of curves with labels, not an empty canvas


def test_plot_demo_reports_missing_csv(tmp_path: Path) -> None:
    r = subprocess.run([sys.executable, str(PLOT), str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert r.returncode != 0
    assert "timeseries.csv" in r.stderr
    assert not (tmp_path / "demo.png").exists()


def count_vertex_lines(path: Path) -> int:
    with path.open() as f:
        return sum(1 for line in f if line.startswith("v "))


def test_gd_demo_short_run(tmp_path: Path) -> None:
    if not GD_DEMO.is_file():
        pytest.skip(f"{GD_DEMO} is not built")
    out = tmp_path / "demo"
    r = subprocess.run(
        [str(GD_DEMO), "--out", str(out), "--seconds", "0.05", "--spacing", "0.05"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout + r.stderr

    summary = json.loads((out / "summary.json").read_text())
    for key in (
        "vertices",
        "steps",
        "seconds_simulated",
        "wall_seconds",
        "ms_per_step",
        "max_strain_final",
        "energy_initial",
        "energy_final",
        "energy_increase_steps",
    ):
        assert key in summary, key
    assert summary["vertices"] > 0
    assert summary["steps"] == 10  # 0.05 s at dt = 1/200
    assert summary["seconds_simulated"] == pytest.approx(0.05)
    assert summary["wall_seconds"] > 0
    assert summary["ms_per_step"] > 0
    assert math.isfinite(summary["max_strain_final"]) and summary["max_strain_final"] >= 0
    assert math.isfinite(summary["energy_initial"]) and math.isfinite(summary["energy_final"])
    # Pinned corners do no work: a dissipative integrator never gains energy.
    assert summary["energy_final"] <= summary["energy_initial"]
    assert summary["energy_increase_steps"] == 0

    n_initial = count_vertex_lines(out / "initial.obj")
    assert n_initial == summary["vertices"]
    assert count_vertex_lines(out / "final.obj") == n_initial

    rows = (out / "timeseries.csv").read_text().strip().splitlines()
    assert rows[0] == "t,kinetic,stretch,bending,gravity,total,max_strain,newton_iters,pcg_iters,ms"
    assert len(rows) == 1 + 1 + summary["steps"]  # header, t = 0, one per step
