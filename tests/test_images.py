"""PNG output of RGB images."""

import cv2
import numpy as np
import pytest

from kgn_bench.viz.images import PALETTE_RGB, save_png


def test_save_png_round_trips_rgb(tmp_path):
    img = np.zeros((4, 5, 3), dtype=np.uint8)
    img[0, 0] = (255, 0, 0)
    save_png(tmp_path / "sub" / "a.png", img)
    back = cv2.cvtColor(cv2.imread(str(tmp_path / "sub" / "a.png")), cv2.COLOR_BGR2RGB)
    np.testing.assert_array_equal(back, img)
    with pytest.raises(ValueError, match="uint8"):
        save_png(tmp_path / "b.png", img.astype(float))


def test_palette_is_tab10():
    assert len(PALETTE_RGB) == 10 and PALETTE_RGB[0] == (31, 119, 180)
