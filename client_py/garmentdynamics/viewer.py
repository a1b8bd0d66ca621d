"""A live 3D viewer of a server's scenes in a web page (docs/viewer.md).

    python -m garmentdynamics.viewer --server 127.0.0.1:50051 --scene s-1234 [--scene s-5678 ...]
    python -m garmentdynamics.viewer --server 127.0.0.1:50051 --scene s-1234 --screenshot out.png
    python -m garmentdynamics.viewer --server 127.0.0.1:50051 --job j-5678

The viewer subscribes to the scenes' frames (StreamFrames without steps of its own: it watches
whatever steps them, an RL loop or a benchmark), or to a queued or running job's scene as the
job steps it (from its first step on; the page opens once that step is made), and draws them with viser, which serves the page
from this process (open the printed URL; on a remote machine forward the port): the garments in a
grid, the table, each arm's tool (green open, red closed), robot mode's arms (their chains from
base to hand, by forward kinematics) and the kinematic colliders (robot mode's finger pads), a time slider over the frames received, and per-scene statistics. Viewing
costs the server a snapshot per frame sent; `every` thins the frames.

viser (PyPI, `pip install garmentdynamics[viewer]`) was chosen over rerun-sdk because it serves
a plain web page from the local Python process with no separate viewer application, scene
objects are updated in place (a mesh's vertices per frame), and its GUI widgets (slider,
checkbox, markdown) live in the same page. `--screenshot` renders that page in headless Chromium
(Debian's `chromium`, software WebGL) and writes a PNG, for CI, reports and remote machines.

In code:

    from garmentdynamics import Client
    from garmentdynamics.viewer import SceneViewer, screenshot
    with SceneViewer(Client("127.0.0.1:50051"), ["s-1234"], port=8080) as v:
        v.wait_for_frames(1)
        screenshot(v.url, "scene.png")
"""

from __future__ import annotations

import argparse
import bisect
import math
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections import deque
from pathlib import Path
from typing import Dict, List, Optional, Sequence

import numpy as np

import grpc

from ._proto import pb
from .client import Client, SceneState, _scene_info_to_dict

CLOTH_COLOR = (214, 72, 48)       # garments: a saturated red-orange, easy to find in a screenshot
TABLE_COLOR = (190, 190, 196)
OPEN_COLOR = (40, 170, 80)
CLOSED_COLOR = (150, 40, 190)   # purple: not the garment's red
PAD_COLOR = (70, 90, 200)
ARM_COLOR = (60, 60, 70)          # robot mode: the arms' chains
MARGIN = 0.25                     # m between neighbouring scenes of the grid


def _viser():
    try:
        import viser  # noqa: F401
    except ImportError as exc:  # pragma: no cover - only without the extra
        raise ImportError("the viewer needs viser: pip install 'garmentdynamics[viewer]' (or pip install viser)") from exc
    return viser


def find_chromium() -> Optional[str]:
    """The path of a Chromium or Chrome binary, or None."""
    for name in ("chromium", "chromium-browser", "chromium-headless-shell", "google-chrome", "google-chrome-stable"):
        path = shutil.which(name)
        if path:
            return path
    return None


def screenshot(url: str, path, width: int = 1280, height: int = 800, wait_s: float = 8.0,
               chromium: Optional[str] = None, timeout_s: float = 120.0, attempts: int = 3) -> Path:
    """Renders `url` in headless Chromium (software WebGL) after `wait_s` seconds of page time
    and writes a PNG to `path`. Chromium's page clock runs ahead of the page's websocket, so a
    picture of one colour (the page had drawn nothing yet) is taken again, with twice the wait,
    up to `attempts` times. Raises RuntimeError when no Chromium is installed (Debian:
    apt-get install chromium) or it writes nothing."""
    exe = chromium or find_chromium()
    if exe is None:
        raise RuntimeError("no Chromium to take screenshots with: install it (Debian: apt-get install chromium)")
    path = Path(path).resolve()
    path.parent.mkdir(parents=True, exist_ok=True)
    for attempt in range(max(1, int(attempts))):
        if path.exists():
            path.unlink()
        with tempfile.TemporaryDirectory(prefix="gd-chromium-") as profile:
            cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
                   "--enable-unsafe-swiftshader", "--hide-scrollbars", "--mute-audio", "--no-first-run",
                   f"--user-data-dir={profile}", f"--window-size={int(width)},{int(height)}",
                   f"--virtual-time-budget={int(wait_s * 1000 * 2 ** attempt)}", f"--screenshot={path}", url]
            proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=timeout_s, check=False)
        if not path.exists() or path.stat().st_size == 0:
            tail = proc.stderr.decode(errors="replace")[-2000:]
            raise RuntimeError(f"Chromium wrote no screenshot of {url} (exit {proc.returncode}): {tail}")
        if not _one_colour(path):
            break
    return path


def _one_colour(png: Path) -> bool:
    """True when every pixel of the PNG has the same colour (a page that has drawn nothing)."""
    import imageio.v3 as iio  # viser's dependency
    img = np.asarray(iio.imread(png))
    flat = img.reshape(-1, img.shape[-1]) if img.ndim == 3 else img.reshape(-1, 1)
    return bool((flat == flat[0]).all())


class _SceneTrack:
    """One scene's received frames and its objects in the page."""

    def __init__(self, scene_id: str, info: dict, offset: np.ndarray, keep: int):
        self.scene_id = scene_id
        self.info = info
        self.offset = offset
        self.frames: deque = deque(maxlen=keep)   # (time, SceneState)
        self.times: deque = deque(maxlen=keep)
        self.mesh = None
        self.arms: Dict[str, object] = {}
        self.links: Dict[str, object] = {}   # robot mode: each arm's chain as line segments
        self.colliders: List[object] = []

    def frame_at(self, t: float) -> Optional[SceneState]:
        """The latest frame at or before scene time t (the first one before them all)."""
        if not self.frames:
            return None
        times = list(self.times)
        k = max(0, bisect.bisect_right(times, t) - 1)
        return self.frames[k][1]


class SceneViewer:
    """Watches scenes on a server and draws them in a viser page (see the module docstring).

    client: a Client of the server (its token sees the scenes); scene_ids: the scenes, drawn in a
    grid in this order, or job_id: a queued or running job, whose scene is drawn from its first
    step on (the constructor waits for that step, at most first_frame_timeout s); host/port: where the page is served (port 0: a free one); every: a frame
    every k-th step of a scene; keep_frames: frames kept per scene for the time slider; max_fps:
    how often the page is updated at most (frames arriving faster are kept for the slider but
    drawn only at this rate, so a browser on the server's machine does not take its cores)."""

    def __init__(self, client: Client, scene_ids: Sequence[str] = (), host: str = "127.0.0.1", port: int = 8080,
                 every: int = 1, keep_frames: int = 600, max_fps: float = 10.0, job_id: Optional[str] = None,
                 first_frame_timeout: float = 600.0):
        viser = _viser()
        if bool(scene_ids) == bool(job_id):
            raise ValueError("give scene ids or a job id (one of them)")
        self.client = client
        self.job_id = str(job_id) if job_id else None
        self._call = None
        try:
            if self.job_id:
                self.scene_ids = [self.job_id]
                infos, first = self._open_job(int(every), first_frame_timeout)
            else:
                self.scene_ids = [str(s) for s in scene_ids]
                infos = client.describe(self.scene_ids)
                # Subscribe before the first states are read, and wait for the server's initial
                # metadata: it is sent once the subscription is in place, so every step another
                # client makes after the constructor returns reaches the page.
                self._call = client._stub.StreamFrames(
                    pb.StreamFramesRequest(scene_ids=self.scene_ids, every=int(every), steps=0),
                    timeout=client.stream_timeout)
                self._call.initial_metadata()
                first = client.get_state(self.scene_ids)
            if port == 0:
                port = _free_port(host)
            self.host, self.port = host, int(port)
            self.server = viser.ViserServer(host=host, port=self.port, verbose=False)
            self._lock = threading.Lock()
            self._tracks = self._layout(infos, keep_frames)
            self._frames_received = 0
            self._stop = threading.Event()
            self._error: Optional[BaseException] = None
            self._build_page(infos)
            for track, state in zip(self._tracks, first):
                self._receive(track, state)
            self._redraw()
            self._dirty = threading.Event()
            self._period = 1.0 / max(0.1, float(max_fps))
            self._thread = threading.Thread(target=self._listen, name="gd-viewer", daemon=True)
            self._thread.start()
            self._painter = threading.Thread(target=self._paint, name="gd-viewer-paint", daemon=True)
            self._painter.start()
        except BaseException:
            if self._call is not None:  # the subscription, made above
                self._call.cancel()
            raise

    # --- public --------------------------------------------------------------------------------
    @property
    def url(self) -> str:
        host = "127.0.0.1" if self.host in ("0.0.0.0", "") else self.host
        return f"http://{host}:{self.port}/"

    @property
    def frames_received(self) -> int:
        """Frames received from the stream (not counting the first states)."""
        return self._frames_received

    def wait_for_frames(self, n: int, timeout: float = 60.0) -> bool:
        """Waits until n frames have arrived; False on timeout or when the stream ended."""
        end = time.monotonic() + timeout
        while self._frames_received < n and time.monotonic() < end and self._thread.is_alive():
            time.sleep(0.05)
        return self._frames_received >= n

    def close(self) -> None:
        self._stop.set()
        if self._call is not None:
            self._call.cancel()
        self._dirty.set()
        self._thread.join(timeout=5)
        self._painter.join(timeout=5)
        self.server.stop()

    def __enter__(self) -> "SceneViewer":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # --- page ----------------------------------------------------------------------------------
    def _layout(self, infos: List[dict], keep: int) -> List[_SceneTrack]:
        n = len(infos)
        cols = max(1, math.ceil(math.sqrt(n)))
        extents = np.array([np.ptp(np.asarray(i["rest_positions"], dtype=np.float64)[:, :2], axis=0) for i in infos])
        dx, dy = extents.max(axis=0) + MARGIN
        tracks = []
        for k, (sid, info) in enumerate(zip(self.scene_ids, infos)):
            row, col = divmod(k, cols)
            tracks.append(_SceneTrack(sid, info, np.array([col * dx, -row * dy, 0.0]), keep))
        return tracks

    def _build_page(self, infos: List[dict]) -> None:
        s = self.server
        s.scene.set_up_direction("+z")
        # Fixed lights rather than the default environment map, which the page decodes in the
        # background: a picture taken before it is ready came out washed out.
        s.scene.configure_environment_map(hdri=None)
        s.scene.configure_default_lights(enabled=False)
        s.scene.add_light_ambient("/light/ambient", intensity=0.9)
        s.scene.add_light_directional("/light/sun", intensity=1.6, position=(0.3, -0.5, 2.0))
        lo = np.min([t.offset + np.min(i["rest_positions"], axis=0) for t, i in zip(self._tracks, infos)], axis=0)
        hi = np.max([t.offset + np.max(i["rest_positions"], axis=0) for t, i in zip(self._tracks, infos)], axis=0)
        heights = [i["table_height"] for i in infos if i.get("table_height") is not None]
        if heights:
            size = (hi - lo)[:2] + 0.6
            centre = 0.5 * (hi + lo)
            s.scene.add_box("/table", color=TABLE_COLOR, dimensions=(size[0], size[1], 0.01),
                            position=(centre[0], centre[1], min(heights) - 0.005 - 1e-4))
        for t, info in zip(self._tracks, infos):
            tris = np.asarray(info["triangles"], dtype=np.uint32)
            verts = np.asarray(info["rest_positions"], dtype=np.float32) + t.offset.astype(np.float32)
            t.mesh = s.scene.add_mesh_simple(f"/{t.scene_id}/cloth", verts, tris, color=CLOTH_COLOR, side="double")
            s.scene.add_label(f"/{t.scene_id}/label", _short(t.scene_id),
                              position=(float(verts[:, 0].min()), float(verts[:, 1].max()), 0.1))
            for arm in ("left", "right"):
                t.arms[arm] = s.scene.add_icosphere(f"/{t.scene_id}/{arm}_tool", radius=0.015, color=OPEN_COLOR)
        cam = 0.5 * (hi + lo)
        span = float(np.max(hi - lo)) + 0.5

        @s.on_client_connect
        def _(client) -> None:  # a fresh page looks at the whole grid from the front, above
            client.camera.position = (cam[0] - 1.1 * span, cam[1] - 0.2 * span, cam[2] + 0.9 * span)
            client.camera.look_at = tuple(cam)

        with s.gui.add_folder("Frames"):
            self._live = s.gui.add_checkbox("Live", initial_value=True, hint="follow the newest frame")
            self._slider = s.gui.add_slider("Frame", min=0, max=1, step=1, initial_value=0,
                                            hint="frames received (of the first scene); untick Live to scrub")
            self._time_text = s.gui.add_text("Scene time (s)", initial_value="0", disabled=True)
        self._stats = s.gui.add_markdown("waiting for frames ...")

        @self._slider.on_update
        def _(_event) -> None:
            if not self._live.value:
                self._redraw(index=int(self._slider.value))

        @self._live.on_update
        def _(_event) -> None:
            self._redraw()

    # --- frames --------------------------------------------------------------------------------
    def _open_job(self, every: int, timeout: float):
        """Subscribes to the job's frames and waits for the first (it carries the scene's info)."""
        self._call = self.client._stub.StreamFrames(pb.StreamFramesRequest(job_id=self.job_id, every=every),
                                                    timeout=self.client.stream_timeout)
        got: list = []

        def first() -> None:
            try:
                got.append(next(self._call))
            except BaseException as exc:  # the stream's error (unknown or finished job), or no frame
                got.append(exc)

        t = threading.Thread(target=first, daemon=True)
        t.start()
        t.join(timeout)
        if not got:
            self._call.cancel()
            raise TimeoutError(f"job {self.job_id}: no frame within {timeout:g} s (is it still queued?)")
        msg = got[0]
        if isinstance(msg, StopIteration):
            raise RuntimeError(f"job {self.job_id} ended before its first frame")
        if isinstance(msg, grpc.RpcError):
            raise RuntimeError(f"job {self.job_id}: {msg.code().name}: {msg.details()}") from None
        if isinstance(msg, BaseException):
            raise msg
        info = _scene_info_to_dict(msg.info)
        self.client._scene_info[self.job_id] = info
        return [info], [SceneState.from_proto(msg.state)]

    def _listen(self) -> None:
        by_id = {t.scene_id: t for t in self._tracks}
        try:
            for msg in self._call:
                if self._stop.is_set():
                    break
                state = SceneState.from_proto(msg.state)
                track = by_id.get(state.scene_id)
                if track is None:
                    continue
                self._receive(track, state)
                self._frames_received += 1
                self._dirty.set()
        except Exception as exc:  # the stream ended: cancelled by close(), scenes destroyed, server gone
            if not self._stop.is_set():
                self._error = exc

    def _paint(self) -> None:
        """Redraws the newest frames at most every self._period s while Live is ticked."""
        while not self._stop.is_set():
            self._dirty.wait()
            if self._stop.is_set():
                break
            self._dirty.clear()
            if self._live.value:
                self._redraw()
            time.sleep(self._period)

    def _receive(self, track: _SceneTrack, state: SceneState) -> None:
        with self._lock:
            if track.times and state.time < track.times[-1]:  # the scene was reset: start again
                track.frames.clear()
                track.times.clear()
            track.frames.append((state.time, state))
            track.times.append(state.time)

    def _redraw(self, index: Optional[int] = None) -> None:
        with self._lock:
            ref = self._tracks[0]
            if not ref.frames:
                return
            n = len(ref.frames)
            k = n - 1 if index is None else int(np.clip(index, 0, n - 1))
            t = ref.times[k]
            frames = [tr.frame_at(t) for tr in self._tracks]
        if index is None:
            self._slider.max = max(1, n - 1)
            self._slider.value = k
        self._time_text.value = f"{t:.3f}"
        lines = ["| scene | t (s) | steps | last call (ms) | contacts | intersecting | Newton / PCG | arms |",
                 "|---|---|---|---|---|---|---|---|"]
        for tr, f in zip(self._tracks, frames):
            if f is None:
                continue
            self._draw_scene(tr, f)
            st = f.stats
            arms = ", ".join(
                f"{a}: {s['grip'] if s.get('grip') else 'closed' if s['closed'] else 'open'}"
                + (f" {s['squeeze']:.1f} N" if "squeeze" in s else (f" {s['held_vertices']} v" if s["closed"] else ""))
                for a, s in f.arms.items())
            status = "" if not f.failed else f" FAILED: {f.failure}"
            lines.append(f"| {_short(tr.scene_id)} | {f.time:.3f} | {f.steps} | {st.get('wall_ms', 0.0):.1f} | "
                         f"{st.get('active_contacts', 0)} | {st.get('intersecting_pairs', 0)} | "
                         f"{st.get('newton_iterations', 0)} / {st.get('pcg_iterations', 0)} | "
                         f"{arms}{status} |")
        self._stats.content = "\n".join(lines)

    def _draw_scene(self, track: _SceneTrack, f: SceneState) -> None:
        s = self.server
        off = track.offset
        if f.positions is not None:
            track.mesh.vertices = (np.asarray(f.positions, dtype=np.float32) + off.astype(np.float32))
        for arm, a in f.arms.items():
            h = track.arms.get(arm)
            if h is None:
                continue
            h.position = tuple(np.asarray(a["position"]) + off)
            h.color = CLOSED_COLOR if a["closed"] else OPEN_COLOR
        for arm, a in f.arms.items():  # robot mode: the arm's chain from its base to the hand
            pts = a.get("links")
            if pts is None or len(pts) < 2:
                continue
            segs = np.stack([pts[:-1], pts[1:]], axis=1).astype(np.float32) + off.astype(np.float32)
            h = track.links.get(arm)
            if h is None or len(h.points) != len(segs):
                track.links[arm] = s.scene.add_line_segments(f"/{track.scene_id}/{arm}_arm", segs, colors=ARM_COLOR,
                                                             thickness=0.012)
            else:
                h.points = segs
        for k, c in enumerate(f.colliders):
            if c["shape"] != "box":
                continue
            if k >= len(track.colliders):
                track.colliders.append(s.scene.add_box(f"/{track.scene_id}/collider_{k}", color=PAD_COLOR,
                                                       dimensions=tuple(2 * np.asarray(c["half_extents"]))))
            box = track.colliders[k]
            box.position = tuple(np.asarray(c["position"]) + off)
            box.wxyz = tuple(np.asarray(c["orientation"]))


def _short(scene_id: str) -> str:
    """A label for a scene or job id: scenes ("s-" + 32 hex) by their head, jobs ("j-" + time +
    "-" + hex) by their random tail (their heads are the date)."""
    return scene_id[:12] if not scene_id.startswith("j-") else "j-…" + scene_id[-8:]


def _free_port(host: str) -> int:
    import socket
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind((host if host not in ("", "0.0.0.0") else "127.0.0.1", 0))
        return sock.getsockname()[1]


def main(argv: Optional[Sequence[str]] = None) -> int:
    p = argparse.ArgumentParser(prog="python -m garmentdynamics.viewer",
                                description="A live 3D viewer of scenes on a GarmentDynamics server (docs/viewer.md)")
    p.add_argument("--server", required=True, help="HOST:PORT of the gd-server")
    p.add_argument("--scene", action="append", default=[], help="a scene id (repeat, or comma-separated)")
    p.add_argument("--job", help="a queued or running job's id instead of scenes: its scene as it runs")
    p.add_argument("--host", default="127.0.0.1", help="address the page is served on (0.0.0.0: every interface)")
    p.add_argument("--port", type=int, default=8080, help="port of the page (0: a free one)")
    p.add_argument("--every", type=int, default=1, help="a frame every k-th step of a scene")
    p.add_argument("--max-fps", type=float, default=10.0, help="page updates per second at most")
    p.add_argument("--screenshot", help="write a PNG of the page (headless Chromium) and exit")
    p.add_argument("--wait", type=float, default=8.0, help="--screenshot: seconds of page time before the picture")
    p.add_argument("--size", default="1280x800", help="--screenshot: WIDTHxHEIGHT")
    p.add_argument("--token-file", help="a file holding the server's bearer token")
    p.add_argument("--tls", action="store_true", help="connect with TLS")
    args = p.parse_args(argv)
    ids = [s for arg in args.scene for s in arg.split(",") if s]
    if bool(ids) == bool(args.job):
        p.error("give the scenes to watch (--scene ID) or a job (--job ID)")
    client = Client(args.server, token_file=args.token_file, tls=args.tls)
    try:
        viewer = SceneViewer(client, ids, host=args.host, port=args.port, every=args.every, max_fps=args.max_fps,
                             job_id=args.job)
    except (RuntimeError, TimeoutError) as exc:
        print(f"viewer: {exc}", file=sys.stderr)
        return 2
    with viewer:
        if args.screenshot:
            w, h = (int(v) for v in args.size.lower().split("x"))
            out = screenshot(viewer.url, args.screenshot, width=w, height=h, wait_s=args.wait)
            print(out)
            return 0
        what = f"job {args.job}" if args.job else f"{len(ids)} scene(s)"
        print(f"viewing {what} at {viewer.url} (Ctrl-C to stop)", flush=True)
        try:
            while viewer._thread.is_alive():
                time.sleep(0.5)
        except KeyboardInterrupt:
            pass
        if viewer._error is not None:
            print(f"the frame stream ended: {viewer._error}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
