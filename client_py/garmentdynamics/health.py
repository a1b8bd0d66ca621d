"""A minimal client of the standard gRPC health service (grpc.health.v1.Health/Check).

The two messages are tiny, so they are encoded by hand rather than adding a dependency:
HealthCheckRequest {string service = 1} and HealthCheckResponse {ServingStatus status = 1}
with SERVING = 1. A gd-server with --auth-token-file answers it without a token.
"""

import grpc

SERVING = 1
_METHOD = "/grpc.health.v1.Health/Check"


def _encode_request(service: str) -> bytes:
    data = service.encode()
    if not data:
        return b""
    if len(data) > 127:
        raise ValueError("service name too long")
    return b"\x0a" + bytes([len(data)]) + data


def _decode_status(data: bytes) -> int:
    """The `status` field of a HealthCheckResponse (0 = UNKNOWN when absent)."""
    i = 0
    while i < len(data):
        key = data[i]
        i += 1
        if key != 0x08:  # only field 1 (varint) is expected
            break
        value, shift = 0, 0
        while i < len(data):
            b = data[i]
            i += 1
            value |= (b & 0x7F) << shift
            shift += 7
            if not b & 0x80:
                break
        return value
    return 0


def check(channel: grpc.Channel, service: str = "", timeout: float = 5.0) -> int:
    """The serving status of `service` ("" = the whole server); raises grpc.RpcError."""
    call = channel.unary_unary(_METHOD, request_serializer=_encode_request,
                               response_deserializer=_decode_status)
    return call(service, timeout=timeout)


def is_serving(channel: grpc.Channel, timeout: float = 2.0) -> bool:
    """True when the server answers SERVING; False while it is unreachable or not serving yet."""
    try:
        return check(channel, timeout=timeout) == SERVING
    except grpc.RpcError as err:
        if err.code() == grpc.StatusCode.UNIMPLEMENTED:
            raise RuntimeError("the server has no gRPC health service") from None
        return False
