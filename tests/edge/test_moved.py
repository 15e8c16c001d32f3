"""Every old module path and old public name (edge/_moved.py, made from the git history)
imports with a DeprecationWarning naming its new home, or raises an ImportError naming what
replaced it; and the history holds no old name that edge/_moved.py misses."""

from __future__ import annotations

import importlib
import sys
import warnings

import pytest
from tactile_force.edge import _moved

MODULES = sorted(_moved.MOVED)
RENAMED = sorted((m, n, home) for m, names in _moved.RENAMED.items() for n, home in names.items())
GONE = sorted((m, n, what) for m, names in _moved.GONE.items() for n, what in names.items())
_EXTRAS = ("mcap", "cyclonedds", "foxglove")


@pytest.fixture(autouse=True)
def _old_modules_forgotten():
    """Old module paths imported here leave sys.modules as they found it (their first import warns)."""
    before = set(sys.modules)
    yield
    for key in set(sys.modules) - before:
        if isinstance(sys.modules[key], _moved._MovedModule):
            del sys.modules[key]


def _needs_torch(module: str) -> None:
    """tactile_force.export needs torch (the 'export' extra): skip its names where it is absent."""
    if module.startswith("export"):
        pytest.importorskip("torch", reason="tactile_force.export needs torch (the 'export' extra)")


def _fresh_import(name: str):
    for key in [k for k in sys.modules if k == name or k.startswith(name + ".")]:
        del sys.modules[key]
    return importlib.import_module(name)


@pytest.mark.parametrize("old", MODULES)
def test_an_old_module_path_imports_and_warns_naming_its_new_home(old):
    targets = _moved.MOVED[old]
    try:
        for t in targets:
            importlib.import_module(f"tactile_force.edge.{t}")
    except ImportError as exc:
        if (exc.name or "").split(".")[0] in _EXTRAS:
            pytest.skip(f"needs an extra: {exc}")
        raise
    with pytest.warns(DeprecationWarning, match=rf"tactile_force\.edge\.{old} moved to tactile_force\.edge\."
                                                rf"{targets[0]}"):
        module = _fresh_import(f"tactile_force.edge.{old}")
    main = importlib.import_module(f"tactile_force.edge.{targets[0]}")
    public = [n for n in dir(main) if not n.startswith("_")]
    assert public and all(getattr(module, n) is getattr(main, n) for n in public[:20])


@pytest.mark.parametrize("module, name, home", RENAMED, ids=[f"{m}.{n}" for m, n, _ in RENAMED])
def test_an_old_name_imports_and_warns_naming_its_new_home(module, name, home):
    _needs_torch(module)
    new_module, _, new_name = f"tactile_force.{home}".rpartition(".")
    expected = getattr(importlib.import_module(new_module), new_name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # the old module's own warning
        old = importlib.import_module(f"tactile_force.{module}")
    with pytest.warns(DeprecationWarning, match=rf"tactile_force\.{module}\.{name} is now tactile_force\.{home}"):
        got = getattr(old, name)
    assert got is expected
    with pytest.warns(DeprecationWarning, match=rf"tactile_force\.{home}"):
        namespace: dict = {}
        exec(f"from tactile_force.{module} import {name}", namespace)
    assert namespace[name] is expected


@pytest.mark.parametrize("module, name, what", GONE, ids=[f"{m}.{n}" for m, n, _ in GONE])
def test_a_name_that_is_gone_raises_an_import_error_naming_what_replaced_it(module, name, what):
    _needs_torch(module)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        with pytest.raises(ImportError) as info:
            exec(f"from tactile_force.{module} import {name}", {})
    assert name in str(info.value) and what in str(info.value)


@pytest.mark.parametrize("module", sorted(_moved.GONE_MODULES))
def test_a_module_that_is_gone_raises_an_import_error_naming_what_replaced_it(module):
    _needs_torch(module)
    with pytest.raises(ImportError, match="no longer exists") as info:
        importlib.import_module(f"tactile_force.{module}")
    assert _moved.GONE_MODULES[module] in str(info.value)


def test_an_unknown_name_is_still_an_attribute_error():
    import tactile_force.edge.errors as errors

    with pytest.raises(AttributeError):
        errors.NoSuchThing  # noqa: B018
    assert not hasattr(errors, "NoSuchThing")


def test_every_old_module_path_and_public_name_in_the_history_still_imports():
    """Made from the repository's history: every module that ever existed, every name any
    version of it made public."""
    from benchmarks.harness.paths import require_repo
    from benchmarks.robustness_cli import history_names, old_name_verdict

    names = history_names(require_repo("this test"))
    if not names:
        pytest.skip("no git history here (a source archive)")
    assert "tactile_force.edge.mcap_output" in names and "OutputSpec" in names["tactile_force.edge.manifest"]
    bad = [str(v) for module in sorted(names) for name in [None, *sorted(names[module])]
           if not (v := old_name_verdict(module, name)).ok]
    assert not bad, bad
