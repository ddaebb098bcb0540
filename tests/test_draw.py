import numpy as np

from kgn_bench.camera import REALSENSE
from kgn_bench.geometry import make_pose
from kgn_bench.viz.draw import colorize_depth, draw_grasps, show_view


def test_grasp_box_is_drawn_where_it_projects():
    img = np.zeros((480, 640, 3), np.uint8)
    # grasp 0.5 m in front of the camera, approach along +z (away from the camera), closing along x
    R = np.stack([[0, 0, 1], [0, -1, 0], [1, 0, 0]], axis=1)
    T = make_pose(R, [0.0, 0.0, 0.5])
    out = draw_grasps(img, T[None], np.array([0.1]), REALSENSE.K, (255, 0, 0))
    # L at x = +0.05 m projects 61.6 px right of the principal point; the box is drawn around there
    u_l = round(REALSENSE.cx + REALSENSE.fx * 0.05 / 0.5)
    v = round(REALSENSE.cy)
    assert out[v - 2 : v + 3, u_l - 2 : u_l + 3, 0].max() > 100
    assert out[v, int(REALSENSE.cx), 0] > 100  # the centre dot
    assert out[:, :, 1].max() == 0 and img.max() == 0  # input untouched, only red drawn


def test_colorize_depth_blacks_out_missing_pixels():
    d = np.zeros((10, 10), np.float32)
    d[:5] = np.linspace(0.5, 1.0, 10)
    img, (lo, hi) = colorize_depth(d)
    assert (lo, hi) == (0.5, 1.0)
    assert img[5:].max() == 0 and img[:5].max() > 0


def test_show_view_panels(tiny_dataset):
    root, _ = tiny_dataset
    img = show_view(root, 0, 0, box="fixed")
    assert img.shape == (480, 1280, 3)
