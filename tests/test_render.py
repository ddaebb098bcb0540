"""Real MuJoCo rendering against the pinhole model: projection ≤ 0.5 px, back-projection ≤ 1 mm."""

import numpy as np
import pytest

from kgn_bench.camera import REALSENSE, orbit_pose
from kgn_bench.geometry import backproject, invert_pose, make_pose, project, transform_points
from kgn_bench.shapes.primitives import Cuboid, Sphere, Stick
from kgn_bench.sim.render import SceneRenderer
from kgn_bench.sim.scene import Scene, SceneObject

CAMERAS = [orbit_pose(0.7, np.deg2rad(90), 0.4), orbit_pose(0.9, np.deg2rad(40), 2.0)]


@pytest.mark.parametrize("cam", CAMERAS)
def test_disc_centres_render_where_K_projects_them(cam):
    # Thin discs facing the camera: a disc parallel to the image plane images as a circle centred
    # exactly on the projection of its centre, so the mask centroid measures the projection.
    centres = np.array(
        [[0.0, 0.0, 0.05], [0.12, 0.05, 0.02], [-0.15, -0.1, 0.1], [0.1, -0.17, 0.04], [-0.2, 0.15, 0.08]]
    )
    objects = [SceneObject(Stick(0.015, 0.0004), (1.0, 0.0, 0.0), make_pose(cam[:3, :3], c)) for c in centres]
    scene = Scene(objects)
    with SceneRenderer(scene) as r:
        view = r.render(cam)
    expected = project(transform_points(invert_pose(cam), centres), REALSENSE.K)
    for i, uv in enumerate(expected):
        v, u = np.nonzero(view.mask == i + 1)
        assert len(u) > 100
        centroid = np.array([u.mean(), v.mean()])
        assert np.linalg.norm(centroid - uv) < 0.5, (i, centroid, uv)


def test_depth_back_projects_onto_the_true_surfaces():
    box = Cuboid((0.08, 0.06, 0.05))
    ball = Sphere(0.04)
    objects = [
        SceneObject(box, (0.8, 0.2, 0.2), make_pose(t=[0.05, 0.03, 0.025])),
        SceneObject(ball, (0.2, 0.2, 0.8), make_pose(t=[-0.08, -0.05, 0.04])),
    ]
    scene = Scene(objects)
    cam = orbit_pose(0.75, np.deg2rad(55), 0.9)
    with SceneRenderer(scene) as r:
        view = r.render(cam)
    assert view.rgb.shape == (480, 640, 3) and view.rgb.dtype == np.uint8
    assert view.depth.dtype == np.float32 and view.mask.dtype == np.uint8
    pts = transform_points(cam, backproject(view.depth, REALSENSE.K))
    table = (view.mask == 0) & (view.depth > 0)
    assert table.sum() > 10000
    assert np.abs(pts[table][:, 2]).max() < 1e-3
    on_box = transform_points(invert_pose(objects[0].pose), pts[view.mask == 1])
    surf = np.max(np.abs(on_box) - np.array(box.size) / 2, axis=1)
    assert np.abs(surf).max() < 1e-3
    on_ball = pts[view.mask == 2] - objects[1].pose[:3, 3]
    assert np.abs(np.linalg.norm(on_ball, axis=1) - ball.r).max() < 1e-3
    # beyond the table edge nothing returns
    assert np.all(view.depth[view.mask == 0][~table[view.mask == 0]] == 0)


def test_closed_renderer_refuses_to_render():
    scene = Scene([SceneObject(Sphere(0.03), (1, 1, 1), make_pose(t=[0, 0, 0.03]))])
    r = SceneRenderer(scene)
    r.close()
    with pytest.raises(RuntimeError):
        r.render(CAMERAS[0])
