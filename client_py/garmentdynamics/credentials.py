"""Tokens and TLS for the Client: the bearer token sent on every call, and the channel's TLS
credentials.

A gd-server started with `--auth-token-file` answers every call but the gRPC health service and
server reflection with UNAUTHENTICATED unless it carries the metadata
`authorization: Bearer <token>` with one of its tokens; each scene and job then belongs to the
token that created it. A server started with `--tls-cert/--tls-key` speaks TLS only, and with
`--tls-client-ca` it also requires a client certificate signed by that CA (mutual TLS).

The token travels in plain text over a channel without TLS: use TLS for anything but loopback.

- `read_token_file(path)`: the token of a token file (its first line that is neither blank nor a
  `#` comment, whitespace stripped), the format of gd-server's --auth-token-file.
- `resolve_token(token, token_file)`: what Client uses: `token`, else `token_file`, else the file
  named by $GD_TOKEN_FILE, else None.
- `channel_credentials(...)`: grpc.ssl_channel_credentials from PEM bytes or paths (None: no TLS).
- `TokenInterceptor`: adds the authorization metadata to unary and streaming calls.
"""

import collections
import os
from pathlib import Path
from typing import Optional, Union

import grpc

TOKEN_FILE_ENV = "GD_TOKEN_FILE"
MIN_TOKEN_LENGTH = 16

PathOrBytes = Union[bytes, bytearray, str, "os.PathLike[str]"]


def check_token(token: str, where: str = "the token") -> str:
    """The token if it is one gd-server can accept (at least 16 printable ASCII characters, no
    spaces); ValueError saying what is wrong otherwise."""
    if not isinstance(token, str):
        raise TypeError(f"{where} must be a str, not {type(token).__name__}")
    bad = sorted({c for c in token if not ("!" <= c <= "~")})
    if bad:
        raise ValueError(f"{where} contains characters a token cannot have ({', '.join(repr(c) for c in bad)}): "
                         "tokens are printable ASCII without spaces")
    if len(token) < MIN_TOKEN_LENGTH:
        raise ValueError(f"{where} is {len(token)} characters long; gd-server's tokens have at least "
                         f"{MIN_TOKEN_LENGTH}")
    return token


def read_token_file(path: Union[str, "os.PathLike[str]"]) -> str:
    """The token in a token file: its first line that is not blank and does not start with '#',
    surrounding whitespace stripped (gd-server's --auth-token-file format; a client uses the
    first token). ValueError naming the file when it cannot be read or holds no token."""
    p = Path(os.fspath(path)).expanduser()
    try:
        text = p.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise ValueError(f"token file {str(p)!r} does not exist") from None
    except UnicodeDecodeError:
        raise ValueError(f"token file {str(p)!r} is not text (UTF-8)") from None
    except OSError as exc:
        raise ValueError(f"token file {str(p)!r} cannot be read: {exc.strerror or exc}") from None
    for number, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        return check_token(line, f"the token on line {number} of token file {str(p)!r}")
    raise ValueError(f"token file {str(p)!r} is empty: it has no line with a token (blank lines and "
                     "lines starting with '#' are skipped)")


def resolve_token(token: Optional[str] = None,
                  token_file: Union[None, str, "os.PathLike[str]"] = None) -> Optional[str]:
    """`token`, else the token of `token_file`, else that of the file named by $GD_TOKEN_FILE,
    else None. Both token and token_file is a ValueError."""
    if token is not None and token_file is not None:
        raise ValueError("give token= or token_file=, not both")
    if token is not None:
        return check_token(token.strip(), "token=")
    if token_file is not None:
        return read_token_file(token_file)
    env = os.environ.get(TOKEN_FILE_ENV, "").strip()
    if env:
        try:
            return read_token_file(env)
        except ValueError as exc:
            raise ValueError(f"${TOKEN_FILE_ENV}: {exc}") from None
    return None


def read_pem(value: Optional[PathOrBytes], what: str, marker: str) -> Optional[bytes]:
    """PEM bytes from bytes, PEM text, or a path; ValueError naming the file or the argument
    when it cannot be read or holds no PEM block of `marker` ("CERTIFICATE", "PRIVATE KEY")."""
    if value is None:
        return None
    if isinstance(value, (bytes, bytearray)):
        data, source = bytes(value), f"{what}= (bytes)"
    elif isinstance(value, str) and value.lstrip().startswith("-----BEGIN"):
        data, source = value.encode(), f"{what}= (PEM text)"
    elif isinstance(value, (str, os.PathLike)):
        p = Path(os.fspath(value)).expanduser()
        source = f"{what} file {str(p)!r}"
        try:
            data = p.read_bytes()
        except FileNotFoundError:
            raise ValueError(f"{source} does not exist") from None
        except OSError as exc:
            raise ValueError(f"{source} cannot be read: {exc.strerror or exc}") from None
    else:
        raise TypeError(f"{what} must be PEM bytes or a path, not {type(value).__name__}")
    if b"-----BEGIN" not in data:
        raise ValueError(f"{source} is not PEM (no '-----BEGIN' line); convert DER with "
                         f"`openssl x509 -inform der` / `openssl pkey -inform der`")
    if marker.encode() not in data:
        raise ValueError(f"{source} has no {marker} block (were the certificate and the key swapped?)")
    return data


def channel_credentials(tls: bool = False, root_certificates: Optional[PathOrBytes] = None,
                        certificate_chain: Optional[PathOrBytes] = None,
                        private_key: Optional[PathOrBytes] = None) -> Optional[grpc.ChannelCredentials]:
    """grpc.ssl_channel_credentials when `tls` or any certificate is given, else None (plaintext).
    root_certificates: the CAs (or the self-signed certificate) to trust, None = the system's;
    certificate_chain + private_key: the client certificate for mutual TLS (both or neither)."""
    if (certificate_chain is None) != (private_key is None):
        raise ValueError("mutual TLS needs both certificate_chain= and private_key= (or neither)")
    if not tls and root_certificates is None and certificate_chain is None:
        return None
    return grpc.ssl_channel_credentials(
        root_certificates=read_pem(root_certificates, "root_certificates", "CERTIFICATE"),
        private_key=read_pem(private_key, "private_key", "PRIVATE KEY"),
        certificate_chain=read_pem(certificate_chain, "certificate_chain", "CERTIFICATE"))


class _CallDetails(collections.namedtuple("_CallDetails", ("method", "timeout", "metadata", "credentials",
                                                           "wait_for_ready", "compression")),
                   grpc.ClientCallDetails):
    pass


class TokenInterceptor(grpc.UnaryUnaryClientInterceptor, grpc.UnaryStreamClientInterceptor,
                       grpc.StreamUnaryClientInterceptor, grpc.StreamStreamClientInterceptor):
    """Adds `authorization: Bearer <token>` to the metadata of every call."""

    def __init__(self, token: str):
        self._header = ("authorization", f"Bearer {token}")

    def __repr__(self) -> str:  # never show the token
        return "TokenInterceptor(<token>)"

    def _details(self, d: grpc.ClientCallDetails) -> _CallDetails:
        metadata = [m for m in (d.metadata or ()) if m[0].lower() != "authorization"] + [self._header]
        return _CallDetails(d.method, d.timeout, metadata, d.credentials, getattr(d, "wait_for_ready", None),
                            getattr(d, "compression", None))

    def intercept_unary_unary(self, continuation, client_call_details, request):
        return continuation(self._details(client_call_details), request)

    def intercept_unary_stream(self, continuation, client_call_details, request):
        return continuation(self._details(client_call_details), request)

    def intercept_stream_unary(self, continuation, client_call_details, request_iterator):
        return continuation(self._details(client_call_details), request_iterator)

    def intercept_stream_stream(self, continuation, client_call_details, request_iterator):
        return continuation(self._details(client_call_details), request_iterator)
