"""bench/plot_bench.py on gd-bench --json arrays written by hand: the PNG and the table of every
case, a log-wrapped array read as it is, and a clear exit without drape or fold cases."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from gd_bench_path import ROOT

SCRIPT = ROOT / "bench" / "plot_bench.py"


def case(name: str, ms: float, backend: str = "cuda") -> dict:
    return {"case": name, "vertices": int(name.split("/")[1]), "ms_per_step": ms, "backend": backend,
            "newton_iters": 1.0, "pcg_iters": 30.0, "converged": 1.0, "deterministic": False,
            "stage_ms": {"pcg": 0.6 * ms, "assembly": 0.3 * ms, "stopping": 0.1 * ms}}


def test_png_and_table(tmp_path: Path):
    gpu = tmp_path / "gpu.json"
    gpu.write_text(json.dumps([case("drape/5000", 10.0), case("drape/20000", 14.0), case("fold/5000", 30.0)]))
    cpu = tmp_path / "cpu.log"  # an array wrapped in a log's '==' lines
    cpu.write_text("== bench (limit 100s)\n" + json.dumps([case("fold/5000", 100.0, "cpu")]) + "\n== bench: rc=0\n")
    png = tmp_path / "out.png"
    r = subprocess.run([sys.executable, str(SCRIPT), str(gpu), str(cpu), "--label", "cpu.log=CPU 16", "--png", str(png)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = [line.split() for line in r.stdout.splitlines()[1:]]
    assert ["cuda", "drape/20000", "20000", "14.00"] == rows[1][:4]
    assert any(row[:3] == ["CPU", "16", "fold/5000"] for row in rows)


def test_no_cases_is_a_clear_error(tmp_path: Path):
    f = tmp_path / "svc.json"
    f.write_text(json.dumps([{"case": "service/16", "vertices": 5000, "ms_per_step": 1.0, "backend": "cpu"}]))
    r = subprocess.run([sys.executable, str(SCRIPT), str(f), "--png", str(tmp_path / "x.png")], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode != 0 and "no drape/N or fold/N cases" in r.stderr
