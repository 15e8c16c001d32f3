"""Old module paths of ``tactile_force.edge`` keep working: ``import tactile_force.edge.manifest``
gives the module that now holds those names, with a DeprecationWarning naming the new path.

The package was laid out by job (``bundle/``, ``gate/``, ``runtime/``, ...); the flat module
names it had before are mapped here, and nowhere else.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import types
import warnings
from collections.abc import Sequence

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
}

_PREFIX = __name__.rsplit(".", 1)[0] + "."


class _MovedModule(types.ModuleType):
    """Stands for an old module: attributes come from the modules that now hold them."""

    def __init__(self, name: str, targets: Sequence[str]) -> None:
        super().__init__(name, f"Moved: use {', '.join(_PREFIX + t for t in targets)}.")
        self._targets = [importlib.import_module(_PREFIX + t) for t in targets]

    def __getattr__(self, attr: str) -> object:
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
        warnings.warn(f"{spec.name} moved to {', '.join(_PREFIX + t for t in targets)}; import it from there",
                      DeprecationWarning, stacklevel=2)
        return _MovedModule(spec.name, targets)

    def exec_module(self, module: types.ModuleType) -> None:
        return None


class _Finder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname: str, path: object = None, target: object = None
                  ) -> importlib.machinery.ModuleSpec | None:
        if not fullname.startswith(_PREFIX):
            return None
        old = fullname[len(_PREFIX):]
        if old not in MOVED:
            return None
        return importlib.util.spec_from_loader(fullname, _Loader(old))


def install() -> None:
    """Put the finder on ``sys.meta_path`` once."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.append(_Finder())
