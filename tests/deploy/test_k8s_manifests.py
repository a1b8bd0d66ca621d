"""The deployment files agree with the server they deploy.

Renders deploy/k8s's overlays with `kubectl kustomize` (skipped where kubectl is absent), then
checks that every flag the manifests and the Dockerfile pass to gd-server is one `gd-server --help`
lists, that the probes are gRPC health probes on the container's port, that SIGTERM's drain fits in
the pod's grace period, and that the GPU overlay asks for a GPU and the CUDA backend.
"""
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
OVERLAYS = ["cpu", "gpu"]


def server_bin():
    path = os.environ.get("GD_SERVER_BIN", str(ROOT / "build" / "bin" / "gd-server"))
    if not Path(path).is_file():
        pytest.skip(f"gd-server not built ({path}); set GD_SERVER_BIN")
    return path


def server_flags():
    out = subprocess.run([server_bin(), "--help"], capture_output=True, text=True, timeout=30)
    assert out.returncode == 0, out.stderr
    return set(re.findall(r"(--[a-z][a-z0-9-]*)", out.stdout))


def render(overlay):
    kubectl = shutil.which("kubectl")
    if kubectl is None:
        pytest.skip("kubectl is not installed")
    out = subprocess.run([kubectl, "kustomize", str(ROOT / "deploy" / "k8s" / "overlays" / overlay)],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return [d for d in yaml.safe_load_all(out.stdout) if d]


def statefulset(docs):
    sets = [d for d in docs if d["kind"] == "StatefulSet"]
    assert len(sets) == 1
    return sets[0]


def flags_of(args):
    return [a for a in args if a.startswith("--")]


def value_of(args, flag):
    return args[args.index(flag) + 1]


@pytest.mark.parametrize("overlay", OVERLAYS)
def test_manifest_flags_are_server_flags(overlay):
    known = server_flags()
    args = statefulset(render(overlay))["spec"]["template"]["spec"]["containers"][0]["args"]
    unknown = [f for f in flags_of(args) if f not in known]
    assert not unknown, f"{overlay}: gd-server does not accept {unknown}"


def test_dockerfile_entrypoint_flags_are_server_flags():
    known = server_flags()
    text = (ROOT / "deploy" / "Dockerfile").read_text()
    entry = re.search(r"^ENTRYPOINT (\[.*\])$", text, re.M)
    assert entry, "deploy/Dockerfile has no exec-form ENTRYPOINT"
    args = json.loads(entry.group(1))
    assert args[0] == "gd-server"
    unknown = [f for f in flags_of(args) if f not in known]
    assert not unknown, f"Dockerfile: gd-server does not accept {unknown}"
    assert value_of(args, "--port") == "50051"


@pytest.mark.parametrize("overlay", OVERLAYS)
def test_probes_services_and_drain(overlay):
    docs = render(overlay)
    sts = statefulset(docs)
    pod = sts["spec"]["template"]["spec"]
    c = pod["containers"][0]
    port = c["ports"][0]["containerPort"]
    for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
        assert c[probe]["grpc"]["port"] == port, probe
    grace = int(value_of(c["args"], "--grace-seconds"))
    assert pod["terminationGracePeriodSeconds"] > grace
    services = {d["metadata"]["name"]: d for d in docs if d["kind"] == "Service"}
    assert services[sts["spec"]["serviceName"]]["spec"]["clusterIP"] == "None"
    for s in services.values():
        assert s["spec"]["ports"][0]["targetPort"] in ("grpc", port)
        assert s["spec"]["selector"] == sts["spec"]["selector"]["matchLabels"]
    # Reports live on a per-pod volume mounted where the server keeps its data.
    mount = c["volumeMounts"][0]
    assert mount["name"] == sts["spec"]["volumeClaimTemplates"][0]["metadata"]["name"]


def test_gpu_overlay_asks_for_a_gpu_and_cuda():
    c = statefulset(render("gpu"))["spec"]["template"]["spec"]["containers"][0]
    assert c["resources"]["limits"]["nvidia.com/gpu"] == 1
    assert value_of(c["args"], "--backend") == "cuda"
    c = statefulset(render("cpu"))["spec"]["template"]["spec"]["containers"][0]
    assert "nvidia.com/gpu" not in c["resources"].get("limits", {})
    assert value_of(c["args"], "--backend") == "cpu"
