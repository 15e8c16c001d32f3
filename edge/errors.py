"""Exception types shared by the whole package.

Every error names the input it rejects and what was expected, so a message read in a
robot's log is enough to fix the cause.
"""

from __future__ import annotations


class TactileForceError(Exception):
    """Base class of every error this package raises on purpose."""


class FrameError(TactileForceError, ValueError):
    """A frame has the wrong shape, dtype, colour order or content."""


class CheckFailedError(TactileForceError):
    """A check the user asked for failed (parity, verify, latency budget) or a run lost
    every sensor: the CLI exits 1, where bad input exits 2."""


class BundleError(TactileForceError):
    """A model bundle is missing, truncated, corrupted or does not match its manifest."""


class ModelClosedError(TactileForceError):
    """A model (or a runtime) was used after ``close()``; the message names the bundle."""


class OptionsError(TactileForceError, ValueError):
    """An options object (RuntimeOptions, ...) or a constructor argument holds a value outside
    its range; the message names the field or parameter and what was expected."""


class ArgumentTypeError(TactileForceError, TypeError, ValueError):
    """A constructor argument or an options field has the wrong type (``ContactGate("x")``,
    ``GateOptions(threshold="x")``); the message names the parameter and the expected type.

    A TypeError, and also a ValueError (as numpy's AxisError is both a ValueError and an
    IndexError): code that caught the ValueError some options raised for a wrong type before
    keeps working."""


class DatasetError(TactileForceError):
    """A labelled dataset on disk is missing files or holds unparsable ones."""


class SourceError(TactileForceError):
    """A frame source failed (device gone, file unreadable)."""


class SceneError(TactileForceError, ValueError):
    """A scene file is malformed or asks for something that cannot be built."""


class AcceleratorUnavailableError(TactileForceError):
    """An accelerator backend (OAK) cannot run here: no device, busy, unusable model.

    A runtime that may fall back to the CPU backend catches this one type.
    """


class MissingExtraError(TactileForceError, ImportError):
    """An optional dependency is needed; the message names the extra to install."""

    def __init__(self, module: str, extra: str, purpose: str) -> None:
        super().__init__(
            f"{purpose} needs the Python module '{module}', which is not installed. "
            f"Install it with: pip install 'tactile-force[{extra}]'"
        )
        self.module = module
        self.name = module  # ImportError's own field: the module that is not there
        self.extra = extra


def require(module: str, extra: str, purpose: str):
    """Import an optional module or raise :class:`MissingExtraError` with one clear line."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise MissingExtraError(module, extra, purpose) from exc
