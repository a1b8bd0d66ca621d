"""docs/rgbench.md stays true: its section 4 commands and its section 3 Python (RGBench's call
sequence through the adapter, on the capture section 4 makes) run here as written."""

import csv
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PAGE = REPO / "docs" / "rgbench.md"


def blocks(lang: str, section: str) -> list:
    """The ```lang blocks of the page's section whose heading starts with `section`."""
    text = PAGE.read_text()
    parts = re.split(r"^## ", text, flags=re.M)
    body = next(p for p in parts if p.startswith(section))
    return re.findall(rf"```{lang}\n(.*?)```", body, flags=re.S)


def test_section_4_and_3_run_as_written(server_bin, tmp_path):
    bin_dir = Path(server_bin).resolve().parent
    if not (bin_dir / "gd").exists():
        pytest.skip(f"no gd beside {server_bin}")
    # Section 4: gd synth-capture, then gd run with the capture (build/bin/ of this checkout).
    for line in blocks("bash", "4.")[0].strip().splitlines():
        args = line.split()
        assert args[0] == "build/bin/gd", line
        r = subprocess.run([str(bin_dir / "gd")] + args[1:], cwd=tmp_path, capture_output=True, text=True,
                           timeout=600)
        assert r.returncode == 0, f"{line}\n{r.stderr[-2000:]}"
    with (tmp_path / "out/eval/metrics.csv").open() as f:
        rows = list(csv.reader(f))
    assert "chamfer_l1_real_to_sim" in rows[0]
    mean = dict(zip(rows[0], rows[-2]))  # the unlabelled mean row, RGBench's iloc[-2]
    assert mean["sim_time"] == "" and 0 < float(mean["chamfer_l1_real_to_sim"]) < 0.1
    # Section 3: the Python, with the adapter spawning this build's gd-server.
    code = blocks("python", "3.")[0]
    env = dict(os.environ, GD_SERVER_BIN=str(server_bin))
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600,
                       env=env)
    assert r.returncode == 0, r.stderr[-3000:]
    cds = [float(m) for m in re.findall(r"cd_l1_r2s = ([0-9.]+) m", r.stdout)]
    assert len(cds) >= 5, r.stdout
    assert all(math.isfinite(c) and 0 < c < 0.05 for c in cds), r.stdout  # gd run: 0.019 m
