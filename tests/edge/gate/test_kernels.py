"""The gate's compiled kernels (edge/gate/kernels.py, through edge/gate/frame_work.py) equal the OpenCV
calls they replace (tests/edge/gate/oracle.py) bit for bit: per kernel on random images of many
shapes (odd ones included) and on real frames, and the whole gate's results over sequences."""

from __future__ import annotations

import contextlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from tactile_force.edge import compiled_path
from tactile_force.edge.gate import ContactGate, GateOptions
from tactile_force.edge.gate import kernels as K
from tactile_force.edge.gate.frame_work import FrameWork

from tests.conftest import compiled_kernels, shared_data
from tests.edge.gate.oracle import OracleGate, blur_cv, changed_cv, fit_cv, noise_cv, reduce_cv, residual_cv


@pytest.fixture(autouse=True, scope="module")
def _kernels():
    compiled_kernels("gate")


_SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _image(seed: int, shape: tuple[int, ...], style: int) -> np.ndarray:
    """Random uint8 content: uniform noise, the extremes 0 / 255 only, or a smooth ramp with noise."""
    rng = np.random.default_rng(seed)
    if style == 0:
        return rng.integers(0, 256, shape, dtype=np.uint8)
    if style == 1:
        return (rng.integers(0, 2, shape, dtype=np.uint8) * 255).astype(np.uint8)
    ramp = np.linspace(0, 255, int(np.prod(shape))).reshape(shape)
    return np.clip(ramp + rng.normal(0, 3, shape), 0, 255).astype(np.uint8)


@contextlib.contextmanager
def _path(opencv: bool):
    """The OpenCV path of the robot-side install (kernel mode 'off') while the block runs, where asked."""
    compiled_path.set_kernel_mode("off" if opencv else None)
    try:
        yield
    finally:
        compiled_path.set_kernel_mode(None)


def _work(frame: np.ndarray, k: int, blur: int = 3) -> FrameWork:
    fw = FrameWork(frame.shape, k, blur, 10.0)  # type: ignore[arg-type]
    fw.reduce(frame, blur=True)
    return fw


@_SETTINGS
@given(k=st.sampled_from([2, 4, 8, 16]), h=st.integers(2, 23), w=st.integers(2, 23), seed=st.integers(0, 2**31),
       style=st.integers(0, 2))
def test_reduction_and_blur_equal_opencv(k, h, w, seed, style):
    frame = _image(seed, (k * h, k * w, 3), style)
    fw = _work(frame, k)
    ref = reduce_cv(frame, k)
    assert np.array_equal(fw.small, ref)
    assert np.array_equal(fw.work, blur_cv(ref))
    th, tw = fw.thumb.shape[:2]
    thumb = cv2.resize(blur_cv(ref), (tw, th), interpolation=cv2.INTER_LINEAR)
    assert np.array_equal(fw.thumbnail(), thumb)
    fw.blur_small()  # the blur alone (after the runtime's separate reduce)
    assert np.array_equal(fw.work, blur_cv(ref))
    assert np.array_equal(fw.thumbnail(), thumb)


@_SETTINGS
@given(f=st.sampled_from([2, 4, 6, 8, 16]), h=st.integers(1, 17), w=st.integers(1, 17), seed=st.integers(0, 2**31),
       style=st.integers(0, 2))
def test_thumbnail_shrink_equals_opencv_linear_at_even_factors(f, h, w, seed, style):
    img = _image(seed, (f * h, f * w, 3), style)
    out = np.empty((h, w, 3), np.uint8)
    K.shrink(img.reshape(f * h, f * w * 3), f, out.reshape(h, w * 3))
    assert np.array_equal(out, cv2.resize(img, (w, h), interpolation=cv2.INTER_LINEAR))


@_SETTINGS
@given(h=st.integers(2, 41), w=st.integers(2, 41), seed=st.integers(0, 2**31), style=st.integers(0, 2),
       band=st.integers(1, 45))
def test_blur_equals_opencv_gaussian_3x3_with_its_reflect_101_edges(h, w, seed, style, band):
    """In bands of any number of rows (the scratch's: one row, a band that does not divide the image,
    more rows than it has)."""
    img = _image(seed, (h, w, 3), style)
    out = np.empty_like(img)
    K.blur3(img.reshape(h, w * 3), np.empty(band * w * 3, np.uint16), out.reshape(h, w * 3))
    assert np.array_equal(out, cv2.GaussianBlur(img, (3, 3), 0))


@_SETTINGS
@given(k=st.sampled_from([4, 8, 16]), h=st.integers(2, 21), w=st.integers(2, 21), seed=st.integers(0, 2**31),
       style=st.integers(0, 2))
def test_noise_level_equals_opencv(k, h, w, seed, style):
    frame = _image(seed, (k * h, k * w, 3), style)
    fw = _work(frame, k)
    assert fw.noise(frame) == noise_cv(frame, k)  # exactly: cv2.mean's sum x (1 / count)
    assert np.array_equal(fw.sub, cv2.resize(frame, (w, h), interpolation=cv2.INTER_NEAREST))


@_SETTINGS
@given(h=st.integers(1, 19), w=st.integers(1, 19), seed=st.integers(0, 2**31),
       threshold=st.sampled_from([10.0, 10.5, 11.5, 0.4, 3.2, 28.0, 254.6, 255.0]), identity=st.booleans(),
       opencv=st.booleans())
def test_changed_mask_and_difference_equal_opencv(h, w, seed, threshold, identity, opencv):
    """Both paths (``opencv``: the robot-side install's calls) against the oracle."""
    rng = np.random.default_rng(seed)
    work = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    bg = (rng.random((h, w, 3)) * 320 - 30).astype(np.float32)  # below 0 and above 255: |x|, saturation
    model = np.zeros((3, 4), np.float32)
    if identity:
        model[[0, 1, 2], [0, 1, 2]] = 1.0
    else:
        model[[0, 1, 2], [0, 1, 2]] = (rng.random(3) * 2.5 - 0.5).astype(np.float32)
        model[:, 3] = (rng.random(3) * 120 - 60).astype(np.float32)
    with _path(opencv):
        fw = FrameWork((h, w, 3), 1, 1, threshold)
    assert (fw._k is None) == opencv
    np.copyto(fw.work, work)
    n = fw.changed(bg, model)
    ad, mask = changed_cv(work, bg, model, threshold)
    assert np.array_equal(fw.ad, ad) and np.array_equal(fw.mask, mask)
    assert n == cv2.countNonZero(mask)


@_SETTINGS
@given(rows=st.integers(2, 17), cols=st.integers(2, 23), seed=st.integers(0, 2**31),
       tol=st.sampled_from([8.0, 8.3, 0.5, 2.7, 40.0, 1e-7]), near=st.booleans())
def test_thumbnail_fit_equals_opencv(rows, cols, seed, tol, near):
    """The fit's model, inlier mask and count, with thumbnails whose residual lands next to the
    tolerance (``near``: the frame is the model +- the tolerance +- a float32 step)."""
    rng = np.random.default_rng(seed)
    bg = (rng.random((rows, cols, 3)) * 255).astype(np.float32)
    model = np.zeros((3, 4), np.float32)
    model[[0, 1, 2], [0, 1, 2]] = rng.random(3) * 1.6 + 0.2
    model[:, 3] = rng.random(3) * 40 - 20
    ref_model, ref_inl, ref_n = residual_cv(bg, bg, model, tol)
    if near:
        step = rng.choice([-1, 0, 1], (rows, cols, 3)) * np.spacing(np.float32(tol))
        sign = rng.choice([-1.0, 1.0], (rows, cols, 3))
        thumb = (ref_model + sign * (np.float32(tol) + step)).astype(np.float32)
    else:
        thumb = (bg * rng.random((rows, cols, 3)) * 2 + rng.normal(0, 5, (rows, cols, 3))).astype(np.float32)
    ref_model, ref_inl, ref_n = residual_cv(bg, thumb, model, tol)
    tmodel, inl = np.empty_like(thumb), np.empty((rows, cols), np.uint8)
    fw = FrameWork((4 * rows, 4 * cols, 3), 4, 3, 10.0)
    n = fw.residual(bg, thumb, model, tmodel, inl, np.float32(tol))
    assert n == ref_n and np.array_equal(inl, ref_inl)
    assert np.array_equal(tmodel.view(np.uint32), ref_model.view(np.uint32))  # the same float32 bits


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(rows=st.integers(2, 17), cols=st.integers(2, 23), seed=st.integers(0, 2**31),
       tol=st.sampled_from([8.0, 2.7, 40.0, 1e-7]), scene=st.sampled_from(["near", "changed", "dark", "flat"]),
       opencv=st.booleans())
def test_photometric_fit_equals_opencv(rows, cols, seed, tol, scene, opencv):
    """The fitted gain and offset, to the float32 bit, and the float32 thumbnail: over the cells
    that fit (``near``: most do), over every cell (``changed``: few do), with a background that
    decayed towards 0 in places (``dark``: values across 40 binades, where the order of the sums
    shows) and with a channel of no variance (``flat``: the gain is 0)."""
    rng = np.random.default_rng(seed)
    bg = (rng.random((rows, cols, 3)) * 250 + 1).astype(np.float32)
    if scene == "dark":
        bg *= (rng.random((rows, cols, 3)) < 0.3) * np.float32(2.0) ** -rng.integers(0, 40, (rows, cols, 3))
        bg = bg.astype(np.float32)
    if scene == "flat":
        bg[..., 1] = np.float32(rng.random() * 200)
    model = np.zeros((3, 4), np.float32)
    model[[0, 1, 2], [0, 1, 2]] = rng.random(3) * 0.4 + 0.8
    model[:, 3] = rng.random(3) * 10 - 5
    noise = 2.0 if scene != "changed" else 60.0
    thumb = np.clip(bg * model.diagonal() + model[:, 3] + rng.normal(0, noise, bg.shape), 0, 255).astype(np.uint8)
    ref_model, ref_y = fit_cv(bg, thumb, model, tol)
    with _path(opencv):
        fw = FrameWork((4 * rows, 4 * cols, 3), 4, 3, 10.0)
    y, tmodel, inl = np.empty_like(bg), np.empty_like(bg), np.empty((rows, cols), np.uint8)
    got = model.copy()
    fw.fit(bg, thumb, y, got, tmodel, inl, np.float32(tol))
    assert np.array_equal(y, ref_y)
    assert np.array_equal(got.view(np.uint32), ref_model.view(np.uint32))  # the same float32 bits
    # the float64 moments too (the float32 model hides their last bits)
    _, ref_inl, n = residual_cv(bg, ref_y, model, tol)
    mask = ref_inl if n >= ref_inl.size // 2 else None
    mx, sx = cv2.meanStdDev(bg, mask=mask)
    my, mxy = cv2.mean(ref_y, mask=mask), cv2.mean(cv2.multiply(bg, ref_y), mask=mask)
    assert fw.fit_moments() == [(mx[c, 0], sx[c, 0], my[c], mxy[c]) for c in range(3)]
    ref_tmodel, ref_inl, _ = residual_cv(bg, ref_y, model, tol)  # left as the residual of the model given
    assert np.array_equal(inl, ref_inl) and np.array_equal(tmodel.view(np.uint32), ref_tmodel.view(np.uint32))


@_SETTINGS
@given(h=st.integers(1, 31), w=st.integers(1, 31), seed=st.integers(0, 2**31),
       fill=st.sampled_from([0.0, 0.01, 0.5, 1.0]), opencv=st.booleans())
def test_contact_area_and_deformation_equal_opencv(h, w, seed, fill, opencv):
    rng = np.random.default_rng(seed)
    with _path(opencv):
        fw = FrameWork((4 * h, 4 * w, 3), 4, 3, 10.0)
    fw.mask[...] = np.where(rng.random((h, w)) < fill, rng.integers(1, 256, (h, w)), 0).astype(np.uint8)
    fw.ad[...] = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    area, deformation = fw.contact_stats()
    assert area == cv2.countNonZero(fw.mask)
    assert deformation == max(cv2.mean(fw.ad, mask=fw.mask)[:3])  # exactly


def _real_frames() -> list[np.ndarray]:
    files = sorted(shared_data("aurova_digit_grasp", "images").glob("*.png"))
    files += sorted(p for p in shared_data("digit_backgrounds").iterdir() if p.suffix in (".png", ".jpg"))
    frames = [cv2.imread(str(p), cv2.IMREAD_COLOR) for p in files]
    assert frames and all(f is not None for f in frames)
    return [np.ascontiguousarray(f) for f in frames]


@pytest.mark.parametrize("k", [2, 4, 8])
def test_kernels_equal_opencv_on_real_frames(k):
    for frame in _real_frames():
        if frame.shape[0] % k or frame.shape[1] % k:
            continue
        fw = _work(frame, k)
        ref = reduce_cv(frame, k)
        assert np.array_equal(fw.small, ref) and np.array_equal(fw.work, blur_cv(ref))
        if k > 2:
            assert fw.noise(frame) == noise_cv(frame, k)


@pytest.mark.parametrize("offset", [0, 1, 2, 3])
def test_the_fused_reduction_equals_opencv_at_any_frame_address(offset):
    """The kernel copies four pixels per three 32-bit words only where the frame's and the buffers'
    addresses allow; a frame that starts at any byte (a view into a larger buffer) gives the same
    reduced image, blur and noise level as OpenCV, with the noise measured in the same call."""
    rng = np.random.default_rng(5)  # a smooth DIGIT-sized image with pixel noise
    frame0 = np.clip(cv2.resize(rng.integers(0, 256, (15, 20, 3), dtype=np.uint8), (320, 240))
                     + rng.normal(0, 4, (240, 320, 3)), 0, 255).astype(np.uint8)
    for k in (4, 8):
        raw = np.zeros(frame0.nbytes + 8, np.uint8)
        frame = raw[offset:offset + frame0.nbytes].reshape(frame0.shape)
        frame[...] = frame0
        fw = FrameWork(frame.shape, k, 3, 10.0)  # type: ignore[arg-type]
        fw.reduce(frame, blur=True, noise=True)
        ref = reduce_cv(frame0, k)
        assert np.array_equal(fw.small, ref) and np.array_equal(fw.work, blur_cv(ref))
        assert fw.noise(frame) == noise_cv(frame0, k)  # the level measured by reduce, taken once
        assert fw.noise(frame) == noise_cv(frame0, k)  # measured again


# -- the whole gate ---------------------------------------------------------------------------

def _compare(a, b) -> None:
    for name in ("contact", "area_px", "area_frac", "saturation_seen", "background_ready", "mismatch", "invalid",
                 "deformation", "gain", "offset", "centroid", "bbox"):
        assert getattr(a, name) == getattr(b, name), name
    for name in ("reduced", "reduced_mask", "thumb", "mask"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def _run_both(frames: list[np.ndarray], options: GateOptions, background: np.ndarray | None = None) -> list:
    gate, oracle = ContactGate(options), OracleGate(options)
    if background is not None:
        gate.capture_background([background])
        oracle.capture_background([background])
    results = []
    for f in frames:
        a, b = gate.update(f), oracle.update(f)
        _compare(a, b)
        results.append(a)
    assert gate.relearned == oracle.relearned
    return results


def _virtual_sequence() -> list[np.ndarray]:
    from tactile_force.edge.synthetic.digit import ContactSpec, VirtualDigit, VirtualDigitOptions

    digit = VirtualDigit(VirtualDigitOptions(seed=3))
    rng = np.random.default_rng(5)
    frames = [digit.render(None, 0.0).frame for _ in range(12)]  # the background is learnt
    for force in (1.0, 3.0, 6.0, 9.0, 12.0, 6.0, 2.0):
        frames.append(digit.render(ContactSpec("circle_large", (150.0, 110.0)), force).frame)
    quiet = digit.render(None, 0.0).frame
    step = np.clip(quiet.astype(np.float32) * 1.35 + 8, 0, 255).astype(np.uint8)  # LED / exposure step
    frames += [step] * 4
    burst = np.clip(quiet + rng.normal(0, 25, quiet.shape), 0, 255).astype(np.uint8)  # pixel-noise burst
    frames += [burst, burst, quiet, quiet]
    shifted = np.roll(quiet, 9, axis=1)  # the gel moved
    frames += [shifted] * 4
    frames += [digit.render(ContactSpec("circle_large", (100.0, 140.0)), 8.0).frame, quiet]
    return [np.ascontiguousarray(f) for f in frames]


@pytest.mark.parametrize("options", [GateOptions(), GateOptions(downscale=2), GateOptions(downscale=8),
                                     GateOptions(downscale=3), GateOptions(blur=5), GateOptions(trust=False),
                                     GateOptions.gelsight_mini()],
                         ids=["default", "x2", "x8", "x3", "blur5", "no-trust", "gelsight-mini"])
@pytest.mark.parametrize("path", ["compiled", "opencv"])
def test_the_gate_equals_its_opencv_oracle_over_a_virtual_sequence(options, path, kernel_mode):
    """Both of the package's paths: the compiled kernels, and the OpenCV calls of the robot-side install."""
    kernel_mode("off" if path == "opencv" else None)
    results = _run_both(_virtual_sequence(), options)
    if options.trust and options.downscale == 4:  # the sequence exercises what it is meant to
        assert any(r.contact for r in results) and any(r.invalid for r in results)
        assert any(r.mismatch for r in results) and any(not r.contact for r in results[12:])


@pytest.mark.parametrize("path", ["compiled", "opencv"])
def test_the_gate_equals_its_opencv_oracle_on_the_real_aurova_grasp(path, kernel_mode):
    kernel_mode("off" if path == "opencv" else None)
    background = cv2.imread(str(shared_data("digit_backgrounds", "aurova_background_b.png")), cv2.IMREAD_COLOR)
    frames = [f for f in _real_frames() if f.shape == background.shape]
    results = _run_both(frames, GateOptions(), np.ascontiguousarray(background))
    assert any(r.contact for r in results)


def test_changed_model_out_of_range_values_saturate_like_opencv():
    """NaN, infinities and models beyond int32 (a near-uniform thumbnail's huge gain): convertScaleAbs
    rounds to int32 first, which makes them 0, not 255."""
    bg = np.array([[[np.nan, np.inf, -np.inf], [1e30, -1e30, 300.0], [2.1e9, 2.2e9, -254.6]]], np.float32)
    work = np.array([[[7, 200, 13], [255, 0, 128], [3, 90, 250]]], np.uint8)
    model = np.zeros((3, 4), np.float32)
    model[[0, 1, 2], [0, 1, 2]] = 1.0
    fw = FrameWork((4, 12, 3), 4, 3, 10.0)
    fw.work[...] = work
    n = fw.changed(bg, model)
    ad, mask = changed_cv(work, bg, model, 10.0)
    assert np.array_equal(fw.ad, ad) and np.array_equal(fw.mask, mask) and n == cv2.countNonZero(mask)


def test_changed_model_rounds_like_opencv_next_to_the_half_grey_levels():
    """Backgrounds whose model lands next to k + 0.5: a model computed another way (float32 product then
    sum, an FMA) moves some of them across the rounding boundary."""
    rng = np.random.default_rng(11)
    h, w = 60, 80
    model = np.zeros((3, 4), np.float32)
    for _ in range(20):
        gain = (rng.random(3) * 1.6 + 0.2).astype(np.float32)
        offset = (rng.random(3) * 80 - 40).astype(np.float32)
        model[[0, 1, 2], [0, 1, 2]], model[:, 3] = gain, offset
        target = rng.integers(0, 256, (h, w, 3)) + 0.5 + rng.normal(0, 1e-5, (h, w, 3))
        bg = ((target - offset) / gain).astype(np.float32)
        fw = FrameWork((h, w, 3), 1, 1, 10.0)
        work = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        np.copyto(fw.work, work)
        fw.changed(bg, model)
        ad, mask = changed_cv(work, bg, model, 10.0)
        assert np.array_equal(fw.ad, ad) and np.array_equal(fw.mask, mask)


def test_a_kernel_compiles_in_memory_when_no_cache_folder_is_writable(monkeypatch, caplog):
    """numba refuses cache=True where no cache folder is writable (a read-only install without
    a home folder); the gate's kernels are then compiled without a disk cache, with a warning
    naming NUMBA_CACHE_DIR, instead of failing to import."""
    import logging

    import numba as nb
    from tactile_force.edge import compiled

    real = nb.njit

    def no_locator(*args, **kwargs):
        if kwargs.get("cache"):
            raise RuntimeError("cannot cache function 'f': no locator available for file 'x.py'")
        return real(*args, **kwargs)

    monkeypatch.setattr(nb, "njit", no_locator)

    def add_one(x):
        return x + 1

    with caplog.at_level(logging.WARNING, logger="tactile_force.edge.compiled"):
        f = compiled.compiled("contact gate kernels")(add_one)
    assert f(41) == 42
    assert "NUMBA_CACHE_DIR" in caplog.text and "no locator available" in caplog.text
    assert "contact gate kernels" in caplog.text


def test_kernels_are_cached_in_the_users_cache_folder_not_beside_the_module(monkeypatch, tmp_path):
    """The compiled forms go to XDG_CACHE_HOME/tactile_force/numba (an installed package's folder
    is site-packages: what pip did not install stays there after an uninstall), and numba's own
    setting is left as the user had it."""
    import numba as nb
    from tactile_force.edge import compiled

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(nb.config, "CACHE_DIR", "")

    def cached_in_the_users_folder(x):
        return x + 2

    f = compiled.compiled("a test kernel")(cached_in_the_users_folder)
    assert f(40) == 42
    assert nb.config.CACHE_DIR == ""
    assert list((tmp_path / "tactile_force" / "numba").rglob("*cached_in_the_users_folder*.nbi"))
    beside = Path(__file__).parent / "__pycache__"
    assert not list(beside.glob("*cached_in_the_users_folder*")) if beside.is_dir() else True
    monkeypatch.setattr(nb.config, "CACHE_DIR", str(tmp_path / "mine"))
    assert compiled.cache_dir() == str(tmp_path / "mine")
