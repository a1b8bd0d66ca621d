#!/usr/bin/env python3
"""One self-contained HTML page of a run's report: REPORT_DIR/report.html.

    report_html.py REPORT_DIR

Reads what `gd run` (or a job, fetched by `gd report JOB --out DIR`) wrote there: summary.json,
metrics_summary.json and comparison.csv of a capture run, and the pictures (animation.gif,
capture_animation.gif, metrics_over_time.png, frames.png), which are embedded as data URIs, so
the page can be mailed or attached as one file. `gd run` writes it with its plots; `gd report JOB --out DIR --open`
writes it for a job and opens it.
"""

from __future__ import annotations

import base64
import csv
import html
import json
import sys
from pathlib import Path

PICTURES = [("animation.gif", "The run (front and top views)"),
            ("capture_animation.gif", "Simulation and real capture side by side"),
            ("metrics_over_time.png", "Sim-to-real metrics over time"),
            ("frames.png", "Simulated and real point clouds")]
METRICS = [("cd_l1_s2r", "CD L1 sim→real"), ("cd_l2_s2r", "CD L2 sim→real"), ("cd_l1_r2s", "CD L1 real→sim"),
           ("hd_s2r", "HD sim→real"), ("hd_r2s", "HD real→sim"), ("sim_stab", "sim stability"),
           ("z_err", "z mean error")]

STYLE = """
body { font-family: sans-serif; margin: 2em auto; max-width: 1100px; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em; }
td, th { border: 1px solid #ccc; padding: 3px 8px; text-align: left; font-size: 14px; }
th { background: #f2f2f2; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
img { max-width: 100%; border: 1px solid #ddd; }
.bad { color: #b00; font-weight: bold; }
"""


def fmt(v) -> str:
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, (list, dict)):
        return html.escape(json.dumps(v)[:200])
    return html.escape(str(v))


def table(rows, header=None) -> str:
    out = ["<table>"]
    if header:
        out.append("<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in header) + "</tr>")
    for r in rows:
        cells = []
        for v in r:
            cls = ' class="num"' if isinstance(v, (int, float)) and not isinstance(v, bool) else ""
            cells.append(f"<td{cls}>{fmt(v)}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def picture(path: Path) -> str:
    mime = {"gif": "image/gif", "png": "image/png"}[path.suffix[1:]]
    data = base64.b64encode(path.read_bytes()).decode()
    return f'<img src="data:{mime};base64,{data}" alt="{html.escape(path.name)}">'


def grip_news(arms: dict, events: list) -> list:
    """Sentences on the hands that did not hold what they grasped (summary.json's robot.arms)."""
    out = []
    for a, st in arms.items():
        closed = [e["t"] for e in events if e.get("arm") == a and e.get("grasp")]
        if st.get("held_at") is None and closed:
            missed = st.get("missed_at")
            why = f": its fingers stopped on little cloth or none at {missed:.3f} s" if missed is not None else ""
            out.append(f"The {a} hand, closed at {closed[0]:.3f} s, never got hold of the cloth{why}.")
        elif st.get("lost_at") is not None:
            out.append(f"The {a} hand let go of the cloth at {st['lost_at']:.3f} s.")
    return out


def build(d: Path) -> str:
    s = json.loads((d / "summary.json").read_text()) if (d / "summary.json").exists() else {}
    title = " ".join(str(s.get(k, "")) for k in ("garment", "task")).strip() or d.name
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
             f"<style>{STYLE}</style></head><body>",
             f"<h1>{html.escape(title)} <small>({html.escape(str(s.get('mode', '')))} mode)</small></h1>"]
    if s.get("failed"):
        parts.append(f"<p class='bad'>The simulation failed: {html.escape(str(s.get('failure', '')))}</p>")
    run_keys = [("garment_source", "garment"), ("material", "material"), ("vertices", "vertices"),
                ("triangles", "triangles"), ("dt", "dt (s)"), ("sim_seconds", "simulated (s)"), ("steps", "steps"),
                ("wall_seconds", "wall (s)"), ("ms_per_step", "ms per step"), ("newton_per_step", "Newton per step"),
                ("pcg_per_step", "PCG per step"), ("converged_fraction", "steps converged"),
                ("intersecting_pairs_max", "intersecting pairs (max)"), ("untangle_runs", "untangling runs"),
                ("backend", "backend")]
    parts.append("<h2>Run</h2>" + table([(label, s[k]) for k, label in run_keys if k in s]))
    if isinstance(s.get("final"), dict):
        ini, fin = s.get("initial", {}), s["final"]
        keys = [k for k in fin if isinstance(fin[k], (int, float))]
        parts.append("<h2>Shape</h2>" + table([(k, ini.get(k, ""), fin[k]) for k in keys], ["", "initial", "final"]))
    if any(k in s for k, _ in METRICS):
        std = s.get("metrics_std", {})
        parts.append("<h2>Sim-to-real metrics (m, means over the calculate window)</h2>"
                     + table([(label, s[k], std.get(k, "")) for k, label in METRICS if k in s], ["metric", "mean", "std"]))
    comp = d / "comparison.csv"
    if comp.exists():
        with comp.open() as f:
            rows = list(csv.reader(f))
        if rows:
            parts.append("<h2>Against the paper's baselines (RGBench, Hu et al.)</h2>" + table(rows[1:], rows[0]))
    if isinstance(s.get("robot"), dict):
        r = s["robot"]
        parts.append("<h2>Robot arms</h2>" + table([(k, v) for k, v in r.items() if k != "arms"]))
        arms = r.get("arms")
        if isinstance(arms, dict):
            parts.append(table([(a, *(fmt(v) for v in st.values())) for a, st in arms.items()],
                               ["arm", *next(iter(arms.values())).keys()]))
            parts.extend(f"<p class='bad'>{html.escape(line)}</p>" for line in grip_news(arms, s.get("grasp_events", [])))
    if isinstance(s.get("stage_ms_per_step"), dict):
        st = sorted(s["stage_ms_per_step"].items(), key=lambda kv: -kv[1])
        parts.append("<h2>Where a step's time goes (ms per step)</h2>" + table(st, ["stage", "ms"]))
    for name, caption in PICTURES:
        if (d / name).exists():
            parts.append(f"<h2>{html.escape(caption)}</h2>{picture(d / name)}")
    files = sorted(p.name for p in d.iterdir() if p.is_file() and p.name != "report.html")
    parts.append("<h2>Files</h2><p>" + ", ".join(html.escape(f) for f in files) + "</p>")
    parts.append("</body></html>")
    return "\n".join(parts)


def main() -> int:
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    d = Path(sys.argv[1])
    if not d.is_dir():
        print(f"report_html: no directory {d}", file=sys.stderr)
        return 1
    out = d / "report.html"
    out.write_text(build(d), encoding="utf-8")
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
