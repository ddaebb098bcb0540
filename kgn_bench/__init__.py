"""KGN-Bench: KGNv2 keypoint grasp detection from RGB-D, its Primitive Shape dataset, and a simulated
closed-loop grasping benchmark in MuJoCo."""

import os as _os

from kgn_bench import kernels as _kernels

# Before any numerical library loads: every library's CPU dispatch capped at the portable x86-64-v3 set, so
# a run gives the same records on any x86-64 CPU with AVX2 (kgn_bench.kernels; KGN_BENCH_KERNELS=native
# lifts it).
_kernels.apply()

# Headless rendering by default: MuJoCo and PyOpenGL read these when first imported.
_os.environ.setdefault("MUJOCO_GL", "egl")
_os.environ.setdefault("PYOPENGL_PLATFORM", _os.environ["MUJOCO_GL"])

__version__ = "0.1.0"
