"""Network input: resize/warp, standardisation, padding, and the image → input / output affines."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from kgn_bench.model.preprocess import (
    InputConfig,
    affine_for_crop,
    full_frame_affine,
    output_affine,
    prepare,
    standardize,
    warp_images,
    warp_inputs,
)
from kgn_bench.model.targets import apply_affine

H, W = 480, 640
CFG = InputConfig()


def _frame(rng, depth=0.8):
    rgb = rng.integers(0, 256, size=(H, W, 3), dtype=np.uint8)
    d = np.full((H, W), depth, dtype=np.float32)
    return rgb, d


def _unstandardize_red(x: np.ndarray) -> np.ndarray:
    return x[0] * CFG.std[0] + CFG.mean[0]


def _blob(center_uv, sigma=3.0, h=H, w=W) -> np.ndarray:
    """A Gaussian blob (uint8 RGB, peak 250) centred at a sub-pixel image position."""
    v, u = np.mgrid[0:h, 0:w]
    g = 250.0 * np.exp(-((u - center_uv[0]) ** 2 + (v - center_uv[1]) ** 2) / (2 * sigma**2))
    return np.repeat(np.round(g).astype(np.uint8)[..., None], 3, axis=2)


def _centroid(img: np.ndarray) -> np.ndarray:
    img = np.clip(img, 0, None)
    v, u = np.mgrid[0 : img.shape[0], 0 : img.shape[1]]
    return np.array([(u * img).sum(), (v * img).sum()]) / img.sum()


def test_prepare_shapes_padding_and_affine(rng):
    rgb, depth = _frame(rng)
    x, M, out_shape = prepare(rgb, depth)
    assert x.shape == (4, 256, 320) and x.dtype.is_floating_point
    assert out_shape == (60, 80)
    np.testing.assert_allclose(M, [[1 / 8, 0, -1 / 16], [0, 1 / 8, -1 / 16]])
    assert np.all(x[:, 240:, :].numpy() == 0.0)  # bottom padding is the neutral 0
    np.testing.assert_allclose(x[3, :240].numpy(), 0.0, atol=1e-6)  # depth at the mean standardises to 0


def test_prepare_maps_a_bright_square_to_M(rng):
    """The content of image pixel (u, v) lands at A_in @ (u, v, 1) in the input, i.e. 4·M @ (u, v, 1)."""
    rgb = np.zeros((H, W, 3), dtype=np.uint8)
    rgb[201:205, 333:337] = 255  # 4×4 square, centroid (334.5, 202.5)
    depth = np.ones((H, W), dtype=np.float32)
    x, M, _ = prepare(rgb, depth)
    red = _unstandardize_red(x.numpy())[:240, :320]  # the image region (the padding reads as the mean)
    centroid_in = _centroid(red)
    np.testing.assert_allclose(centroid_in, 4 * apply_affine(M, np.array([334.5, 202.5])), atol=1e-6)
    # a single pixel lands in the input pixel whose footprint contains its mapped centre
    for u, v in [(51, 100), (50, 101), (639, 479), (0, 0)]:
        rgb[:] = 0
        rgb[v, u] = 255
        red = _unstandardize_red(prepare(rgb, depth)[0].numpy())[:240, :320]
        x_in, y_in = 4 * apply_affine(M, np.array([u, v], dtype=float))
        assert abs(x_in - round(x_in)) <= 0.25 and abs(y_in - round(y_in)) <= 0.25
        assert np.unravel_index(np.argmax(red), red.shape) == (round(y_in), round(x_in))


def test_prepare_depth_nearest_standardised_and_invalid():
    rgb = np.zeros((H, W, 3), dtype=np.uint8)
    v, u = np.mgrid[0:H, 0:W]
    depth = (0.5 + 0.001 * u + 0.0001 * v).astype(np.float32)
    depth[:10, :] = 0.0  # no return
    x, _, _ = prepare(rgb, depth)
    d = x[3].numpy() * CFG.std[3] + CFG.mean[3]
    # nearest neighbour: σ = ½ takes source pixel (2u', 2v'), no mixed depths
    np.testing.assert_allclose(d[10:240, :], depth[20:480:2, 0:640:2], atol=1e-6)
    assert np.all(x[3, :5].numpy() == 0.0)  # invalid depth → standardised 0
    np.testing.assert_allclose(x[0, :240].numpy(), (0.0 - CFG.mean[0]) / CFG.std[0])


@pytest.mark.parametrize(
    ("rgb", "depth", "match"),
    [
        (np.zeros((H, W, 3), np.float32), np.ones((H, W), np.float32), "uint8"),
        (np.zeros((H, W), np.uint8), np.ones((H, W), np.float32), "uint8"),
        (np.zeros((H, W, 3), np.uint8), np.ones((H, W - 1), np.float32), "matching"),
        (np.zeros((H, W, 3), np.uint8), np.ones((H, W), np.uint16), "float"),
        (np.zeros((H, W, 3), np.uint8), np.full((H, W), np.nan, np.float32), "NaN"),
        (np.zeros((H, W, 3), np.uint8), np.zeros((H, W), np.float32), "no valid"),
        (np.zeros((H, W, 3), np.uint8), -np.ones((H, W), np.float32), "negative"),
    ],
)
def test_prepare_rejects_bad_inputs(rgb, depth, match):
    with pytest.raises(ValueError, match=match):
        prepare(rgb, depth)


def test_input_config_validation():
    with pytest.raises(ValueError, match="input_scale"):
        InputConfig(input_scale=0.0)
    with pytest.raises(ValueError, match="pad_multiple"):
        InputConfig(pad_multiple=16)
    with pytest.raises(ValueError, match="std"):
        InputConfig(std=(0.25, 0.25, 0.25, 0.0))
    x, M, out_shape = prepare(*_frame(np.random.default_rng(0)), InputConfig(input_scale=1.0))
    assert x.shape == (4, 480, 640) and out_shape == (120, 160)
    np.testing.assert_allclose(M, [[0.25, 0, 0], [0, 0.25, 0]])


def test_output_stride_two_halves_the_cell():
    """Stride 2 on the half-resolution input: one output cell is 4 image pixels (the paper's cell)."""
    frame = _frame(np.random.default_rng(0))
    x4, M4, shape4 = prepare(*frame)
    x2, M2, shape2 = prepare(*frame, stride=2)
    np.testing.assert_array_equal(x2.numpy(), x4.numpy())
    np.testing.assert_allclose(M2, 2.0 * M4)
    assert shape4 == (60, 80) and shape2 == (120, 160)
    np.testing.assert_allclose(apply_affine(M2, np.array([[4.0 * 9 + 0.5, 0.5]])), [[9.0, 0.0]])
    with pytest.raises(ValueError, match="output stride"):
        output_affine(full_frame_affine((W, H)), 3)


def test_warp_with_full_frame_affine_equals_prepare(rng):
    """Training warps reproduce the inference input on the image region."""
    rgb, depth = _frame(rng)
    depth[::7, ::5] = 0.0
    depth += rng.uniform(0.0, 0.3, size=depth.shape).astype(np.float32) * (depth > 0)
    x, M, _ = prepare(rgb, depth)
    A = full_frame_affine((W, H))
    np.testing.assert_allclose(output_affine(A), M)
    xw = warp_inputs(rgb, depth, A, (320, 256))
    np.testing.assert_allclose(xw[:3, :240, :320].numpy(), x[:3, :240].numpy(), atol=2.5 / 255 / 0.25)
    np.testing.assert_array_equal(xw[3, :240].numpy(), x[3, :240].numpy())


def test_crop_affine_centre_edges_and_output():
    A = affine_for_crop((300.0, 200.0), 384.0, (256, 256))
    np.testing.assert_allclose(apply_affine(A, np.array([300.0, 200.0])), [127.5, 127.5])
    # crop edges (pixel footprints) map onto the input's outer edges
    np.testing.assert_allclose(apply_affine(A, np.array([300.0 - 192.0, 200.0 + 192.0])), [-0.5, 255.5])
    np.testing.assert_allclose(output_affine(A), A / 4)
    R = affine_for_crop((319.5, 239.5), (640.0, 480.0), (320, 240))  # the whole frame, rectangular
    np.testing.assert_allclose(R, full_frame_affine((W, H)))
    with pytest.raises(ValueError, match="crop_size"):
        affine_for_crop((0.0, 0.0), -1.0, (64, 64))
    with pytest.raises(ValueError, match="singular"):
        output_affine(np.zeros((2, 3)))


@pytest.mark.parametrize(("side", "flip"), [(300.0, False), (300.0, True), (900.0, False), (500.0, True)])
def test_crop_affine_moves_content_like_warp(side, flip):
    """A blob at image point p appears at A @ p in the warped input, zoomed in or out, mirrored or not."""
    p = np.array([351.3, 217.6])
    rgb = _blob(p)
    depth = np.ones((H, W), dtype=np.float32)
    A = affine_for_crop((330.0, 230.0), side, (256, 192), flip=flip)
    black_border = InputConfig(mean=(0.0, 0.0, 0.0, 0.8))  # the border is the RGB mean: make it black here
    rgb_w, _ = warp_images(rgb, depth, A, (256, 192), black_border)
    assert rgb_w.shape == (192, 256, 3) and rgb_w.dtype == np.float32
    np.testing.assert_allclose(_centroid(rgb_w[..., 0]), apply_affine(A, p), atol=0.05)


def test_flip_is_mirror_of_warp(rng):
    rgb, depth = _frame(rng)
    depth += rng.uniform(0.0, 0.3, size=depth.shape).astype(np.float32)
    a = affine_for_crop((310.0, 250.0), 400.0, (128, 96))
    af = affine_for_crop((310.0, 250.0), 400.0, (128, 96), flip=True)
    rgb_a, d_a = warp_images(rgb, depth, a, (128, 96))
    rgb_f, d_f = warp_images(rgb, depth, af, (128, 96))
    np.testing.assert_allclose(rgb_f, cv2.flip(rgb_a, 1), atol=1e-3)
    np.testing.assert_array_equal(d_f, cv2.flip(d_a, 1))


def test_zoomed_out_crop_border_is_neutral(rng):
    rgb, depth = _frame(rng)
    x = warp_inputs(rgb, depth, affine_for_crop((320.0, 240.0), 1280.0, (128, 128)), (128, 128)).numpy()
    assert x.shape == (4, 128, 128)
    np.testing.assert_allclose(x[:, :10, :10], 0.0, atol=1e-6)  # outside the image: RGB mean, invalid depth
    assert np.abs(x[0, 60:68, 60:68]).max() > 0.1  # the image itself is there (anti-aliased, not flat)


def test_standardize_constants():
    rgb = np.full((2, 3, 3), 255, dtype=np.uint8)
    depth = np.array([[0.0, 1.0, 0.8], [0.6, 0.0, 1.2]], dtype=np.float32)
    x = standardize(rgb, depth)
    np.testing.assert_allclose(x[:3], (1.0 - 0.5) / 0.25)
    np.testing.assert_allclose(x[3], [[0.0, 1.0, 0.0], [-1.0, 0.0, 2.0]], atol=1e-6)
