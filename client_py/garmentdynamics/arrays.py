"""numpy <-> the proto `Array` (bytes + dtype + shape, little-endian, row-major)."""

import numpy as np

from ._proto import pb

_DTYPES = {"float32": np.dtype("<f4"), "int32": np.dtype("<i4")}


def to_array(a, dtype="float32") -> "pb.Array":
    """Packs an array-like as a proto Array of `dtype` ("float32" or "int32")."""
    if dtype not in _DTYPES:
        raise ValueError(f"dtype must be one of {sorted(_DTYPES)}, got {dtype!r}")
    arr = np.ascontiguousarray(np.asarray(a), dtype=_DTYPES[dtype])
    return pb.Array(dtype=dtype, shape=list(arr.shape), data=arr.tobytes())


def from_array(msg: "pb.Array") -> np.ndarray:
    """Unpacks a proto Array into a new native-endian numpy array (float32 or int32)."""
    if not msg.dtype and not msg.shape and not msg.data:
        return np.zeros((0,), dtype=np.float32)
    if msg.dtype not in _DTYPES:
        raise ValueError(f"unsupported Array dtype {msg.dtype!r} (expected float32 or int32)")
    dt = _DTYPES[msg.dtype]
    shape = tuple(int(s) for s in msg.shape)
    count = int(np.prod(shape)) if shape else 0
    if len(msg.data) != count * dt.itemsize:
        raise ValueError(f"Array of shape {shape} and dtype {msg.dtype} should hold "
                         f"{count * dt.itemsize} bytes, got {len(msg.data)}")
    return np.frombuffer(msg.data, dtype=dt).astype(dt.newbyteorder("="), copy=True).reshape(shape)
