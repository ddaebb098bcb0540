"""The D435-like depth model: axial noise ∝ z², stereo occlusion shadows, the left band, edge dropouts."""

from __future__ import annotations

import numpy as np
import pytest

from kgn_bench.camera import REALSENSE
from kgn_bench.sim.depth_noise import DepthNoise, DexNoise, noise_model, occlusion_shadow, upsample_bilinear

FX = REALSENSE.fx
H, W = 120, 640


def _block_scene(near: float = 0.5, far: float = 1.0, cols: tuple[int, int] = (300, 400)) -> np.ndarray:
    """A wall at ``far`` with a block at ``near`` covering columns [cols) in the middle rows."""
    depth = np.full((H, W), far, dtype=np.float32)
    depth[40:80, cols[0]:cols[1]] = near
    return depth


def test_zero_strength_returns_the_depth_unchanged():
    depth = _block_scene()
    out = DepthNoise(0.0).apply(depth, FX, np.random.default_rng(0))
    np.testing.assert_array_equal(out, depth)
    assert out is not depth


def test_axial_noise_follows_the_intel_rms_model():
    noise = DepthNoise(1.0)
    for z in (0.5, 1.0):
        depth = np.full((200, W), z, dtype=np.float64)
        out = noise.apply(depth, FX, np.random.default_rng(1))
        err = out[:, 80:] - z  # right of the left band
        assert err.std() == pytest.approx(z**2 * 0.08 / (384.2 * 0.05), rel=0.05)
        assert abs(err.mean()) < 0.1 * err.std()
    assert noise.axial_sigma(1.0) / noise.axial_sigma(0.5) == pytest.approx(4.0)
    assert DepthNoise(2.0).axial_sigma(0.8) == pytest.approx(2 * noise.axial_sigma(0.8))


def test_shadow_lies_left_of_a_near_block_and_is_as_wide_as_the_disparity_step():
    depth = _block_scene(near=0.5, far=1.0)
    mask = occlusion_shadow(depth, FX, 0.05)
    row = mask[60]
    expected = FX * 0.05 * (1 / 0.5 - 1 / 1.0)  # 30.8 px
    shadow = np.nonzero(row[100:300])[0] + 100
    assert len(shadow) == pytest.approx(expected, abs=1.5)
    assert shadow.max() == 299  # it ends at the block's left edge
    assert not row[300:].any()  # the block and everything right of it are visible
    band = np.nonzero(mask[10])[0]  # a row without the block: only the left band
    assert band.max() + 1 == pytest.approx(FX * 0.05 / 1.0, abs=1.0) and band.min() == 0


def test_edge_dropouts_take_about_the_configured_fraction_of_edge_pixels():
    depth = _block_scene()
    right_edge = (slice(41, 79), slice(399, 401))  # both sides of the block's right edge, outside the shadow
    kept = [DepthNoise(s).apply(depth, FX, np.random.default_rng(2))[right_edge] > 0 for s in (1.0, 2.0)]
    assert 0.35 < 1 - kept[0].mean() < 0.65  # edge_dropout 0.5 at strength 1
    assert not kept[1].any()  # clipped to probability 1 at strength 2


def test_missing_pixels_stay_missing_and_the_draw_is_seeded():
    depth = _block_scene()
    depth[:, 600:] = 0.0
    a = DepthNoise(1.0).apply(depth, FX, np.random.default_rng(5))
    b = DepthNoise(1.0).apply(depth, FX, np.random.default_rng(5))
    np.testing.assert_array_equal(a, b)
    assert not a[:, 600:].any() and a.dtype == depth.dtype


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="strength"):
        DepthNoise(-1.0)
    with pytest.raises(ValueError, match="2-D float"):
        DepthNoise(1.0).apply(np.zeros((4, 4, 1), np.float32), FX, np.random.default_rng(0))


# -- GIGA's "dex" model -----------------------------------------------------------------------------------------


def test_dex_scale_factor_has_the_gamma_moments():
    """α ~ Gamma(1000, 0.001): mean 1, standard deviation √1000 · 0.001 = 3.16 %."""
    noise = DexNoise(gp_probability=0.0)
    flat = np.full((4, 4), 0.5)
    rng = np.random.default_rng(0)
    alphas = np.array([noise.apply(flat, 540.0, rng)[0, 0] / 0.5 for _ in range(4000)])
    assert abs(alphas.mean() - 1.0) < 0.002
    assert abs(alphas.std() - 0.0316) < 0.002
    once = noise.apply(flat, 540.0, rng)
    assert np.all(once == once[0, 0])  # one α for the whole image


def test_dex_field_is_smooth_and_present_in_about_half_the_images():
    noise = DexNoise(gamma_shape=1e12, gamma_scale=1e-12)  # α = 1: only the additive field is left
    depth = np.full((480, 640), 0.6)
    rng = np.random.default_rng(1)
    fields = [noise.apply(depth, 540.0, rng) - depth for _ in range(200)]
    with_field = [f for f in fields if f.std() > 1e-5]  # without the field, f = (α − 1)·z is constant
    assert 80 <= len(with_field) <= 120  # Binomial(200, 0.5): ±2.8 σ
    f = with_field[0]
    inner = f[8:-8, 8:-8]
    assert 0.002 < inner.std() < 0.005  # N(0, 5 mm) at the grid points, smoothed between them
    steps = np.diff(inner, axis=1)
    assert steps.std() < 0.4 * inner.std()  # neighbours are correlated: a field, not per-pixel noise


def test_dex_keeps_holes_and_repeats_with_the_seed():
    depth = np.full((48, 64), 0.7, dtype=np.float32)
    depth[10:20, 10:20] = 0.0
    a = DexNoise().apply(depth, 540.0, np.random.default_rng(5))
    b = DexNoise().apply(depth, 540.0, np.random.default_rng(5))
    assert a.dtype == np.float32 and np.array_equal(a, b)
    assert np.all(a[10:20, 10:20] == 0) and np.all(a[depth > 0] > 0)


def test_bilinear_upsampling_interpolates_between_grid_points():
    grid = np.array([[0.0, 1.0], [2.0, 3.0]])
    up = upsample_bilinear(grid, (4, 4))
    # Output pixel i samples the input at (i + 1/2)/2 - 1/2: 1 -> 0.25, 2 -> 0.75, 3 -> 1.25 (beyond the border,
    # where the grid is extended with zeros).
    assert up[1, 1] == pytest.approx(0.75 * 0.25 * 1.0 + 0.25 * 0.75 * 2.0 + 0.25 * 0.25 * 3.0)
    assert up[1, 2] == pytest.approx(0.75 * 0.75 * 1.0 + 0.25 * 0.25 * 2.0 + 0.25 * 0.75 * 3.0)
    assert up[0, 3] == pytest.approx(0.75 * 0.75 * 1.0)


def test_the_noise_models_a_task_can_name_are_the_ones_built():
    from kgn_bench.config import NOISE_MODELS

    assert noise_model("d435", 0.0) is None and noise_model("dex", 0.0) is None
    assert noise_model("d435", 1.5) == DepthNoise(1.5)
    assert isinstance(noise_model("dex", 1.0), DexNoise)
    for name in NOISE_MODELS:
        assert noise_model(name, 1.0) is not None
    with pytest.raises(ValueError, match="unknown depth noise model"):
        noise_model("kinect", 1.0)
