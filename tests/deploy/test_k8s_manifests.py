"""The Kubernetes manifests agree with the server they deploy.

Renders deploy/k8s's overlays, alone and with the TLS component, with `kubectl kustomize` (skipped
where kubectl is absent), then checks that every flag they pass to gd-server is one
`gd-server --help` lists, that the token (and the TLS certificate) come from Secrets mounted
read-only where the flags point, that the probes are gRPC health probes on the container's port
(which need no token; TCP probes with TLS, which the kubelet's gRPC probe cannot speak), that
SIGTERM's drain fits in the pod's grace period, and that the GPU overlay asks for a GPU and the
CUDA backend. The Dockerfile, its entrypoint and compose.yaml: test_container.py.
"""
import os
import shutil
import subprocess
from pathlib import Path, PurePosixPath

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
K8S = ROOT / "deploy" / "k8s"
OVERLAYS = ["cpu", "gpu"]
# Each overlay alone, and with the TLS component as docs/deployment.md says to add it.
VARIANTS = [(o, ()) for o in OVERLAYS] + [(o, ("tls",)) for o in OVERLAYS]
VARIANT_IDS = [o + "".join("+" + c for c in comps) for o, comps in VARIANTS]
TOKEN_SECRET = "gd-server-token"
TLS_SECRET = "gd-server-tls"


def kustomize(directory):
    kubectl = shutil.which("kubectl")
    if kubectl is None:
        pytest.skip("kubectl is not installed")
    out = subprocess.run([kubectl, "kustomize", str(directory)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return [d for d in yaml.safe_load_all(out.stdout) if d]


def own_overlay(tmp_path, overlay, components=(), extra=None):
    """An overlay of a user's own in tmp_path: deploy/k8s/overlays/OVERLAY plus components (kustomize
    takes relative paths only)."""
    rel = lambda p: os.path.relpath(p, tmp_path)  # noqa: E731
    k = {"apiVersion": "kustomize.config.k8s.io/v1beta1", "kind": "Kustomization",
         "resources": [rel(K8S / "overlays" / overlay)]}
    if components:
        k["components"] = [rel(K8S / "components" / c) for c in components]
    k.update(extra or {})
    (tmp_path / "kustomization.yaml").write_text(yaml.safe_dump(k))
    return tmp_path


def render(overlay, components=(), tmp_path=None):
    if not components:
        return kustomize(K8S / "overlays" / overlay)
    return kustomize(own_overlay(tmp_path, overlay, components))


def statefulset(docs):
    sets = [d for d in docs if d["kind"] == "StatefulSet"]
    assert len(sets) == 1
    return sets[0]


def flags_of(args):
    return [a for a in args if a.startswith("--")]


def value_of(args, flag):
    assert args.count(flag) == 1, f"{flag} given {args.count(flag)} times in {args}"
    return args[args.index(flag) + 1]


def secret_behind(pod, container, path):
    """The Secret volume whose read-only mount holds `path`, or fail."""
    volumes = {v["name"]: v for v in pod.get("volumes", [])}
    for m in container.get("volumeMounts", []):
        mount = PurePosixPath(m["mountPath"])
        if mount in PurePosixPath(path).parents:
            secret = volumes[m["name"]].get("secret")
            assert secret is not None, f"{path} is on volume {m['name']}, not a Secret"
            assert m.get("readOnly") is True, f"{m['mountPath']} is mounted writable"
            return secret
    raise AssertionError(f"no volume is mounted where {path} lies")


@pytest.mark.parametrize("overlay,components", VARIANTS, ids=VARIANT_IDS)
def test_manifest_flags_are_server_flags(overlay, components, tmp_path, server_flags):
    args = statefulset(render(overlay, components, tmp_path))["spec"]["template"]["spec"]["containers"][0]["args"]
    unknown = [f for f in flags_of(args) if f not in server_flags]
    assert not unknown, f"{overlay}: gd-server does not accept {unknown}"


@pytest.mark.parametrize("overlay,components", VARIANTS, ids=VARIANT_IDS)
def test_token_comes_from_a_secret(overlay, components, tmp_path):
    pod = statefulset(render(overlay, components, tmp_path))["spec"]["template"]["spec"]
    c = pod["containers"][0]
    assert "--allow-unauthenticated" not in c["args"]
    secret = secret_behind(pod, c, value_of(c["args"], "--auth-token-file"))
    assert secret["secretName"] == TOKEN_SECRET
    assert PurePosixPath(value_of(c["args"], "--auth-token-file")).name == "token"  # the Secret's key
    assert secret.get("optional") is not True  # no Secret, no pod: never a server without tokens
    assert pod.get("automountServiceAccountToken") is False


@pytest.mark.parametrize("overlay", OVERLAYS)
def test_tls_component(overlay, tmp_path):
    pod = statefulset(render(overlay, ("tls",), tmp_path))["spec"]["template"]["spec"]
    c = pod["containers"][0]
    cert, key = value_of(c["args"], "--tls-cert"), value_of(c["args"], "--tls-key")
    for path, name in ((cert, "tls.crt"), (key, "tls.key")):  # the keys of a kubernetes.io/tls Secret
        assert secret_behind(pod, c, path)["secretName"] == TLS_SECRET
        assert PurePosixPath(path).name == name
    # The overlay's own arguments are kept (the component appends).
    assert c["args"][:len(c["args"]) - 4] == statefulset(render(overlay))["spec"]["template"]["spec"][
        "containers"][0]["args"]


@pytest.mark.parametrize("overlay,components", VARIANTS, ids=VARIANT_IDS)
def test_probes_services_and_drain(overlay, components, tmp_path):
    docs = render(overlay, components, tmp_path)
    sts = statefulset(docs)
    pod = sts["spec"]["template"]["spec"]
    c = pod["containers"][0]
    port = c["ports"][0]["containerPort"]
    # The kubelet's gRPC probe (grpc.health.v1, no token needed) speaks plaintext only: with TLS
    # the port is probed with TCP.
    kind = "tcpSocket" if "--tls-cert" in c["args"] else "grpc"
    for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
        assert c[probe][kind]["port"] == port, probe
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
    assert mount["mountPath"] == "/var/lib/garmentdynamics"  # the entrypoint's --data-dir
    assert "--data-dir" not in c["args"] and "--port" not in c["args"]  # the image's own (50051)


def test_gpu_overlay_asks_for_a_gpu_and_cuda():
    c = statefulset(render("gpu"))["spec"]["template"]["spec"]["containers"][0]
    assert c["resources"]["limits"]["nvidia.com/gpu"] == 1
    assert value_of(c["args"], "--backend") == "cuda"
    c = statefulset(render("cpu"))["spec"]["template"]["spec"]["containers"][0]
    assert "nvidia.com/gpu" not in c["resources"].get("limits", {})
    assert value_of(c["args"], "--backend") == "cpu"


def test_secrets_generated_in_an_overlay(tmp_path):
    """docs/deployment.md's deploy/secrets/kustomization.yaml: the cpu overlay, the TLS component and
    a secretGenerator for the token and the certificate from the files beside it; the pods then
    mount the generated (hash-named) Secrets."""
    (tmp_path / "gd-token").write_text("0123456789abcdef0123456789abcdef\n")
    (tmp_path / "tls.crt").write_text("-----BEGIN CERTIFICATE-----\n")
    (tmp_path / "tls.key").write_text("-----BEGIN PRIVATE KEY-----\n")
    docs = kustomize(own_overlay(tmp_path, "cpu", ("tls",), extra={"secretGenerator": [
        {"name": TOKEN_SECRET, "files": ["token=gd-token"]},
        {"name": TLS_SECRET, "type": "kubernetes.io/tls", "files": ["tls.crt", "tls.key"]}]}))
    secrets = {d["metadata"]["name"].rsplit("-", 1)[0]: d for d in docs if d["kind"] == "Secret"}
    assert set(secrets) == {TOKEN_SECRET, TLS_SECRET}
    assert set(secrets[TOKEN_SECRET]["data"]) == {"token"}
    assert set(secrets[TLS_SECRET]["data"]) == {"tls.crt", "tls.key"}
    pod = statefulset(docs)["spec"]["template"]["spec"]
    c = pod["containers"][0]
    for flag, name in (("--auth-token-file", TOKEN_SECRET), ("--tls-cert", TLS_SECRET), ("--tls-key", TLS_SECRET)):
        assert secret_behind(pod, c, value_of(c["args"], flag))["secretName"] == secrets[name]["metadata"]["name"]
