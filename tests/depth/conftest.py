"""Fixtures of the depth tests: real mapping files from ../shared/data, built once."""

import pytest

from tests.conftest import shared_data


@pytest.fixture(scope="session")
def paper_mlp_path():
    return shared_data("aurova_digit_depth_mlp.npz")


@pytest.fixture(scope="session")
def fots_lut_path(tmp_path_factory):
    """Our LUT calibrated on the real FOTS DIGIT ball presses (circles detected)."""
    import cv2
    from tactile_force.edge.depth.calibration import LUTOptions, Press, detect_press_circle, fit_lut

    folder = shared_data("fots_digit", "ball_presses")
    bg = cv2.imread(str(shared_data("digit_backgrounds", "fots_digit_bg.png")))
    presses = []
    for f in sorted(folder.glob("*.png"))[:24]:
        img = cv2.imread(str(f))
        c = detect_press_circle(img, bg)
        if c is not None:
            presses.append(Press(img, c, f.name))
    lut = fit_lut(presses, bg, 2.35 * 19.58, LUTOptions())
    return lut.save(tmp_path_factory.mktemp("lut") / "fots_lut.npz")
