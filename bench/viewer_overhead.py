#!/usr/bin/env python3
"""What watching costs: the same scenes stepped through the service with and without a live viewer
attached (docs/viewer.md), interleaved rounds in one run, on one server.

    build/venv/bin/python bench/viewer_overhead.py [--garment tshirt --vertices 2000 --scenes 4
        --calls 20 --substeps 5 --rounds 3 --every 1 --browser]
    build/venv/bin/python bench/viewer_overhead.py --job [--garment tshirt --vertices 2000
        --time-scale 0.3 --rounds 3 --every 1]

With --job, each round runs the same Grasp job twice on the server (one job worker): first alone,
then with `python -m garmentdynamics.viewer --job ID` subscribed before it starts (it is queued
behind the first), and compares the jobs' own ms_per_step (their stepping time, set-up excluded).

Each round steps the scenes `calls` times (`substeps` each) and times the calls; "viewer" rounds
run `python -m garmentdynamics.viewer` on the scenes in a separate process first (subscribed
with StreamFrames, a frame every `every` steps), and with --browser also a headless Chromium on
its page (on this machine the browser competes for the same cores; a user's browser runs on
theirs). Prints the wall time per step of the batch (all scenes stepped together) for both and
their ratio, and writes them as JSON with --json.
"""

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

from garmentdynamics import Client, find_server_binary  # the installed client (scripts/build: build/venv)
from garmentdynamics.viewer import find_chromium


def step_round(client, ids, calls, substeps):
    """ms per step of the whole batch (one call steps every scene `substeps` times)."""
    t0 = time.perf_counter()
    for _ in range(calls):
        client.step(ids, substeps=substeps)
    return 1e3 * (time.perf_counter() - t0) / (calls * substeps)


def start_viewer(target, ids, every, port, browser):
    procs = [subprocess.Popen([sys.executable, "-m", "garmentdynamics.viewer", "--server", target, "--port", str(port),
                               "--every", str(every)] + [a for i in ids for a in ("--scene", i)],
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)]
    seen = []
    for line in procs[0].stdout:  # viser's banner, then "viewing N scene(s) at URL": the page is up
        seen.append(line)
        if line.startswith("viewing"):
            break
    else:
        raise RuntimeError(f"the viewer did not start: {''.join(seen)[-500:]!r}")
    if browser:
        exe = find_chromium()
        if exe is None:
            raise RuntimeError("--browser needs Chromium")
        procs.append(subprocess.Popen([exe, "--headless", "--no-sandbox", "--use-angle=swiftshader",
                                       "--enable-unsafe-swiftshader", "--remote-debugging-port=0",
                                       f"http://127.0.0.1:{port}/"],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        time.sleep(5)  # the page loads and connects
    return procs


def start_job_viewer(target, job, every, port):
    """The viewer on a queued job: it waits for the job's first step, then serves its page."""
    return subprocess.Popen([sys.executable, "-m", "garmentdynamics.viewer", "--server", target, "--port", str(port),
                             "--every", str(every), "--job", job],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, text=True)


def job_rounds(client, args):
    """ms per step of the same job without and with a viewer, interleaved."""
    spec = dict(garment=args.garment, vertices=args.vertices, task="grasp", time_scale=args.time_scale)
    plain, viewed = [], []
    for r in range(args.rounds):
        alone = client.submit_job(label="alone", **spec)
        watched = client.submit_job(label="watched", **spec)  # queued behind `alone`
        viewer = start_job_viewer(client.target, watched, args.every, args.port)
        try:
            a = client.wait_report(alone, progress=False)["summary"]
            b = client.wait_report(watched, progress=False)["summary"]
        finally:
            viewer.terminate()
            viewer.wait(timeout=30)
        plain.append(a["ms_per_step"])
        viewed.append(b["ms_per_step"])
        print(f"round {r + 1}: the job took {plain[-1]:.2f} ms per step alone, {viewed[-1]:.2f} with a viewer "
              f"({b['steps']} steps)", flush=True)
    return plain, viewed


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--garment", default="tshirt")
    p.add_argument("--vertices", type=int, default=2000)
    p.add_argument("--scenes", type=int, default=4)
    p.add_argument("--calls", type=int, default=20)
    p.add_argument("--substeps", type=int, default=5)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--every", type=int, default=1)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--port", type=int, default=8095)
    p.add_argument("--browser", action="store_true", help="also a headless Chromium on the viewer's page")
    p.add_argument("--job", action="store_true", help="a job watched while it runs instead of stepped scenes")
    p.add_argument("--time-scale", type=float, default=0.3, help="--job: the Grasp's time scale")
    p.add_argument("--json", help="write the numbers to this file")
    args = p.parse_args()
    import tempfile
    with tempfile.TemporaryDirectory() as data, \
            Client.spawn(server_bin=find_server_binary(), data_dir=data, threads=args.threads) as client:
        if args.job:
            plain, viewed = job_rounds(client, args)
            a, b = statistics.median(plain), statistics.median(viewed)
            out = {"job": True, "garment": args.garment, "vertices": args.vertices, "every": args.every,
                   "ms_per_step_plain": plain, "ms_per_step_viewed": viewed, "median_plain": a,
                   "median_viewed": b, "slowdown": b / a}
            print(f"median: {a:.2f} -> {b:.2f} ms per step of the job with a viewer attached ({100 * (b / a - 1):+.1f}%)")
            if args.json:
                Path(args.json).write_text(json.dumps(out, indent=1) + "\n")
            return
        ids = client.create_scenes(garment=args.garment, vertices=args.vertices, count=args.scenes)
        for _ in range(args.calls):  # warm-up: the first steps settle the garments
            client.step(ids, substeps=args.substeps)
        plain, viewed = [], []
        for r in range(args.rounds):
            plain.append(step_round(client, ids, args.calls, args.substeps))
            procs = start_viewer(client.target, ids, args.every, args.port, args.browser)
            try:
                viewed.append(step_round(client, ids, args.calls, args.substeps))
            finally:
                for proc in procs:
                    proc.terminate()
                for proc in procs:
                    proc.wait(timeout=30)
            print(f"round {r + 1}: {plain[-1]:.2f} ms per step of the {args.scenes} scenes without a viewer, "
                  f"{viewed[-1]:.2f} with", flush=True)
        a, b = statistics.median(plain), statistics.median(viewed)
        out = {"garment": args.garment, "vertices": args.vertices, "scenes": args.scenes, "every": args.every,
               "browser": args.browser, "ms_per_step_plain": plain, "ms_per_step_viewed": viewed,
               "median_plain": a, "median_viewed": b, "slowdown": b / a}
        print(f"median: {a:.2f} -> {b:.2f} ms per step of the {args.scenes} scenes with a viewer attached "
              f"({100 * (b / a - 1):+.1f}%)")
        if args.json:
            Path(args.json).write_text(json.dumps(out, indent=1) + "\n")
        client.destroy(ids)


if __name__ == "__main__":
    main()
