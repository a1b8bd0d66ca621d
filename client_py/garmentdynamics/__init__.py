"""Python client of the GarmentDynamics cloth simulation service.

- `Client`: numpy in and out over gRPC; a context manager; `Client.spawn()` starts a local gd-server.
  Robot mode (two URDF arms driven by joints or poses): `create_scenes(mode="robot", urdf=...)`.
  Servers with tokens and TLS: `Client(target, token_file=..., root_certificates=...)`
  (garmentdynamics.credentials; $GD_TOKEN_FILE names a token file by default).
- `garmentdynamics.envs`: Gymnasium environments (one scene, or a VectorEnv over many); needs the
  `[gym]` extra.
- `rgbench_garmentdynamics.GarmentDynamicsEnv` (a separate top-level package of this
  distribution): RGBench's simulator interface on top of a gd-server.
"""

from .actions import arm_array_to_action, joint_array_to_action, scene_action
from .arrays import from_array, to_array
from .client import FINAL_JOB_STATUSES, Client, SceneState, job_to_dict, read_urdf
from .credentials import read_token_file
from .local_server import LocalServer, find_server_binary

__version__ = "0.1.0"

__all__ = ["Client", "SceneState", "LocalServer", "find_server_binary", "to_array", "from_array",
           "scene_action", "arm_array_to_action", "joint_array_to_action", "read_urdf", "job_to_dict",
           "FINAL_JOB_STATUSES", "read_token_file", "__version__"]
