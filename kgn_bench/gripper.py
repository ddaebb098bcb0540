"""Gripper dimensions: the one source for the MJCF gripper, the labelling proxy and the selector.

All lengths in metres, expressed in the grasp frame (``kgn_bench.grasp``): origin at the fingertip midpoint,
+x = approach (the gripper body lies at x < 0), z = closing axis with the left finger at +z, y = z × x.

The physical gripper is three boxes in that frame, for a jaw opening ``w``:

- left finger  ``x ∈ [−finger_length, 0]``, ``|y| ≤ finger_breadth/2``, ``z ∈ [w/2, w/2 + finger_thickness]``
- right finger the mirror image at ``z ∈ [−w/2 − finger_thickness, −w/2]``
- palm         ``x ∈ [−finger_length − palm_depth, −finger_length]``, ``|y| ≤ palm_breadth/2``,
  ``|z| ≤ palm_half_span`` (wide enough to hold both fingers fully open)

The fingertips lie in the plane ``x = 0``, so the TCP (the grasp origin) is exactly their midpoint.
The wrist flange sits at ``x = −tcp_offset`` on the approach axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["GRIPPER", "GRIPPERS", "PANDA_HAND", "GripperBox", "GripperGeometry", "box_corners"]


@dataclass(frozen=True)
class GripperBox:
    """An axis-aligned box in the grasp frame: ``name``, ``centre`` (3,) and ``half`` extents (3,)."""

    name: str
    centre: np.ndarray
    half: np.ndarray

    def swept(self, back: float) -> GripperBox:
        """The volume this box covers moving from ``back`` m behind (along −x, against the approach) to its
        place: the gripper's path on a straight approach from the pre-grasp."""
        along = np.array([back / 2.0, 0.0, 0.0])
        return GripperBox(self.name, self.centre - along, self.half + along)


@dataclass(frozen=True)
class GripperGeometry:
    """Dimensions of the parallel-jaw gripper and of its labelling proxy.

    The proxy used to label ground-truth grasps (as in the reference implementation) is a solid box occupying
    ``x ∈ [−proxy_depth, 0]``, ``|y| ≤ proxy_thickness / 2`` and ``|z| ≤ w/2 + proxy_clearance`` in the
    grasp frame, for a grasp of width ``w``: it covers the fingers, the palm and the space between them.
    """

    proxy_depth: float = 0.10
    proxy_thickness: float = 0.02
    proxy_clearance: float = 0.02

    max_width: float = 0.20
    """Largest jaw opening (m); every PS grasp family width (≤ 0.192 m) fits."""
    finger_length: float = 0.07
    finger_thickness: float = 0.01
    finger_breadth: float = 0.018
    palm_depth: float = 0.04
    palm_breadth: float = 0.05
    finger_mass: float = 0.03
    palm_mass: float = 0.73
    wrist_length: float = 0.12
    wrist_radius: float = 0.045
    """The arm's last link behind the flange (a capsule of this radius), as the selector sees it."""
    grip_force: float = 40.0
    """Force limit (N) of the closing servo; each finger pushes with half of it."""
    grip_stiffness: float = 10000.0
    """Closing servo gain (N per m of the half-opening tendon's error). The servo's force is
    ``min(grip_stiffness · w / 2, grip_force)`` on an object of width ``w`` when commanded shut, so this gain
    makes the force limit, not the object, set the squeeze for every ``w`` ≥ 8 mm (a real gripper's grasp
    command; at 1000 N/m a 12 mm rim got 6 N and the jaws stalled on it)."""
    grip_damping: float = 100.0
    """Closing servo damping (N·s/m of tendon speed)."""
    open_margin: float = 0.01
    """How much wider than a grasp's width (m) the jaws open before the approach."""
    palm_extra_span: float = 0.005
    """How far (m) the palm reaches past each fully open finger along the closing axis."""

    def opening(self, width: float | np.ndarray) -> float | np.ndarray:
        """The jaw opening used for a grasp of ``width``: ``min(width + open_margin, max_width)``."""
        return np.minimum(np.asarray(width) + self.open_margin, self.max_width)

    @property
    def tcp_offset(self) -> float:
        """Distance from the wrist flange to the TCP along the approach axis."""
        return self.finger_length + self.palm_depth

    @property
    def palm_half_span(self) -> float:
        """Half the palm's extent along the closing axis: the open fingers plus ``palm_extra_span``."""
        return self.max_width / 2.0 + self.finger_thickness + self.palm_extra_span

    @property
    def finger_travel(self) -> float:
        """Stroke of each finger's slide joint: the jaw opening is twice the finger position."""
        return self.max_width / 2.0

    # -- physical boxes ------------------------------------------------------------------------
    def finger_box(self, side: int, width: float) -> GripperBox:
        """Finger box for ``side`` +1 (left, +z) or −1 (right) at jaw opening ``width``."""
        half = np.array([self.finger_length / 2.0, self.finger_breadth / 2.0, self.finger_thickness / 2.0])
        centre = np.array([-self.finger_length / 2.0, 0.0, side * (width / 2.0 + self.finger_thickness / 2.0)])
        return GripperBox("left_finger" if side > 0 else "right_finger", centre, half)

    def palm_box(self) -> GripperBox:
        half = np.array([self.palm_depth / 2.0, self.palm_breadth / 2.0, self.palm_half_span])
        return GripperBox("palm", np.array([-self.finger_length - self.palm_depth / 2.0, 0.0, 0.0]), half)

    def wrist_box(self) -> GripperBox:
        """A box bounding the wrist (the last arm link) behind the flange."""
        r = self.wrist_radius
        half = np.array([self.wrist_length / 2.0, r, r])
        return GripperBox("wrist", np.array([-self.tcp_offset - self.wrist_length / 2.0, 0.0, 0.0]), half)

    def boxes(self, width: float) -> list[GripperBox]:
        """The solid boxes at jaw opening ``width``: left finger, right finger, palm, wrist."""
        return [self.finger_box(+1, width), self.finger_box(-1, width), self.palm_box(), self.wrist_box()]

    def closing_region(self, width: float) -> GripperBox:
        """The space swept by the finger faces when closing from ``width``: what a grasp must enclose."""
        half = np.array([self.finger_length / 2.0, self.finger_breadth / 2.0, width / 2.0])
        return GripperBox("closing_region", np.array([-self.finger_length / 2.0, 0.0, 0.0]), half)

    # -- labelling proxy -----------------------------------------------------------------------
    def proxy_half_extents(self, width: float | np.ndarray) -> np.ndarray:
        """Half extents (..., 3) of the proxy box along the grasp frame's x, y, z axes."""
        w = np.asarray(width, dtype=float)
        hx = np.full_like(w, self.proxy_depth / 2.0)
        hy = np.full_like(w, self.proxy_thickness / 2.0)
        hz = w / 2.0 + self.proxy_clearance
        return np.stack([hx, hy, hz], axis=-1)

    @property
    def proxy_centre(self) -> np.ndarray:
        """Centre of the proxy box in the grasp frame: ``(−proxy_depth/2, 0, 0)``."""
        return np.array([-self.proxy_depth / 2.0, 0.0, 0.0])

    def proxy_corners(self, poses: np.ndarray, widths: np.ndarray) -> np.ndarray:
        """The 8 corners (N, 8, 3) of the proxy boxes of grasps ``poses`` (N, 4, 4), in the poses' frame."""
        local = self.proxy_centre + _BOX_SIGNS[None] * self.proxy_half_extents(widths)[:, None, :]
        return np.einsum("nij,nkj->nki", poses[:, :3, :3], local) + poses[:, None, :3, 3]


_BOX_SIGNS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)


def box_corners(box: GripperBox, poses: np.ndarray) -> np.ndarray:
    """The 8 corners (N, 8, 3) of a grasp-frame ``box`` placed at each of ``poses`` (N, 4, 4)."""
    local = box.centre + _BOX_SIGNS * box.half
    return np.einsum("nij,kj->nki", poses[:, :3, :3], local) + poses[:, None, :3, 3]


GRIPPER = GripperGeometry()
"""The benchmark's gripper: a 20 cm opening, carried by the arm."""

PANDA_HAND = GripperGeometry(
    max_width=0.08, finger_length=0.05, finger_thickness=0.012, finger_breadth=0.02, palm_depth=0.0584,
    palm_breadth=0.065, palm_extra_span=0.05, finger_mass=0.1, palm_mass=0.81, wrist_length=0.0,
    wrist_radius=0.0, grip_force=40.0, open_margin=0.0)
"""The Franka Emika Panda hand as VGN and GIGA simulate it: 8 cm maximum opening, 5 cm finger depth (the
fingers' length past the palm), the hand body 5.84 cm deep and about 20 cm across the closing axis, 20 N per
finger. It floats free (``execution.hand = "floating"``), so it has no wrist behind it (``wrist_length`` 0),
and it always opens fully before a grasp (``open_margin`` 0 and ``sim.floating_hand`` opens to
``max_width``)."""

GRIPPERS: dict[str, GripperGeometry] = {"default": GRIPPER, "panda": PANDA_HAND}
"""The grippers a task can name (``[execution] gripper``)."""
