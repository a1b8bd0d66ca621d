"""The container files agree with the server they run.

deploy/Dockerfile's ENTRYPOINT is deploy/gd-entrypoint, which is run here (by /bin/sh, with a stub
gd-server that prints its arguments; no image is built): it binds 0.0.0.0:50051, passes the token
and TLS files when they are mounted and only then, lets the arguments given override each default
without giving a flag twice, and execs gd-server (PID 1, SIGTERM goes to it). Every flag it and
compose.yaml pass is one `gd-server --help` lists. compose.yaml mounts the token as a secret where
the entrypoint looks, publishes on loopback by default, and deploy/secrets stays out of git and of
the build context.
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
DEPLOY = ROOT / "deploy"
ENTRYPOINT = DEPLOY / "gd-entrypoint"
DEFAULTS = ["--host", "0.0.0.0", "--port", "50051", "--data-dir", "/var/lib/garmentdynamics"]


def default_path(var):
    """The entrypoint's default for a GD_SERVER_* path variable."""
    m = re.search(r"\$\{" + var + r":-([^}]+)\}", ENTRYPOINT.read_text())
    assert m, f"gd-entrypoint has no default for {var}"
    return m.group(1)


@pytest.fixture
def run_entrypoint(tmp_path):
    """run(args, files=()) -> (pid of gd-server, its arguments, stderr): the entrypoint with a stub
    gd-server; `files` names which of token, cert, key, client_ca exist (in tmp_path)."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    stub = bin_dir / "gd-server"
    stub.write_text('#!/bin/sh\necho "$$"\nfor a in "$@"; do printf "%s\\n" "$a"; done\n')
    stub.chmod(0o755)
    paths = {"token": tmp_path / "gd-token", "cert": tmp_path / "gd-tls.crt", "key": tmp_path / "gd-tls.key",
             "client_ca": tmp_path / "gd-client-ca.crt"}

    def run(args, files=()):
        for name, p in paths.items():
            if name in files:
                p.write_text("x\n")
            elif p.exists():
                p.unlink()
        env = dict(os.environ, PATH=f"{bin_dir}:{os.environ['PATH']}", GD_SERVER_TOKEN_FILE=str(paths["token"]),
                   GD_SERVER_TLS_CERT=str(paths["cert"]), GD_SERVER_TLS_KEY=str(paths["key"]),
                   GD_SERVER_TLS_CLIENT_CA=str(paths["client_ca"]))
        p = subprocess.Popen([str(ENTRYPOINT), *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=env)
        out, err = p.communicate(timeout=30)
        assert p.returncode == 0, err
        lines = out.splitlines()
        assert int(lines[0]) == p.pid, "gd-entrypoint must exec gd-server (PID 1 in the container)"
        return lines[1:], err

    run.paths = {k: str(v) for k, v in paths.items()}
    return run


def test_dockerfile_runs_the_entrypoint():
    text = (DEPLOY / "Dockerfile").read_text()
    entry = re.search(r"^ENTRYPOINT (\[.*\])$", text, re.M)
    assert entry, "deploy/Dockerfile has no exec-form ENTRYPOINT"
    assert json.loads(entry.group(1)) == ["/usr/local/bin/gd-entrypoint"]
    assert re.search(r"^COPY deploy/gd-entrypoint /usr/local/bin/gd-entrypoint$", text, re.M)
    assert re.search(r"^EXPOSE 50051$", text, re.M)
    assert ENTRYPOINT.read_text().startswith("#!/bin/sh\n")
    assert os.access(ENTRYPOINT, os.X_OK)


def test_entrypoint_without_secrets(run_entrypoint):
    args, err = run_entrypoint(["--threads", "8"])
    assert args == DEFAULTS + ["--threads", "8"]
    # No token: gd-server will refuse 0.0.0.0; the entrypoint says where the token goes.
    assert run_entrypoint.paths["token"] in err and "Authentication and TLS" in err


def test_entrypoint_token_and_tls(run_entrypoint):
    p = run_entrypoint.paths
    args, err = run_entrypoint(["--threads", "8"], files=("token",))
    assert args == DEFAULTS + ["--auth-token-file", p["token"], "--threads", "8"] and err == ""
    args, _ = run_entrypoint([], files=("token", "cert", "key"))
    assert args == DEFAULTS + ["--auth-token-file", p["token"], "--tls-cert", p["cert"], "--tls-key", p["key"]]
    args, _ = run_entrypoint([], files=("token", "cert", "key", "client_ca"))
    assert args[-2:] == ["--tls-client-ca", p["client_ca"]] and "--tls-cert" in args
    # A client CA alone is no TLS; a certificate without its key is passed on for gd-server to refuse.
    args, _ = run_entrypoint([], files=("token", "client_ca"))
    assert not [a for a in args if a.startswith("--tls")]
    args, _ = run_entrypoint([], files=("token", "cert"))
    assert args[args.index("--tls-key") + 1] == p["key"]


def test_entrypoint_arguments_override_defaults(run_entrypoint):
    p = run_entrypoint.paths
    # Local development: loopback and no token, nothing said.
    args, err = run_entrypoint(["--host", "127.0.0.1", "--port=6000", "--log-level", "a b"])
    assert args == ["--data-dir", "/var/lib/garmentdynamics", "--host", "127.0.0.1", "--port=6000",
                    "--log-level", "a b"] and err == ""
    args, _ = run_entrypoint(["--auth-token-file", "/elsewhere", "--tls-cert", "c", "--tls-key", "k"],
                             files=("token", "cert", "key", "client_ca"))
    assert args == DEFAULTS + ["--auth-token-file", "/elsewhere", "--tls-cert", "c", "--tls-key", "k"]
    # --allow-unauthenticated does not drop a mounted token.
    args, err = run_entrypoint(["--allow-unauthenticated"])
    assert "--auth-token-file" not in args and err == ""
    args, _ = run_entrypoint(["--allow-unauthenticated"], files=("token",))
    assert args[args.index("--auth-token-file") + 1] == p["token"]


def test_entrypoint_flags_are_server_flags(run_entrypoint, server_flags):
    args, _ = run_entrypoint([], files=("token", "cert", "key", "client_ca"))
    compose = yaml.safe_load((DEPLOY / "compose.yaml").read_text())
    args += compose["services"]["gd-server"]["command"] + ["--allow-unauthenticated"]
    unknown = sorted({a.split("=")[0] for a in args if a.startswith("--")} - server_flags)
    assert not unknown, f"gd-server does not accept {unknown}"


def interpolate(value):
    """Compose's ${VAR:-default} with VAR unset."""
    return re.sub(r"\$\{[A-Z_]+:-([^}]*)\}", r"\1", value)


def test_compose_mounts_the_token_and_publishes_on_loopback():
    compose = yaml.safe_load((DEPLOY / "compose.yaml").read_text())
    svc = compose["services"]["gd-server"]
    assert [interpolate(p) for p in svc["ports"]] == ["127.0.0.1:50051:50051"]
    # A secret without a target lands at /run/secrets/<name>: where the entrypoint looks.
    assert svc["secrets"] == ["gd-token"]
    assert default_path("GD_SERVER_TOKEN_FILE") == "/run/secrets/gd-token"
    assert compose["secrets"]["gd-token"] == {"file": "./secrets/gd-token"}
    assert not [a for a in svc["command"] if a in ("--host", "--allow-unauthenticated", "--auth-token-file")]


def test_compose_tls_mounts_where_the_entrypoint_looks():
    tls = yaml.safe_load((DEPLOY / "compose.tls.yaml").read_text())
    targets = {s["source"]: "/run/secrets/" + s["target"] for s in tls["services"]["gd-server"]["secrets"]}
    assert targets == {"gd-tls-cert": default_path("GD_SERVER_TLS_CERT"),
                       "gd-tls-key": default_path("GD_SERVER_TLS_KEY")}
    assert {n: s["file"] for n, s in tls["secrets"].items()} == {"gd-tls-cert": "./secrets/tls.crt",
                                                                  "gd-tls-key": "./secrets/tls.key"}


def test_secrets_stay_out_of_git_and_the_build_context():
    assert "deploy/secrets" in (ROOT / ".dockerignore").read_text().split()
    git = shutil.which("git")
    if git is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    for name, ignored in (("gd-token", True), ("tls.key", True), ("ca.key", True), ("README.md", False)):
        rc = subprocess.run([git, "-C", str(ROOT), "check-ignore", "-q", "--no-index",
                             f"deploy/secrets/{name}"]).returncode
        assert rc == (0 if ignored else 1), f"deploy/secrets/{name}: git check-ignore {rc}"
