"""Offscreen RGB-D and instance-mask rendering of a scene with MuJoCo's OpenGL renderer.

Two passes per view: a shaded pass for RGB, and a flat-colour segmentation pass whose colour buffer
gives the geom under each pixel and whose depth buffer gives the depth (one pass for both saves a
render). Depth is planar z in metres, 0 where nothing was hit. ``MUJOCO_GL`` defaults to ``egl``
(set in ``kgn_bench/__init__.py`` before MuJoCo is imported). Shadows and reflections are off.
Call ``close()`` (or use the renderer as a context manager) to release the GL context.
"""

from __future__ import annotations

import os

import mujoco
import numpy as np

from kgn_bench.sim.scene import GROUP_ROBOT, GROUP_VISUAL, Scene
from kgn_bench.types import RGBD

__all__ = ["RGBD", "SceneRenderer"]


def _gl_context(width: int, height: int):
    """An offscreen GL context for the backend named by ``MUJOCO_GL`` (egl, osmesa or glfw; default egl).

    Chosen here rather than through ``mujoco.GLContext`` so that the default holds even when MuJoCo was
    imported before ``kgn_bench``.
    """
    backend = os.environ.get("MUJOCO_GL", "egl").lower()
    if backend == "egl":
        from mujoco.egl import GLContext
    elif backend == "osmesa":
        from mujoco.osmesa import GLContext
    elif backend == "glfw":
        from mujoco.glfw import GLContext
    else:
        raise RuntimeError(f"unsupported MUJOCO_GL={backend!r}; use egl, osmesa or glfw")
    return GLContext(width, height)


class SceneRenderer:
    """Renders the scene camera of one compiled ``Scene`` at its intrinsics."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        m = scene.model
        self.width, self.height = scene.intrinsics.width, scene.intrinsics.height
        self._gl = _gl_context(self.width, self.height)
        self._gl.make_current()
        self._ctx = mujoco.MjrContext(m, mujoco.mjtFontScale.mjFONTSCALE_50)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._ctx)
        self._ctx.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZERONEAR
        self._mjv_scene = mujoco.MjvScene(m, maxgeom=max(1000, 2 * m.ngeom))
        self._mjv_scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
        self._mjv_scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
        self._option = mujoco.MjvOption()
        self._option.geomgroup[:] = 0
        self._option.geomgroup[GROUP_VISUAL] = 1
        self._option.geomgroup[GROUP_ROBOT] = 1
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._camera.fixedcamid = scene.camera_id
        self._rect = mujoco.MjrRect(0, 0, self.width, self.height)
        self._rgb = np.empty((self.height, self.width, 3), dtype=np.uint8)
        self._ids = np.empty((self.height, self.width, 3), dtype=np.uint8)
        self._zbuf = np.empty((self.height, self.width), dtype=np.float32)
        extent = m.stat.extent
        self._near = float(m.vis.map.znear * extent)
        self._far = float(m.vis.map.zfar * extent)
        self._last_geoms: tuple[np.ndarray, np.ndarray] | None = None

    def __enter__(self) -> SceneRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        if self._ctx is not None:
            self._ctx.free()
            self._ctx = None
        if self._gl is not None:
            self._gl.free()
            self._gl = None

    def render(self, camera_pose: np.ndarray) -> RGBD:
        """Render from an OpenCV camera-to-world pose."""
        if self._ctx is None:
            raise RuntimeError("renderer is closed")
        self.scene.set_camera_pose(camera_pose)
        self._gl.make_current()
        m, d, scn = self.scene.model, self.scene.data, self._mjv_scene
        mujoco.mjv_updateScene(m, d, self._option, None, self._camera, mujoco.mjtCatBit.mjCAT_ALL, scn)
        mujoco.mjr_render(self._rect, scn, self._ctx)
        mujoco.mjr_readPixels(self._rgb, None, self._rect, self._ctx)
        rgb = np.flipud(self._rgb).copy()

        scn.flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = 1
        scn.flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = 1
        try:
            mujoco.mjr_render(self._rect, scn, self._ctx)
            mujoco.mjr_readPixels(self._ids, self._zbuf, self._rect, self._ctx)
        finally:
            scn.flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = 0
            scn.flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = 0
        ids = np.flipud(self._ids)
        ids = ids.astype(np.int32)
        segid = ids[..., 0] | (ids[..., 1] << 8) | (ids[..., 2] << 16)
        # segid 0 is background; segid k > 0 is the (k − 1)-th geom of the abstract scene
        seg_to_label = np.zeros(scn.ngeom + 1, dtype=np.uint8)
        seg_to_geom = np.full(scn.ngeom + 1, -1, dtype=np.int32)
        for k in range(scn.ngeom):
            g = scn.geoms[k]
            if g.objtype == mujoco.mjtObj.mjOBJ_GEOM and g.segid >= 0:
                seg_to_label[g.segid + 1] = self.scene.geom_label[g.objid]
                seg_to_geom[g.segid + 1] = g.objid
        segid = np.clip(segid, 0, scn.ngeom)
        self._last_geoms = (segid, seg_to_geom)
        mask = seg_to_label[segid]
        depth = self._linear_depth(np.flipud(self._zbuf))
        depth[segid == 0] = 0.0
        return RGBD(rgb=rgb, depth=depth, mask=mask)

    def last_geom_ids(self) -> np.ndarray:
        """(H, W) int32: the model geom id under each pixel of the last ``render`` (−1 where nothing was hit)."""
        if self._last_geoms is None:
            raise RuntimeError("nothing rendered yet")
        segid, seg_to_geom = self._last_geoms
        return seg_to_geom[segid]

    def _linear_depth(self, zbuf: np.ndarray) -> np.ndarray:
        """Metric planar depth from the depth buffer read with ``mjDEPTH_ZERONEAR`` (0 at near, 1 at far).

        For a perspective frustum with near n and far f the buffer holds ``b = (1/n − 1/z) / (1/n − 1/f)``
        for a point at depth z, so ``z = n f / (f − b (f − n))``.
        """
        n, f = self._near, self._far
        b = zbuf.astype(np.float64)
        return (n * f / (f - b * (f - n))).astype(np.float32)
