"""DepthStage on real frames: exact mode (our LUT, the paper MLP), paper mode, stability."""

import cv2
import numpy as np
import pytest
from tactile_force.edge.depth import DepthOptions, DepthStage, MappingError

from tests.conftest import shared_data


def frames():
    d = shared_data("aurova_digit_grasp")
    return {n: cv2.imread(str(d / "images" / f"{n}.png")) for n in (1500, 1508, 1516)}


def authors_depth(n):
    return cv2.imread(str(shared_data("aurova_digit_grasp", "filt_img_depth", f"depth_img_{n}.png")), cv2.IMREAD_GRAYSCALE)


def circle_mask(cy=160, cx=120, r=40):
    m = np.zeros((320, 240), np.uint8)
    cv2.circle(m, (cx, cy), r, 255, -1)
    return m


@pytest.fixture(scope="module")
def lut_stage(fots_lut_path):
    return DepthStage(DepthOptions(fots_lut_path))


def test_exact_lut_press_is_a_positive_dome(lut_stage):
    """A held-out real FOTS press (not in the LUT fit): depth peaks inside the circle."""
    from tactile_force.edge.depth.calibration import detect_press_circle

    img = cv2.imread(str(shared_data("fots_digit", "ball_presses", "0040.png")))
    c = detect_press_circle(img, lut_stage.lut.background)
    mask = circle_mask(int(c.cy), int(c.cx), int(c.r * 1.1))
    res = lut_stage.process(img, mask)
    assert res.ok and res.depth.shape == (320, 240, 1) and res.depth.dtype == np.uint8
    assert res.depth[mask == 0].max() == 0
    inner = res.height[int(c.cy) - 3:int(c.cy) + 4, int(c.cx) - 3:int(c.cx) + 4].mean()
    assert inner > 0.5 * res.height.max() > 0


def test_paper_mode_overlaps_authors_depth(paper_mlp_path):
    f = frames()
    st = DepthStage(DepthOptions(paper_mlp_path, mode="paper"))
    assert st.process(f[1516], None).ok is False  # no reference yet
    st.set_reference([f[1500]])  # the 1.08 N frame as zero-depth reference
    res = st.process(f[1516], None)
    ref = authors_depth(1516)
    inside = ref > 0
    ours = res.depth[..., 0].astype(float)
    region = ours > 0.1 * ours.max()
    iou = (region & inside).sum() / (region | inside).sum()
    corr = np.corrcoef(ours[inside], ref[inside])[0, 1]
    assert iou > 0.5 and corr > 0.5, (iou, corr)
    masked = st.process(f[1516], inside)
    assert masked.depth[~inside].max() == 0


def test_exact_mode_with_paper_mlp_runs_inside_mask_only(paper_mlp_path):
    st = DepthStage(DepthOptions(paper_mlp_path))
    m = authors_depth(1508) > 0
    res = st.process(frames()[1508], m)
    assert res.ok and res.depth[~m].max() == 0 and np.isfinite(res.height).all()


def test_paper_mode_refuses_a_lut(fots_lut_path):
    with pytest.raises(MappingError, match="paper mode"):
        DepthStage(DepthOptions(fots_lut_path, mode="paper"))


def test_bad_mapping_files(tmp_path):
    empty = tmp_path / "empty.npz"
    empty.write_bytes(b"")
    with pytest.raises(MappingError, match="truncated"):
        DepthStage(DepthOptions(empty))
    with pytest.raises(MappingError, match="not found"):
        DepthStage(DepthOptions(tmp_path / "missing.npz"))
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(MappingError, match="not a calibrate-depth file"):
        DepthStage(DepthOptions(tmp_path / "other.npz"))
    w = dict(np.load(shared_data("aurova_digit_depth_mlp.npz")))
    w["fc2.weight"] = w["fc2.weight"][:, :5]
    np.savez(tmp_path / "bad_mlp.npz", **w)
    with pytest.raises(MappingError, match="fc2"):
        DepthStage(DepthOptions(tmp_path / "bad_mlp.npz"))


def _cases(bg):
    sat = bg.copy()
    sat[100:220, 60:180] = 255
    nanf = bg.astype(np.float32)
    nanf[5, 5] = np.nan
    return {
        "all-dark": (np.zeros_like(bg), circle_mask(), False),
        "all-white": (np.full_like(bg, 255), circle_mask(), False),
        "saturated": (sat, circle_mask(), False),
        "NaN float frame": (nanf, circle_mask(), False),
        "landscape frame": (np.ascontiguousarray(bg.transpose(1, 0, 2)), circle_mask(), False),
        "empty mask": (bg, np.zeros((320, 240), np.uint8), False),
        "bad mask shape": (bg, np.zeros((240, 320), np.uint8), False),
        "full mask": (bg, np.full((320, 240), 255, np.uint8), True),
        "one-pixel contact": (bg, (np.arange(320 * 240).reshape(320, 240) == 160 * 240 + 120), True),
        "curved gel edge": (bg, circle_mask(5, 5, 30), True),
        "random colours": (np.random.default_rng(0).integers(0, 256, bg.shape, dtype=np.uint8), circle_mask(), True),
    }


@pytest.mark.parametrize("case", list(_cases(np.zeros((320, 240, 3), np.uint8))))
def test_stability_never_raises(case, lut_stage, paper_mlp_path):
    bg = lut_stage.lut.background
    frame, mask, expect_ok = _cases(bg)[case]
    for st in (lut_stage, DepthStage(DepthOptions(paper_mlp_path))):
        res = st.process(frame, mask)
        assert res.ok is expect_ok, (case, res.detail)
        assert res.depth.shape == (320, 240, 1) and res.depth.dtype == np.uint8
        if not expect_ok:
            assert res.detail and res.depth.max() == 0
        else:
            assert np.isfinite(res.height).all()
