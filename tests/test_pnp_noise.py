"""The Fig. 2 PnP-noise study: exact recovery without noise, the distance trend, what normalising removes."""

from __future__ import annotations

import numpy as np
import pytest

from kgn_bench.eval.pnp_noise import (
    PnpNoiseConfig,
    PnpNoiseRow,
    random_rotations,
    rows_to_csv,
    run_pnp_noise,
)


def _cell(rows: list[PnpNoiseRow], box: str, sigma: float, d: float) -> PnpNoiseRow:
    (row,) = [r for r in rows if r.box == box and r.sigma_px == sigma and r.distance_m == d]
    return row


@pytest.fixture(scope="module")
def rows() -> list[PnpNoiseRow]:
    return run_pnp_noise(PnpNoiseConfig(distances=(0.3, 0.9, 1.5), sigmas=(0.0, 2.0), samples=400, seed=3))


def test_random_rotations_are_uniform_rotations():
    R = random_rotations(4000, np.random.default_rng(0))
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    # Haar measure: E[R] = 0 and each column is uniform on the sphere.
    assert np.abs(R.mean(axis=0)).max() < 0.05


def test_no_noise_recovers_every_pose_exactly(rows):
    for box in ("fixed", "scale_normalized"):
        for d in (0.3, 0.9, 1.5):
            r = _cell(rows, box, 0.0, d)
            assert r.failures == 0 and r.samples == 400
            assert r.rot_mean_deg < 1e-3 and r.trans_mean_cm < 1e-3


def test_fixed_box_error_grows_with_distance(rows):
    near, mid, far = (_cell(rows, "fixed", 2.0, d) for d in (0.3, 0.9, 1.5))
    assert near.rot_median_deg < mid.rot_median_deg < far.rot_median_deg
    assert near.trans_median_cm < mid.trans_median_cm < far.trans_median_cm
    assert far.trans_median_cm > 3 * near.trans_median_cm


def test_normalised_box_rotation_error_does_not_depend_on_distance(rows):
    rot = [_cell(rows, "scale_normalized", 2.0, d).rot_median_deg for d in (0.3, 0.9, 1.5)]
    assert max(rot) - min(rot) < 0.05 * max(rot)


def test_normalising_with_the_true_scale_removes_most_translation_error(rows):
    for d in (0.9, 1.5):
        fixed, norm = _cell(rows, "fixed", 2.0, d), _cell(rows, "scale_normalized", 2.0, d)
        assert norm.trans_median_cm < 0.25 * fixed.trans_median_cm


def test_csv_has_a_header_and_one_line_per_cell(rows):
    lines = rows_to_csv(rows).splitlines()
    assert lines[0].split(",")[:3] == ["box", "sigma_px", "distance_m"]
    assert len(lines) == 1 + len(rows) == 1 + 2 * 2 * 3


def test_bad_config_is_refused():
    with pytest.raises(ValueError, match="distances"):
        PnpNoiseConfig(distances=(0.0, 1.0))
    with pytest.raises(ValueError, match="noise"):
        PnpNoiseConfig(sigmas=(-1.0,))
    with pytest.raises(ValueError, match="samples"):
        PnpNoiseConfig(samples=0)
