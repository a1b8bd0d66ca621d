"""Starting and stopping a local gd-server process (what Client.spawn uses)."""

import os
import shutil
import signal
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Optional, Sequence, Union

import grpc

from . import health


def find_server_binary(server_bin: Optional[str] = None) -> str:
    """The gd-server executable: `server_bin`, $GD_SERVER_BIN, `gd-server` on PATH, or
    <repo>/build/bin/gd-server of the checkout the package was built from. Raises
    FileNotFoundError listing what was tried."""
    tried = []
    candidates = []
    if server_bin:
        candidates.append(("server_bin", server_bin))
    if os.environ.get("GD_SERVER_BIN"):
        candidates.append(("$GD_SERVER_BIN", os.environ["GD_SERVER_BIN"]))
    on_path = shutil.which("gd-server")
    if on_path:
        candidates.append(("PATH", on_path))
    try:
        from . import _build_info
        if _build_info.REPO_ROOT:
            candidates.append(("checkout", str(Path(_build_info.REPO_ROOT) / "build" / "bin" / "gd-server")))
    except ImportError:
        pass
    for source, path in candidates:
        p = Path(path)
        if p.is_file() and os.access(p, os.X_OK):
            return str(p)
        tried.append(f"{source}: {path}")
    raise FileNotFoundError("gd-server not found; pass server_bin=, set GD_SERVER_BIN or put gd-server on "
                            "PATH (tried " + ("; ".join(tried) if tried else "nothing") + ")")


class LocalServer:
    """A gd-server child process listening on a free loopback port.

    The server is started with `--port 0 --port-file FILE` and reports the port it bound in FILE;
    start() then waits until the gRPC health service says SERVING. stop() sends SIGTERM (graceful
    drain) and kills the process if it has not exited after `stop_timeout` seconds.

    auth_token_file, tls_cert, tls_key, tls_client_ca: the server's --auth-token-file,
    --tls-cert, --tls-key, --tls-client-ca. A server that speaks TLS is waited for over a channel
    with `credentials` (grpc.ChannelCredentials, e.g. garmentdynamics.credentials.
    channel_credentials(root_certificates=tls_cert)) and `channel_options`; the health service
    needs no token.
    """

    def __init__(self, data_dir: Optional[str] = None, threads: Optional[int] = None,
                 server_bin: Optional[str] = None, extra_args: Sequence[str] = (),
                 start_timeout: float = 60.0, stop_timeout: float = 10.0, host: str = "127.0.0.1", *,
                 auth_token_file: Union[None, str, "os.PathLike[str]"] = None,
                 tls_cert: Union[None, str, "os.PathLike[str]"] = None,
                 tls_key: Union[None, str, "os.PathLike[str]"] = None,
                 tls_client_ca: Union[None, str, "os.PathLike[str]"] = None,
                 credentials: Optional[grpc.ChannelCredentials] = None, channel_options: Sequence = ()):
        if (tls_cert is None) != (tls_key is None):
            raise ValueError("give tls_cert and tls_key together (or neither)")
        if tls_client_ca is not None and tls_cert is None:
            raise ValueError("tls_client_ca (mutual TLS) needs tls_cert and tls_key")
        if tls_cert is not None and credentials is None:
            raise ValueError("a server with tls_cert is waited for over TLS: pass credentials= "
                             "(garmentdynamics.credentials.channel_credentials(root_certificates=...))")
        self.security_args = []
        for flag, path in (("--auth-token-file", auth_token_file), ("--tls-cert", tls_cert), ("--tls-key", tls_key),
                           ("--tls-client-ca", tls_client_ca)):
            if path is not None:
                p = Path(os.fspath(path)).expanduser().resolve()
                if not p.is_file():
                    raise ValueError(f"{flag} file {str(p)!r} does not exist")
                self.security_args += [flag, str(p)]
        self.credentials = credentials
        self.channel_options = list(channel_options)
        self.binary = find_server_binary(server_bin)
        self._tmp = tempfile.mkdtemp(prefix="gd-server-")
        self.data_dir = str(Path(data_dir).resolve()) if data_dir else str(Path(self._tmp) / "data")
        Path(self.data_dir).mkdir(parents=True, exist_ok=True)
        self.threads = threads
        self.extra_args = list(extra_args)
        self.start_timeout = start_timeout
        self.stop_timeout = stop_timeout
        self.host = host
        self.port: Optional[int] = None
        self.log_path = str(Path(self._tmp) / "gd-server.log")
        self.proc: Optional[subprocess.Popen] = None

    @property
    def target(self) -> str:
        return f"{self.host}:{self.port}"

    def command(self, port_file: str) -> list:
        cmd = [self.binary, "--host", self.host, "--port", "0", "--port-file", port_file,
               "--data-dir", self.data_dir]
        if self.threads:
            cmd += ["--threads", str(int(self.threads))]
        return cmd + self.security_args + self.extra_args

    def log_tail(self, n: int = 40) -> str:
        try:
            return "\n".join(Path(self.log_path).read_text(errors="replace").splitlines()[-n:])
        except OSError:
            return ""

    def start(self) -> "LocalServer":
        port_file = str(Path(self._tmp) / "port")
        with open(self.log_path, "wb") as log:
            self.proc = subprocess.Popen(self.command(port_file), stdout=log, stderr=subprocess.STDOUT,
                                         stdin=subprocess.DEVNULL, start_new_session=True)
        deadline = time.monotonic() + self.start_timeout
        try:
            while self.port is None:
                self._check_alive()
                text = Path(port_file).read_text().strip() if Path(port_file).exists() else ""
                if text.isdigit() and int(text) > 0:
                    self.port = int(text)
                    break
                if time.monotonic() > deadline:
                    raise TimeoutError(f"gd-server did not write its port within {self.start_timeout} s")
                time.sleep(0.05)
            if self.credentials is not None:
                channel = grpc.secure_channel(self.target, self.credentials, options=self.channel_options)
            else:
                channel = grpc.insecure_channel(self.target, options=self.channel_options)
            last_error = ""
            with channel:
                while True:
                    self._check_alive()
                    remaining = deadline - time.monotonic()
                    if remaining <= 0:
                        hint = ""
                        if self.credentials is not None and last_error:
                            hint = " (do the client's TLS credentials match the server's certificate?)"
                        raise TimeoutError(f"gd-server at {self.target} was not SERVING within "
                                           f"{self.start_timeout} s; last error: {last_error or 'none'}{hint}")
                    try:
                        if health.check(channel, timeout=min(2.0, remaining)) == health.SERVING:
                            return self
                    except grpc.RpcError as err:
                        if err.code() == grpc.StatusCode.UNIMPLEMENTED:
                            raise RuntimeError("the server has no gRPC health service") from None
                        last_error = f"{err.code().name}: {err.details()}"
                    time.sleep(0.05)
        except BaseException as exc:
            tail = self.log_tail()
            self.stop()
            if isinstance(exc, (TimeoutError, RuntimeError)):
                raise RuntimeError(f"{exc}\n--- gd-server log ---\n{tail}") from None
            raise

    def _check_alive(self):
        if self.proc is not None and self.proc.poll() is not None:
            raise RuntimeError(f"gd-server exited with code {self.proc.returncode} during start-up "
                               f"({' '.join(self.proc.args)})")

    def stop(self) -> Optional[int]:
        """Stops the server (SIGTERM, then SIGKILL); returns its exit code. Idempotent."""
        code = None
        if self.proc is not None:
            if self.proc.poll() is None:
                self.proc.send_signal(signal.SIGTERM)
                try:
                    self.proc.wait(timeout=self.stop_timeout)
                except subprocess.TimeoutExpired:
                    self.proc.kill()
                    self.proc.wait()
            code = self.proc.returncode
        # the temporary directory holds the port file, the log and (when no data_dir was given)
        # the data; a caller's data_dir lives outside it and is kept
        shutil.rmtree(self._tmp, ignore_errors=True)
        return code

    def __enter__(self):
        return self.start() if self.proc is None else self

    def __exit__(self, *exc):
        self.stop()
