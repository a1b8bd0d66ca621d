#!/usr/bin/env python3
"""The service demo: a T-shirt Fold run as a job on a local gd-server, through the Python client.

1. A capture to compare with: RGBench's layout, made by `gd synth-capture` from a finer reference
   run (point noise, dropouts, a tilted camera, a camera delay), placed under the server's
   capture root. (Pass --capture NAME to use a real RGBench capture copied there instead.)
2. gd-server is started on a free loopback port (CPU backend, --plots) by Client.spawn.
3. The Fold is submitted as a job; its progress is shown as it runs; the report (summary, RGBench's
   metrics.csv, the paper's baselines beside ours, PNG plots) is fetched and written to OUT/report.
4. The server is stopped (SIGTERM: it drains and exits 0).
"""
import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

from garmentdynamics import Client

METRICS = ["cd_l1_s2r", "cd_l1_r2s", "cd_l2_s2r", "hd_s2r", "hd_r2s", "z_err", "sim_stab"]


def log(msg):
    print(f"[demo] {msg}", file=sys.stderr, flush=True)


def main():
    root = Path(__file__).resolve().parents[1]
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default=str(root / "out" / "demo"))
    p.add_argument("--build", default=str(root / "build"))
    p.add_argument("--garment", default="tshirt")
    p.add_argument("--material", default="cotton")
    p.add_argument("--vertices", type=int, default=500, help="vertices of the simulated garment")
    p.add_argument("--reference-vertices", type=int, default=700, help="vertices of the synthetic capture's reference")
    p.add_argument("--time-scale", type=float, default=0.5, help="speed factor of the fold's slow parts")
    p.add_argument("--capture", default="", help="a capture directory name under OUT/server/captures (default: synthesize one)")
    p.add_argument("--threads", type=int, default=0)
    a = p.parse_args()

    out = Path(a.out).resolve()
    data_dir = out / "server"
    captures = data_dir / "captures"
    captures.mkdir(parents=True, exist_ok=True)
    bin_dir = Path(a.build) / "bin"

    capture = a.capture
    if not capture:
        capture = f"synthetic_{a.garment}_fold"
        if not (captures / capture / "capture.json").is_file():
            log(f"synthesizing a capture ({a.garment} fold, {a.reference_vertices} vertices) into {captures / capture}")
            subprocess.run([str(bin_dir / "gd"), "synth-capture", "--garment", a.garment, "--material", a.material,
                            "--task", "fold", "--vertices", str(a.reference_vertices), "--dt", "0.01",
                            "--time-scale", str(a.time_scale), "--fps", "4", "--out", str(captures / capture)],
                           check=True)

    extra = ["--plots", "--backend", "cpu"]
    log(f"starting gd-server (data dir {data_dir})")
    with Client.spawn(data_dir=str(data_dir), threads=a.threads or None, server_bin=str(bin_dir / "gd-server"),
                      extra_args=extra) as client:
        info = client.server_info()
        log(f"server {info.get('version', '?')} backend {info.get('backend', '?')}, {info.get('threads', '?')} threads")
        t0 = time.monotonic()
        job = client.submit_job(garment=a.garment, material=a.material, task="fold", vertices=a.vertices,
                                capture=capture, time_scale=a.time_scale, dt=0.01, icp=True,
                                label="scripts/demo")
        log(f"job {job} submitted; waiting for its report")
        report = client.wait_report(job, progress=True, include_files=True)
        wall = time.monotonic() - t0

    status = report["job"]["status"]
    summary = report["summary"] or {}
    report_dir = out / "report"
    report_dir.mkdir(parents=True, exist_ok=True)
    for name, data in report["files"].items():
        dest = report_dir / name
        dest.parent.mkdir(parents=True, exist_ok=True)
        dest.write_bytes(data)
    (report_dir / "job.json").write_text(json.dumps(report["job"], indent=2))

    print()
    print(f"Job {job}: {status} in {wall:.0f} s ({summary.get('vertices', '?')} vertices, "
          f"{summary.get('steps', '?')} steps, {summary.get('ms_per_step', float('nan')):.0f} ms/step, "
          f"max intersecting pairs {summary.get('intersecting_pairs_max', '?')})")
    if status != "SUCCEEDED":
        print(f"  {report['job'].get('message', '')}")
        return 1
    print(f"Sim-to-real metrics over {summary.get('frames_in_window', '?')} capture frames (mean, m):")
    for m in METRICS:
        if m in summary:
            print(f"  {m:<10} {summary[m]:.4f}")
    pngs = sorted(str(report_dir / n) for n in report["files"] if n.endswith(".png"))
    print(f"Report in {report_dir}: " + ", ".join(sorted(report["files"])))
    if pngs:
        print("Plots: " + ", ".join(pngs))
    return 0


if __name__ == "__main__":
    sys.exit(main())
