"""Every verb keeps the package's promises: the catalogue's categories of
benchmarks/robustness_verbs.py (result folders, interruption, the statistics floor, labelled data
judged before work, the Python API's argument types, honest states), every case run here on
tiny data with a few generated examples. No case may end as a traceback, silent wrong, data
lost, hang or valid refused; the failures name every case that did."""

from __future__ import annotations

import pytest
from hypothesis import given

from benchmarks.robustness_inputs import run_cases
from benchmarks.robustness_verbs import CATEGORIES, Inputs, probe_option, wrong_options
from tests.robustness.conftest import ROBUST

#: generated examples per generated category here (the catalogue runs 100)
EXAMPLES = 5


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> Inputs:
    """12 labelled frames, a background, the default bundle, a tiny fp32 bundle (torch)."""
    return Inputs.make(tmp_path_factory.mktemp("verbs"))


@pytest.mark.parametrize("key", [key for key, _, _ in CATEGORIES])
def test_every_case_of_the_category_keeps_the_promises(inputs, key):
    _, name, build = next(c for c in CATEGORIES if c[0] == key)
    cases, note = build(inputs, EXAMPLES)
    assert cases, f"{name}: no cases ({note})"
    bad: list[str] = []
    run_cases(cases, lambda v: None if v.ok else bad.append(str(v)))
    assert not bad, f"{len(bad)} of {len(cases)} cases of '{name}' went wrong:\n" + "\n".join(bad)


@ROBUST
@given(wrong_options())
def test_a_wrong_typed_option_is_refused_at_construction_naming_it(case):
    cls_name, field, value = case
    v = probe_option(cls_name, field, value)
    assert v.ok, str(v)
