"""Old module paths and old public names keep working: ``import tactile_force.edge.manifest``
or ``from tactile_force.edge.judging import EstimateJudge`` gives what now holds them, with a
DeprecationWarning naming the new home; a name that no longer exists raises an ImportError
naming what replaced it.

The data below was generated from the repository's history (every module path that was
renamed or deleted, ``git log -M --diff-filter=DR``; every name a module once made public that
it no longer has) and is the one place old names are mapped; tests/edge/test_moved.py checks
every entry, and that the history holds no old name missing from it.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
import types
import warnings
from collections.abc import Callable, Sequence
from typing import Any

#: old module (under tactile_force.edge) -> the modules that now hold its names (first: the main one)
MOVED: dict[str, tuple[str, ...]] = {
    "atomic": ("files.atomic",),
    "output_guard": ("files.guard",),
    "background_check": ("gate.given_background",),
    "background_policy": ("gate.learning",),
    "gate_checks": ("gate.checks",),
    "reduce": ("gate.reduce",),
    "manifest": ("bundle.manifest",),
    "data_stats": ("bundle.data_stats", "fitting.data_stats"),
    "interval": ("bundle.interval", "fitting.interval"),
    "force_calibration": ("bundle.force_calibration",),
    "graph_facts": ("bundle.graph_facts",),
    "inference": ("model.onnx_model", "model.ladder"),
    "grabbers": ("runtime.grabbers",),
    "judging": ("runtime.judging",),
    "dataset": ("data.dataset",),
    "labels": ("data.labels",),
    "metrics": ("data.metrics",),
    "calibrate_force": ("fitting.calibrate", "fitting.force_calibration", "cli.calibrate_force"),
    "cli_args": ("cli.args",),
    "cli_bench": ("cli.bench",),
    "cli_bundle": ("cli.bundle",),
    "cli_runtime": ("cli.run", "cli.demo", "cli.scene", "cli.replay_report", "data.metrics"),
    "depth.cli": ("cli.calibrate_depth",),
    "synthetic.cli": ("cli.synth",),
    "logs": ("report.logs",),
    "progress": ("report.progress",),
    "plots": ("report.plots",),
    "mcap_output": ("outputs.mcap_log",),
    "ros2_output": ("outputs.ros2_topic",),
    "ros2_messages": ("outputs.ros2_messages",),
    "ros2_names": ("outputs.ros2_names",),
    "foxglove_live": ("outputs.foxglove_live",),
}

#: module (under tactile_force.) -> {old name: its new home, "module.name" under tactile_force.}
RENAMED: dict[str, dict[str, str]] = {
    "edge.cli.bundle": {"files_outside": "edge.bundle.store.files_outside"},
    "edge.cli.main": {"Interrupted": "edge.interrupts.Interrupted"},
    "edge": {
        **{n: f"edge.bundle.manifest.{n}" for n in ("DEPTH_VARIANTS", "PRECISIONS", "VARIANTS")},
        "sha256_file": "edge.bundle.store.sha256_file", "open_v4l2": "edge.sources.open_v4l2",
        "plan_stages": "edge.runtime.plan_stages", "fit_interval": "edge.fitting.interval.fit_interval",
        "AuthorsDatasetWriter": "edge.data.dataset.AuthorsDatasetWriter", "Sample": "edge.data.dataset.Sample",
        **{n: f"edge.data.metrics.{n}" for n in ("ErrorStats", "error_report", "error_stats", "relative_error",
                                                 "ErrorBreakdown")},
        "ErrorReport": "edge.data.metrics.ErrorBreakdown",
        **{n: f"edge.depth.{n}" for n in ("DepthOptions", "DepthResult", "DepthStage", "MaxDeformationBaseline",
                                          "NormalLUT")},
        **{n: f"edge.synthetic.{n}" for n in ("ContactSpec", "DatasetOptions", "DatasetSummary", "IndenterSplit",
                                              "SyntheticFrame", "VirtualDigit", "VirtualDigitOptions",
                                              "generate_dataset", "indenter_split", "paper_split", "split_ids")},
    },
    "edge.manifest": {"OutputSpec": "edge.bundle.manifest.ModelOutputSpec"},
    "edge.judging": {"EstimateJudge": "edge.runtime.judging.Judge"},
    "edge.runtime.judging": {"EstimateJudge": "edge.runtime.judging.Judge"},
    "edge.metrics": {"ErrorReport": "edge.data.metrics.ErrorBreakdown"},
    "edge.data.metrics": {"ErrorReport": "edge.data.metrics.ErrorBreakdown"},
    "edge.cli_runtime": {
        "main_run": "edge.cli.run.main", "configure_run": "edge.cli.run.configure",
        "main_demo": "edge.cli.demo.main", "configure_demo": "edge.cli.demo.configure",
        "main_scene": "edge.cli.scene.main", "configure_scene": "edge.cli.scene.configure",
        "depth_problems": "edge.scene.preflight.depth_problems", "scene_inputs": "edge.scene.preflight.scene_inputs",
        **{n: f"edge.cli.args.{n}" for n in ("positive_int", "positive_float", "non_negative_int")},
    },
    "edge.cli.run": {
        "main_run": "edge.cli.run.main", "configure_run": "edge.cli.run.configure",
        "main_demo": "edge.cli.demo.main", "configure_demo": "edge.cli.demo.configure",
        "main_scene": "edge.cli.scene.main", "configure_scene": "edge.cli.scene.configure",
        **{n: f"edge.cli.demo.{n}" for n in ("DemoSummary", "PLOT_NAME", "run_demo")},
        **{n: f"edge.data.metrics.{n}" for n in ("cnn_readings", "readings_error")},
    },
    "edge.bundle": {n: f"edge.bundle.manifest.{n}" for n in ("DEPTH_VARIANTS", "FORMAT_VERSION", "Manifest",
                                                             "PRECISIONS", "VARIANTS")},
    "edge.bundle.data_stats": {n: f"edge.fitting.data_stats.{n}" for n in ("compute_data_stats",
                                                                           "frames_data_stats", "no_frames_warning")},
    "edge.fitting.calibrate": {
        **{n: f"edge.fitting.force_calibration.{n}" for n in ("EXTRAPOLATE_TO_N", "METHODS", "fit_knots", "pav",
                                                              "spearman")},
        **{n: f"edge.cli.calibrate_force.{n}" for n in ("configure", "main", "plot_path")},
    },
    "edge.scene": {"ASSETS_DIR": "edge.runtime.ASSETS_DIR"},
    "export.cli": {n: f"edge.cli.bundle.{n}" for n in ("configure_bundle", "main_bundle")},
    "export.preprocess": {"check_batch": "edge.frames.check_batch"},
}

_KEYS_GONE = ("use typed dataclasses: scene keys are typed dataclasses read by tactile_force.edge.typed_json "
              "(tactile_force.edge.scene.kinds, tactile_force.edge.scene.model)")
#: module (under tactile_force.) -> {name that no longer exists: what replaced it}
GONE: dict[str, dict[str, str]] = {
    "edge.errors": {"SensorMismatchError": "nothing raised it; a reading from another sensor than the "
                                           "calibration's is flagged out_of_distribution (tactile_force.edge.Flags)"},
    "edge.inference": {"error_score": "use the method Manifest.error_score() (tactile_force.edge.bundle.manifest)"},
    "edge.bundle": {"TensorSpec": "use tactile_force.edge.bundle.manifest.InputSpec and ModelOutputSpec"},
    "edge.scene": {"Key": _KEYS_GONE},
    "edge.scene.model": {"Key": _KEYS_GONE},
    "export.quantize": {"vars_of": "use dataclasses.asdict"},
    "edge.gate.frame_work": {"load_kernels": "nothing compiles when a gate is made: tactile_force.edge.compiled_path "
                                             "loads the compiled kernels from numba's cache (compile them once with "
                                             "'tactile-force kernels', or compiled_path.load())"},
    "edge.runtime.prewarm": {"MARGIN_NS": "the margin before a frame is measured on the host (how early frames came "
                                          "against their prediction): Prewarm.lead_ns"},
}

#: module (under tactile_force.) that no longer exists -> what replaced it
GONE_MODULES: dict[str, str] = {
    "export.measure": "latency is measured by 'tactile-force bench' (tactile_force.benchmarks.bench) and the "
                      "repository's benchmarks/ pages",
    "edge.depth.sine_halves": "the DST-I by even and odd halves was tried and retired (the repository's "
                              "docs/benchmarks/dst_halves.md); the Poisson solve keeps the dense sine products "
                              "(tactile_force.edge.depth.poisson)",
}

_ROOT = "tactile_force."
_EDGE = _ROOT + "edge."


def _object(home: str) -> Any:
    """The object at ``home`` ("module.name" under tactile_force.)."""
    module, _, name = (_ROOT + home).rpartition(".")
    return getattr(importlib.import_module(module), name)


def old_name(module: str, name: str) -> Any:
    """``module.name`` for a name the module no longer has: the object now at its new home,
    with a DeprecationWarning naming it; an ImportError naming what replaced a name that is
    gone; else AttributeError."""
    key = module.removeprefix(_ROOT)
    home = RENAMED.get(key, {}).get(name)
    if home is not None:
        warnings.warn(f"{module}.{name} is now {_ROOT}{home}; import it from there", DeprecationWarning,
                      stacklevel=3)
        return _object(home)
    gone = GONE.get(key, {}).get(name)
    if gone is not None:
        raise ImportError(f"{module}.{name} no longer exists: {gone}", name=module)
    raise AttributeError(f"module {module!r} has no attribute {name!r}")


def getattr_for(module: str) -> Callable[[str], Any]:
    """A module-level ``__getattr__`` (PEP 562) serving ``module``'s old names."""

    def __getattr__(name: str) -> Any:
        return old_name(module, name)

    return __getattr__


class _MovedModule(types.ModuleType):
    """Stands for an old module: attributes come from the modules that now hold them."""

    def __init__(self, name: str, targets: Sequence[str]) -> None:
        super().__init__(name, f"Moved: use {', '.join(_EDGE + t for t in targets)}.")
        self._targets = [importlib.import_module(_EDGE + t) for t in targets]

    def __getattr__(self, attr: str) -> object:
        if attr.startswith("__"):
            raise AttributeError(attr)
        key = self.__name__.removeprefix(_ROOT)
        if attr in RENAMED.get(key, {}) or attr in GONE.get(key, {}):
            return old_name(self.__name__, attr)
        for mod in self._targets:
            if hasattr(mod, attr):
                return getattr(mod, attr)
        raise AttributeError(f"module {self.__name__!r} has no attribute {attr!r} (it moved: "
                             f"{', '.join(m.__name__ for m in self._targets)})")

    def __dir__(self) -> list[str]:
        return sorted({n for m in self._targets for n in dir(m)})


class _Loader(importlib.abc.Loader):
    def __init__(self, old: str) -> None:
        self.old = old

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> types.ModuleType:
        targets = MOVED[self.old]
        warnings.warn(f"{spec.name} moved to {', '.join(_EDGE + t for t in targets)}; import it from there",
                      DeprecationWarning, stacklevel=2)
        return _MovedModule(spec.name, targets)

    def exec_module(self, module: types.ModuleType) -> None:
        return None


class _Finder(importlib.abc.MetaPathFinder):
    """Old module paths (:data:`MOVED`, :data:`GONE_MODULES`); and, for a module with old
    names (:data:`RENAMED`, :data:`GONE`), the real module given a ``__getattr__`` serving them."""

    def find_spec(self, fullname: str, path: object = None, target: object = None
                  ) -> importlib.machinery.ModuleSpec | None:
        if not fullname.startswith(_ROOT):
            return None
        key = fullname[len(_ROOT):]
        if key in GONE_MODULES:
            raise ImportError(f"{fullname} no longer exists; {GONE_MODULES[key]}", name=fullname)
        if fullname.startswith(_EDGE) and fullname[len(_EDGE):] in MOVED:
            return importlib.util.spec_from_loader(fullname, _Loader(fullname[len(_EDGE):]))
        if key in RENAMED or key in GONE:
            return self._real_spec_with_old_names(fullname, path, target)
        return None

    def _real_spec_with_old_names(self, fullname: str, path: object, target: object
                                  ) -> importlib.machinery.ModuleSpec | None:
        for finder in sys.meta_path:
            if finder is self or not hasattr(finder, "find_spec"):
                continue
            spec = finder.find_spec(fullname, path, target)  # type: ignore[arg-type]
            if spec is None:
                continue
            loader = spec.loader
            if loader is not None and hasattr(loader, "exec_module"):
                run = loader.exec_module

                def exec_module(module: types.ModuleType, run: Callable[[types.ModuleType], None] = run) -> None:
                    run(module)
                    _serve_old_names(module)

                loader.exec_module = exec_module  # type: ignore[method-assign]
            return spec
        return None


def _serve_old_names(module: types.ModuleType) -> None:
    """Give ``module`` a ``__getattr__`` for its old names, unless it has its own."""
    if "__getattr__" not in module.__dict__:
        module.__getattr__ = getattr_for(module.__name__)  # type: ignore[method-assign]


def install() -> None:
    """Put the finder first on ``sys.meta_path`` once, and serve the old names of the
    modules already imported."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.insert(0, _Finder())
    for key in (*RENAMED, *GONE):
        module = sys.modules.get(_ROOT + key)
        if module is not None:
            _serve_old_names(module)
