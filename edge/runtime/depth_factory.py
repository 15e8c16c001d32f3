"""The depth stage a depth bundle (D, Dmod, RGBmod+D) needs, built from the scene's
``[depth]`` table and the bundle's manifest (:func:`depth_options_for` merges them in this
one place), the plan of the stages a runtime will run (:func:`plan_stages`) and the stage's
call on one gated frame (:func:`depth_of`). The depth code is imported only when a depth
stage is built."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..bundle.manifest import Manifest
from ..errors import SceneError

if TYPE_CHECKING:  # the depth code is imported only for depth bundles
    import numpy as np

    from ..depth import DepthOptions, DepthResult, DepthStage
    from ..gate.contact_gate import GateResult

#: Files shipped with the package (``package:FILE`` in scenes and manifests).
ASSETS_DIR = Path(__file__).resolve().parents[1] / "assets"


def _record_options(record: object) -> dict[str, Any]:
    """The DepthOptions values a depth record sets (None = not set): its fields by name;
    a manifest's ``reduction`` (a FrameReduction, factor k > 1: depth made at the network
    resolution) becomes DepthOptions ``downscale`` = k and ``reduction`` = its method."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(record):  # type: ignore[arg-type]
        value = getattr(record, f.name)
        if value is None:
            continue
        if f.name == "reduction" and hasattr(value, "factor"):
            if value.factor > 1:  # depth at the network resolution (the grid the model reads)
                out["downscale"] = value.factor
                out["reduction"] = value.method.value
            continue
        out[f.name] = value
    return out


def depth_options_for(settings: object | None = None, manifest: Manifest | None = None) -> DepthOptions:
    """The depth stage's typed options for a depth bundle, merged in this one place: each
    :class:`~tactile_force.edge.depth.DepthOptions` field from the scene's ``[depth]`` table
    (``settings``: a :class:`~tactile_force.edge.scene.DepthSettings`, or any dataclass with
    DepthOptions field names, e.g. a DepthOptions), else from what the bundle's manifest
    recorded at training time (``manifest.depth``, a
    :class:`~tactile_force.edge.bundle.manifest.DepthRecord`), else the DepthOptions default.

    Generic over the fields (``dataclasses.fields``): a field a record shares by name with
    DepthOptions flows through without an edit here; None means "not set"; record fields
    DepthOptions does not have (``mapping_sha256``, ``mask``) are not options. A mapping
    named ``package:FILE`` is a file shipped in tactile_force/edge/assets (e.g. the virtual
    DIGIT's calibration that the reference depth models were trained with).

    Raises
    ------
    SceneError
        No mapping anywhere (``depth.mapping``), or a value DepthOptions refuses (``depth``).
    """
    from ..depth import DepthOptions  # noqa: PLC0415 - lazy on purpose

    names = {f.name for f in dataclasses.fields(DepthOptions)}
    values: dict[str, Any] = {}
    for record in (manifest.depth if manifest is not None else None, settings):  # the scene's table wins
        if record is not None:
            values.update({k: v for k, v in _record_options(record).items() if k in names})
    if "mapping" not in values:
        raise SceneError("depth.mapping: missing; a depth bundle needs the colour->normal .npz "
                         "(the paper MLP or a 'tactile-force calibrate-depth' result) in the scene's [depth] "
                         "table or the bundle manifest")
    values["mapping"] = resolve_package_path(str(values["mapping"]))
    try:
        return DepthOptions(**values)
    except (TypeError, ValueError) as exc:
        raise SceneError(f"depth: {exc}") from None


def resolve_package_path(path: str) -> str:
    """``package:FILE`` -> the file shipped in tactile_force/edge/assets; other paths unchanged."""
    if path.startswith("package:"):
        return str(ASSETS_DIR / path.split(":", 1)[1])
    return path


def build_depth_stage(settings: object | None = None, manifest: Manifest | None = None) -> DepthStage:
    """The depth stage for D/Dmod/RGBmod+D bundles (imported only for those); settings and
    manifest as in :func:`depth_options_for`.

    Raises
    ------
    SceneError
        As :func:`depth_options_for`, or the mapping file is unusable (``depth``).
    """
    from ..depth import DepthStage  # noqa: PLC0415 - lazy on purpose

    options = depth_options_for(settings, manifest)
    try:
        return DepthStage(options)
    except (TypeError, ValueError) as exc:  # MappingError: the mapping file is unusable
        raise SceneError(f"depth: {exc}") from None


def plan_stages(sensors: Iterable[str], needs_depth: bool, backend: str = "cpu") -> list[str]:
    """Names of the stages a runtime will run, in order, e.g. ['source:left', 'gate:left',
    'inference:cpu']; 'depth:NAME' only for depth bundles."""
    out = []
    for name in sensors:
        out += [f"source:{name}", f"gate:{name}"] + ([f"depth:{name}"] if needs_depth else [])
    return out + [f"inference:{backend}"]


def depth_of(depth: DepthStage, frame: np.ndarray, g: GateResult) -> DepthResult:
    """The depth stage on one gated frame: a stage at the network resolution reads the gate's
    reduced image and mask (the frame's one downscale; its exposure was judged in the gate
    step), otherwise the frame and the full-resolution mask."""
    if g.reduced is not None and g.reduced.shape == depth.grid_frame_shape:
        return depth.process(g.reduced, g.reduced_mask, checked=True)
    return depth.process(frame, g.mask)
