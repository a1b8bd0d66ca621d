"""The live viewer in a real browser: headless Chromium opens the viser page while a scene steps
on the server, and its screenshots show the garment (its colour's pixels) moving between two
pictures. The screenshots are kept in $GD_TEST_OUTPUT (default build/test-output/viewer/)."""

import os
import threading
from pathlib import Path

import numpy as np
import pytest

from conftest import REPO, TOWEL_VERTICES, corner_vertices

viser = pytest.importorskip("viser", reason="the viewer needs viser (pip install 'garmentdynamics[viewer]')")
from garmentdynamics.viewer import CLOTH_COLOR, SceneViewer, find_chromium, screenshot  # noqa: E402

pytestmark = pytest.mark.skipif(find_chromium() is None, reason="no Chromium (Debian: apt-get install chromium)")


def output_dir() -> Path:
    d = Path(os.environ.get("GD_TEST_OUTPUT") or REPO / "build" / "test-output") / "viewer"
    d.mkdir(parents=True, exist_ok=True)
    return d


def cloth_mask(png: Path) -> np.ndarray:
    """Pixels of the garment's red-orange under the page's lighting (and nothing else drawn there:
    the table is grey, the grippers green or purple, the page white and blue)."""
    import matplotlib.image as mpimg
    rgb = (mpimg.imread(str(png))[..., :3] * 255).astype(np.int32)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    # red-orange hue (red the largest, green between blue and red) and clearly saturated
    return (r > 80) & (r - np.maximum(g, b) > 40) & (g >= b - 10)


def lift(corner, closed: bool, height: float) -> dict:
    return {"left": {"position": (corner[0], corner[1], corner[2] + height), "orientation": (0, 1, 0, 0),
                     "gripper": 0.0 if closed else 0.035}}


def test_the_page_draws_the_garment_and_follows_it_while_it_steps(client):
    assert CLOTH_COLOR[0] > 2 * CLOTH_COLOR[1]  # what cloth_mask looks for
    ids = client.create_scenes(garment="towel", vertices=TOWEL_VERTICES)
    try:
        rest = client.scene_info(ids[0])["rest_positions"]
        corner = rest[corner_vertices(rest)[0]]
        with SceneViewer(client, ids, port=0) as viewer:
            # Another client steps the scene (the viewer only watches): grasp a corner.
            client.step(ids, [lift(corner, False, 0.0)], substeps=2)
            client.step(ids, [lift(corner, True, 0.0)], substeps=2)
            assert viewer.wait_for_frames(4, timeout=30)
            first = screenshot(viewer.url, output_dir() / "towel_lying.png", width=960, height=640, wait_s=6)
            # Lift the corner 30 cm while the page is open, then take the second picture.
            done = threading.Event()

            def step_up():
                for k in range(1, 16):
                    client.step(ids, [lift(corner, True, 0.02 * k)], substeps=3)
                done.set()

            stepper = threading.Thread(target=step_up)
            stepper.start()
            stepper.join(timeout=120)
            assert done.is_set()
            assert viewer.wait_for_frames(4 + 45, timeout=30)
            second = screenshot(viewer.url, output_dir() / "towel_lifted.png", width=960, height=640, wait_s=6)
        a, b = cloth_mask(first), cloth_mask(second)
        print(f"screenshots: {first} ({a.sum()} garment pixels), {second} ({b.sum()}); "
              f"{(a ^ b).sum()} pixels changed")
        assert a.sum() > 3000 and b.sum() > 3000  # the garment is drawn in both
        assert (a ^ b).sum() > 0.1 * a.sum()      # and it moved between them
    finally:
        client.destroy(ids)


def test_a_grid_of_scenes_and_the_robot_pads(client, piper_urdf, tmp_path):
    # Two pseudo scenes and a robot-mode one in one page: each scene's garment, the robot
    # scene's four finger pads as boxes; the page draws them all.
    pseudo = client.create_scenes(garment="towel", vertices=TOWEL_VERTICES, count=2)
    robot = client.create_scenes(garment="towel", vertices=TOWEL_VERTICES, mode="robot", urdf=piper_urdf)
    try:
        state = client.get_state(robot)[0]
        assert len(state.colliders) == 4 and all(c["shape"] == "box" for c in state.colliders)
        assert state.arms["left"]["position"].shape == (3,)
        links = state.arms["left"]["links"]  # the arm's chain: base (0, 0.25, 0) to the tool
        assert links.shape[1] == 3 and len(links) >= 4
        assert np.allclose(links[0], (0, 0.25, 0), atol=1e-6)
        assert np.allclose(links[-1], state.arms["left"]["position"], atol=1e-5)
        with SceneViewer(client, pseudo + robot, port=0) as viewer:
            client.step(pseudo + robot, substeps=2)
            # The constructor returns once the server has the subscription: every frame of the
            # two steps of the three scenes reaches the page.
            assert viewer.wait_for_frames(6, timeout=30)
            png = screenshot(viewer.url, output_dir() / "grid_of_three.png", width=960, height=640, wait_s=6)
            assert len(viewer._tracks[2].colliders) == 4
            assert set(viewer._tracks[2].links) == {"left", "right"}  # the robot's arms, drawn
            assert not viewer._tracks[0].links
        assert cloth_mask(png).sum() > 3000
    finally:
        client.destroy(pseudo + robot)


def test_a_job_in_progress(client):
    # The viewer follows a job's scene from its first step to its end (the job waits behind
    # another, so the viewer is subscribed before it runs); the page draws the garment and keeps
    # the last frame once the job has ended.
    ahead = client.submit_job(garment="towel", task="grasp", vertices=TOWEL_VERTICES, dt=0.02, time_scale=0.5,
                              settle=0.1, self_contact=False, label="ahead")
    job = client.submit_job(garment="towel", task="grasp", vertices=TOWEL_VERTICES, dt=0.02, time_scale=0.5,
                            settle=0.1, self_contact=False, label="viewed")
    with SceneViewer(client, job_id=job, port=0, every=2) as viewer:
        assert viewer.scene_ids == [job]
        assert viewer.wait_for_frames(3, timeout=120)
        png = screenshot(viewer.url, output_dir() / "job_in_progress.png", width=960, height=640, wait_s=6)
        viewer._thread.join(timeout=300)  # the stream ends with the job
        assert not viewer._thread.is_alive() and viewer._error is None
        report = client.wait_report(job, progress=False)
        assert report["job"]["status"] == "SUCCEEDED", report["job"]["message"]
        assert viewer.frames_received + 1 == report["summary"]["steps"] // 2  # + the first, taken before
    assert client.wait_report(ahead, progress=False)["job"]["status"] == "SUCCEEDED"
    assert cloth_mask(png).sum() > 3000
    with pytest.raises(RuntimeError, match="FAILED_PRECONDITION"):  # ended: its report has the animation
        SceneViewer(client, job_id=job, port=0)


def test_unknown_scenes_are_refused_before_a_page_is_served(client):
    import grpc
    with pytest.raises(grpc.RpcError) as err:
        SceneViewer(client, ["s-doesnotexist"], port=0)
    assert err.value.code() == grpc.StatusCode.NOT_FOUND
