"""Contact gate: does anything touch the gel, and can this frame be judged at all?

The gate keeps a background image of the gel without contact (mean of the first N frames, or
an explicit :meth:`ContactGate.capture_background`), compares every frame with it per pixel
and decides contact from the masked area with hysteresis: contact turns on when the area
reaches ``on_area_frac`` of the frame and off only when it falls below ``off_area_frac``.
While there is no contact the background follows slow LED drift (``refresh_rate``).

Resolution: the work runs on the frame shrunk by ``downscale`` (default 4: a 320x240 DIGIT
frame becomes 80x60, the input size of the compact default model), reduced once per frame by
the package's box average (:func:`tactile_force.edge.gate.reduce.default_reduction`: ``area-2x-steps``
for a power-of-two factor) into a buffer allocated once; :attr:`GateResult.reduced` is that
image, and when a bundle's network input is reduced the same way the runtime hands it to the
model as its input (one downscale per frame). The full-resolution mask
(the depth stage filters its full-size depth image with it) is made only when
:attr:`GateResult.mask` is read.

Trust (``GateOptions.trust``, on by default; see docs/runtime.md, "Flags"): before the
difference, a per-channel gain and offset between frame and background is fitted robustly on
a 20x15 thumbnail (the cells that do not look like contact), so an LED or exposure change
does not look like contact. Then the frame is judged:

- ``invalid``: the frame fits the background far better with B and R swapped (RGB order), it
  is uniform (no gel image), or it carries a burst of pixel noise;
- ``mismatch``: the frame no longer fits the background in a way no contact explains: a
  sudden brightness step (gain/offset beyond ``step_level``), a shift or rotation of the
  image (gel or camera moved), or most of the frame changed at once (another unit, another
  session, occlusion, colour cast). Recovery: the mismatch clears as soon as a frame fits the
  background again; the background is re-learnt from the live frame once it has been stable
  for ``relearn_frames`` frames with no contact-like blob (after a brightness step: no blob
  left after compensation; otherwise the change must cover the frame's borders or be a pure
  shift/rotation). A press that grew while the gate watched is tracked as contact and never
  re-learnt into the background.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable

import cv2
import numpy as np

from .. import compiled_path
from ..bundle.manifest import FrameReduction
from ..checks import expect
from ..errors import FrameError
from ..frames import TimedFrame, check_frame
from .blobs import BlobFinder
from .checks import Reference, colour_swapped, dark_share, is_uniform, motion_explained, noise_verdict
from .frame_work import THUMB_CELL_PX, FrameWork
from .learning import BackgroundLearner, RelearnPolicy, refresh
from .options import GateOptions
from .reduce import default_reduction
from .result import GateResult

__all__ = ["THUMB_CELL_PX", "ContactGate", "GateResult"]

_log = logging.getLogger(__name__)

_UINT8 = np.dtype(np.uint8)


class ContactGate:
    """Per-sensor contact gate; one instance per sensor, not thread-safe."""

    #: the per-frame image work (edge/gate/frame_work.py); the tests put an OpenCV-only oracle here
    frame_work: type[FrameWork] = FrameWork

    def __init__(self, options: GateOptions | None = None) -> None:
        expect(options, (GateOptions, type(None)), "ContactGate.options", "a GateOptions or None (the defaults)")
        self.options = options or GateOptions()
        self.options.validate()
        compiled_path.request("gate")  # the compiled kernels, off the reading path (OpenCV meanwhile)
        self._bg: np.ndarray | None = None  # blurred background, float32, working res
        self._bg_thumb: np.ndarray | None = None  # its thumbnail, float32
        self._ref: Reference | None = None
        self._learner = BackgroundLearner()  # the first live frames, while the background is learnt
        self._relearned_now = False
        self._shape: tuple[int, int, int] | None = None
        self._contact = False
        # The per-channel photometric model (frame = gain x background + offset) as the 3 x 4
        # matrix cv2.transform applies; _gain (its diagonal) and _offset (its last column) are
        # views into it, so the fit writes the matrix directly.
        self._M = np.zeros((3, 4), np.float32)
        self._M_keep = np.empty_like(self._M)  # prewarm() restores the model from it
        self._gain = self._M.reshape(-1)[::5]
        self._offset = self._M[:, 3]
        self._gain[:] = 1.0
        self._level: tuple[float, float, float] | None = None  # mean colour of _bg_thumb (cached)
        self._bg_noise = 1.0
        self._policy = RelearnPolicy(self.options)  # the mismatch state and when to re-learn
        self._given = 0  # live frames still to check against a background given at start
        self._given_origin = ""
        self._reduced_for: np.ndarray | None = None  # the frame reduce() was called for
        self._last_frame: np.ndarray | None = None  # the last frame prepared (prewarm() reuses it)
        self._fit_frac = 1.0  # share of thumbnail cells the photometric model fits
        self._reduction: FrameReduction | None = None
        self.relearned = 0  # how many times the background was re-learnt after a mismatch
        #: the first full-resolution frame given to :meth:`capture_background` (HxWx3 uint8 BGR;
        #: None while the background is learnt from live frames): the runtime checks it once for
        #: a press against the bundle's no-contact reference (edge/gate/given_background.py)
        self.background_image: np.ndarray | None = None
        self.background_origin = ""

    # -- background ---------------------------------------------------------------------
    @property
    def background_ready(self) -> bool:
        return self._bg is not None

    @property
    def reduction(self) -> FrameReduction:
        """How the gate reduces each frame before judging it (method and factor ``downscale``);
        the runtime hands :attr:`GateResult.reduced` to a model whose network input is
        reduced the same way."""
        k = int(self.options.downscale)
        red = self._reduction
        if red is None or red.factor != k:  # made once (the runtime asks for it every frame)
            red = self._reduction = default_reduction(k)
        return red

    @property
    def frame_shape(self) -> tuple[int, int, int] | None:
        """H x W x 3 the gate works at, fixed by the first background."""
        return self._shape

    @property
    def state(self) -> str:
        """'learning', 'ok' or 'mismatch: <reason>'."""
        if self._bg is None:
            return "learning"
        reason = self._policy.reason
        return f"mismatch: {reason}" if reason else "ok"

    def capture_background(self, frames: Iterable[np.ndarray | TimedFrame], origin: str = "") -> None:
        """Set the background to the mean of ``frames`` (HxWx3 uint8 BGR, no contact).

        origin: where the frames came from (e.g. the scene's background file); when given,
        the first live frames are checked against it and a mismatch names it."""
        learner = BackgroundLearner()
        first: np.ndarray | None = None
        for i, f in enumerate(frames):
            arr = self._as_array(f, i)
            first = arr if first is None else first
            w, t = self._prepare(arr)
            learner.add(w, t, self._noise(w))
        if first is None:
            raise FrameError("capture_background: no frames given; expected at least one no-contact frame")
        self._set_background(*learner.mean())
        self._given, self._given_origin = (5, origin) if origin else (0, "")
        assert first is not None
        self.background_image, self.background_origin = first.copy(), origin

    def reset(self) -> None:
        """Forget the background; the next ``background_frames`` frames are learnt again."""
        self._bg = None
        self._bg_thumb = None
        self._ref = None
        self._learner.clear()
        self._contact = False
        self._policy.clear()

    def relearn(self, frame: np.ndarray | TimedFrame) -> None:
        """Take ``frame`` (no contact: the gripper is open) as the new background now."""
        self.capture_background([frame])

    # -- per frame ----------------------------------------------------------------------
    def reduce(self, frame: np.ndarray | TimedFrame) -> np.ndarray:
        """The frame's one downscale, now: the reduced image (H/k x W/k x 3 uint8, the gate's
        buffer, valid until the next frame). A following :meth:`update` of the same array
        judges this image without reducing the frame again (the runtime checks the frame's
        exposure on it first)."""
        arr = self._as_array(frame, None)
        self._reduce(arr)
        self._reduced_for = arr
        return self._small

    def update(self, frame: np.ndarray | TimedFrame) -> GateResult:
        """Gate one frame (HxWx3 uint8 BGR, same size as the background)."""
        arr = frame if frame is self._reduced_for else self._as_array(frame, None)  # reduce() checked it
        work, thumb = self._prepare(arr)
        o = self.options
        if self._bg is None:
            learner = self._learner
            if learner.add(work, thumb, self._noise(work)) >= o.background_frames:
                self._set_background(*learner.mean())
                learner.clear()
            self._mask[:] = 0
            r = GateResult(False, 0, False, self._mask, self._full_mask, int(o.downscale), self._exact,
                           background_ready=False)
            r._mask_ready = False
            r.thumb = thumb
            r.reduced = self._small
            return r

        self._fit_thumb(thumb)
        y = self._y
        self._changed(work)
        area_small, saturation_seen, deformation = self._blobs()

        s = int(o.downscale)
        k = s if self._exact else 1
        if s > 1 and self._exact:
            area = area_small * s * s
        elif s > 1:  # the factor does not divide the frame: count on the full-resolution mask
            cv2.resize(self._mask, (arr.shape[1], arr.shape[0]), dst=self._full_mask, interpolation=cv2.INTER_NEAREST)
            area = cv2.countNonZero(self._full_mask)
        else:
            area = area_small
        frac = area / self._full_area

        was_contact = self._contact
        if self._contact:
            self._contact = frac >= o.off_area_frac
        else:
            self._contact = frac >= o.on_area_frac

        invalid = mismatch = ""
        self._relearned_now = False
        if o.trust:
            invalid, mismatch = self._judge(y, work, thumb, frac, was_contact)
        if self._relearned_now:  # this frame is the new background: no contact in it
            self._contact = False
            area, saturation_seen, deformation = 0, False, 0.0
            self._mask[:] = 0
        elif invalid or mismatch:
            self._contact = was_contact and not mismatch and not invalid
        elif not self._contact and o.refresh_rate > 0:
            assert self._bg_thumb is not None and self._ref is not None
            refresh(self._bg, self._bg_thumb, work, thumb, o.refresh_rate, self._ref)
            self._level = None

        small = self._mask if (s > 1 and self._exact) else self._full_mask
        full = self._mask if s == 1 else self._full_mask
        contact = self._contact and not mismatch and not invalid
        r = GateResult(contact, int(area), bool(saturation_seen), small if s > 1 else full, full, k, self._exact)
        if s > 1 and not self._exact:
            r._mask_ready = True
        r.mismatch, r.invalid, r.deformation, r.thumb = mismatch, invalid, float(deformation), thumb
        r.reduced = self._small
        r.gain = tuple(self._gain.tolist())
        r.offset = tuple(self._offset.tolist())
        return r

    def prewarm(self) -> None:
        """Run the per-frame work of :meth:`update` once more on the last frame gated, into
        the gate's scratch buffers, and throw the result away: the background, the
        photometric model, the contact state and the mismatch state stay as they were (the
        runtime calls it shortly before a frame is due at a slow cadence, so the frame finds
        caches warm: edge/runtime/prewarm.py). Like :meth:`update` it overwrites the buffers
        of the last :class:`GateResult` (its mask, thumbnail and reduced image). Nothing
        happens before the background is known. Right after :meth:`reduce` of the last frame
        (the runtime judges its exposure first) the frame is not reduced again."""
        arr = self._last_frame
        if self._bg is None or arr is None:
            return
        keep = self._M_keep
        np.copyto(keep, self._M)
        fit_frac = self._fit_frac
        work, thumb = self._prepare(arr)
        self._fit_thumb(thumb)
        self._changed(work)
        self._blobs()
        self._noise(work)
        np.copyto(self._M, keep)
        self._fit_frac = fit_frac

    # -- stages of update (separate so each can be timed) ---------------------------------
    def _fit_thumb(self, thumb: np.ndarray) -> None:
        """Per-channel gain/offset (frame = gain x background + offset) of ``thumb`` (the frame's
        thumbnail, uint8; into ``_thumb_f`` as float32), least squares over the thumbnail cells that
        fit the previous model (all cells when fewer than half do: after a sudden change)
        (:meth:`FrameWork.fit`); with ``trust`` also ``_inl`` (cells that fit now) and ``_fit_frac``
        for the judging."""
        assert self._bg_thumb is not None
        self._fw.fit(self._bg_thumb, thumb, self._thumb_f, self._M, self._tmodel, self._inl, self._tol)
        if self.options.trust:
            self._fit_frac = self._residual() / self._inl.size

    def _changed(self, work: np.ndarray) -> None:
        """The changed-pixel mask into ``_mask`` and |frame - model| into ``_ad`` (``work`` is the
        frame work's own blurred image). Model of the frame = background x gain + offset per
        channel (uint8); changed: the max over B, G, R of |frame - model| > threshold."""
        assert self._bg is not None
        self._changed_px = self._fw.changed(self._bg, self._M)

    def _blobs(self) -> tuple[int, bool, float]:
        """Contact blobs of the changed mask, filled, into ``_mask`` (edge/gate/blobs.py): (area in
        working pixels, gel saturation seen, deformation in grey levels)."""
        return self._blob_finder(self._changed_px)

    # -- trust ----------------------------------------------------------------------------
    def _residual(self) -> int:
        """The model of the thumbnail (gain x background + offset) into ``_tmodel``, the cells within
        ``fit_tolerance`` of it on every channel into ``_inl``; returns their count."""
        assert self._bg_thumb is not None
        return self._fw.residual(self._bg_thumb, self._thumb_f, self._M, self._tmodel, self._inl, self._tol)

    def _judge(self, y: np.ndarray, work: np.ndarray, thumb: np.ndarray, frac: float,
               was_contact: bool) -> tuple[str, str]:
        """(invalid reason, mismatch reason) for this frame; updates the mismatch state and
        re-learns the background when the recovery policy allows."""
        o = self.options
        ref = self._ref
        assert ref is not None
        policy = self._policy
        assert self._bg_thumb is not None
        if self._level is None:  # the background thumbnail's mean colour: re-made when it changes
            self._level = cv2.mean(self._bg_thumb)[:3]
        l0, l1, l2 = self._level
        gain, offset = self._gain.tolist(), self._offset.tolist()
        g0, g1, g2 = gain
        step = max(abs((g0 - 1.0) * l0 + offset[0]), abs((g1 - 1.0) * l1 + offset[1]),
                   abs((g2 - 1.0) * l2 + offset[2]))
        global_change = self._fit_frac < o.fit_floor
        contrast = max(abs(g0 - 1.0), abs(g1 - 1.0), abs(g2 - 1.0))
        photometric = step > o.step_level or contrast > 0.5
        # Pixel noise: mean |frame - blurred| against the background's level. Measured on every
        # frame: the box-averaged image the rest of the gate judges hides a noise burst.
        noise = self._noise(work)
        burst, invalid = noise_verdict(noise, self._bg_noise, gain, o.noise_factor)
        suspicious = global_change or photometric or frac > 0 or policy.reason or burst
        if not suspicious:
            policy.clear()
            return "", ""
        reason, kind = "", ""
        if not invalid and (global_change or photometric):
            if is_uniform(self._thumb_f):
                invalid = "uniform frame: no gel image (LEDs off, lens covered, a test pattern or a stalled camera?)"
            # A wrong colour order shows from the first frame on, never inside a tracked contact.
            elif global_change and not was_contact and colour_swapped(y, ref.x, o.fit_tolerance, self._fit_frac):
                invalid = ("colour order: the frame fits the background far better with B and R swapped; the source "
                           "delivers RGB, the package expects BGR (OpenCV order): convert with frame[..., ::-1]")
        if not invalid:
            # A change that appears at once (no contact tracked) is checked for motion and
            # occlusion; a tracked contact is not re-checked every frame.
            onset = not was_contact or global_change
            explained = (motion_explained(self._thumb_f, self._tmodel, self._tr, ref)
                         if onset and self._fit_frac < 0.98 else 0.0)
            if explained > o.motion_explained:
                reason, kind = (f"the gel or camera moved: {100 * explained:.0f} % of the difference is a shift or "
                                "rotation of the background", "motion")
            elif onset and frac > 0 and dark_share(self._thumb_f, ref.dark(), self._tcmp, self._tdark) > 0.04:
                reason, kind = ("part of the gel is covered or dark (occlusion, a cable or finger in view, "
                                "a failed LED?)", "global")
            elif global_change and not was_contact:
                reason, kind = (f"the frame no longer fits the background: only {100 * self._fit_frac:.0f} % of it "
                                "fits (another sensor unit or session, occlusion, colour cast?)", "global")
            elif photometric and self._fit_frac >= o.fit_floor:
                g = "/".join(f"{v:.2f}" for v in gain)
                reason, kind = (f"sudden brightness step of {step:.0f} grey levels (LED/exposure: gain B/G/R {g})",
                                "photometric")
            elif policy.reason and self._fit_frac >= 0.8 and not photometric:
                policy.clear()
        if self._given and reason:
            reason = (f"the background given at start ({self._given_origin}) does not fit the live frames: {reason}; "
                      "remove it from the scene to learn the background from the first frames, or record a new one")
        if self._given:
            self._given -= 1
        if reason:
            policy.enter(reason, kind)
            if policy.due(thumb, frac, kind, self._inl):
                self._relearn_live()
            return invalid, policy.reason
        if policy.reason and not invalid:
            # In a mismatch state frames that do not show the reason any more but do not fit
            # well either (fit_frac < 0.8) stay mismatched.
            if policy.due(thumb, frac, policy.kind, self._inl):
                self._relearn_live()
            return invalid, policy.reason
        return invalid, ""

    def _relearn_live(self) -> None:
        """The recovery policy (edge/gate/learning.py) says re-learn: the live frame is the
        new background now."""
        reason = self._policy.reason
        assert self._last_frame is not None  # the frame being judged
        self.capture_background([self._last_frame])
        self.relearned += 1
        self._relearned_now = True
        _log.warning("contact gate: background re-learnt from the live frame after %d stable frames (%s)",
                     self.options.relearn_frames, reason)

    def _noise(self, work: np.ndarray) -> float:
        """Pixel-noise level of the frame just prepared (``work`` its blurred reduced image):
        mean |subsampled frame - blurred| (grey levels). A box average hides pixel noise (a k x k
        average divides it by k), so above x2 the level is measured on one pixel per k x k block
        of the full frame (edge/gate/frame_work.py)."""
        assert self._last_frame is not None  # set with the frame prepared
        return self._fw.noise(self._last_frame)

    def _set_background(self, bg: np.ndarray, thumb: np.ndarray, noise: float) -> None:
        self.background_image, self.background_origin = None, ""  # capture_background sets them again
        self._bg = bg
        self._bg_thumb = thumb
        self._level = None
        self._ref = Reference(thumb)
        self._gain[:] = 1.0
        self._offset[:] = 0.0
        self._contact = False
        self._policy.clear()
        self._bg_noise = max(0.5, noise)

    # -- internals ----------------------------------------------------------------------
    def _as_array(self, frame: np.ndarray | TimedFrame, i: int | None) -> np.ndarray:
        arr = frame.frame if isinstance(frame, TimedFrame) else frame
        if (type(arr) is np.ndarray and arr.dtype is _UINT8 and arr.shape == self._shape
                and arr.flags.c_contiguous):  # the usual frame: what check_frame would pass as it is
            self._last_frame = arr
            return arr
        name = "gate frame" if i is None else f"background frame {i}"
        arr = check_frame(arr, name=name, shape=None)
        if self._shape is None:
            self._allocate(arr.shape)
        elif arr.shape != self._shape:
            raise FrameError(f"{name}: shape {arr.shape}; this gate's background is {self._shape} "
                             "(call reset() or use one gate per sensor)")
        self._last_frame = arr
        return arr

    def _allocate(self, shape: tuple[int, int, int]) -> None:
        o = self.options
        h, w = shape[:2]
        s = int(o.downscale)
        th, tw = max(2, h // THUMB_CELL_PX), max(2, w // THUMB_CELL_PX)
        self._shape = (int(shape[0]), int(shape[1]), int(shape[2]))
        fw = self._fw = self.frame_work(self._shape, s, o.blur, o.threshold)
        self._small, self._work, self._thumb, self._ad, self._mask = fw.small, fw.work, fw.thumb, fw.ad, fw.mask
        self._changed_px = 0
        self._exact = fw.exact
        self._thumb_f = np.empty((th, tw, 3), np.float32)
        self._tmodel = np.empty((th, tw, 3), np.float32)
        self._tr = np.empty((th, tw, 3), np.float32)
        self._inl = np.full((th, tw), 255, np.uint8)
        self._tcmp = np.empty((th, tw, 3), np.uint8)  # the occlusion check's buffers
        self._tdark = np.empty((th, tw), np.uint8)
        self._tol = np.float32(o.fit_tolerance)  # inRange's bound on a float32 image: the float32 nearest
        self._y = self._thumb_f.reshape(-1, 3)  # a view: the thumbnail's cells x B, G, R
        self._fit_frac = 1.0
        self._blob_finder = BlobFinder(o, self._mask, self._ad, fw.contact_stats)
        self._full_mask = self._mask if s == 1 else np.zeros((h, w), np.uint8)
        self._full_area = h * w

    def _reduce(self, arr: np.ndarray) -> None:
        """The one downscale into ``_small``, its blur into ``_work`` and, where this frame's
        judging reads it (background learning, ``trust``), its pixel-noise level, in one pass."""
        self._fw.reduce(arr, blur=True, noise=self._bg is None or self.options.trust)

    def _prepare(self, arr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The frame's one downscale (an exact box average, edge/gate/reduce.py, into ``_small``;
        a factor that does not divide the frame: INTER_LINEAR at x2, else one pixel per block)
        + blur into the uint8 working buffer, and its thumbnail; all buffers are reused
        (edge/gate/frame_work.py)."""
        fw = self._fw
        if self._reduced_for is not arr:
            self._reduce(arr)
        self._reduced_for = None
        return self._work, fw.thumbnail()
