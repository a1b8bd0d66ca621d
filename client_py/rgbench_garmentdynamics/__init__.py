"""RGBench's simulator slot for GarmentDynamics: `from rgbench_garmentdynamics import
GarmentDynamicsEnv` is what RGBench's rgbench.envs.get_env imports for an env named
"garment_dynamics" (or "mujoco_style3d"). See env.py for the configuration it reads."""

from .env import GarmentDynamicsEnv, cfg_get
from .trajectory import JointTrack, PoseTrack, load_joint_csv, load_pose_csv

__all__ = ["GarmentDynamicsEnv", "PoseTrack", "JointTrack", "load_pose_csv", "load_joint_csv", "cfg_get"]
