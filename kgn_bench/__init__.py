"""KGN-Bench: KGNv2 keypoint grasp detection from RGB-D, its Primitive Shape dataset, and a simulated
closed-loop grasping benchmark in MuJoCo."""

import os as _os

# Headless rendering by default: MuJoCo and PyOpenGL read these when first imported.
_os.environ.setdefault("MUJOCO_GL", "egl")
_os.environ.setdefault("PYOPENGL_PLATFORM", _os.environ["MUJOCO_GL"])

__version__ = "0.1.0"
