"""The generated protobuf and gRPC modules, with a clear error when they were never generated."""

try:
    from garmentdynamics.v1 import garmentdynamics_pb2 as pb
    from garmentdynamics.v1 import garmentdynamics_pb2_grpc as pb_grpc
except ImportError as exc:  # pragma: no cover - only in a broken install
    raise ImportError(
        "garmentdynamics: the gRPC stubs are missing; install the package with "
        "`pip install ./client_py` (or `pip install -e ./client_py`), which generates them from "
        "proto/") from exc

__all__ = ["pb", "pb_grpc"]
