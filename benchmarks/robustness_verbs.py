"""Every verb keeps the package's promises: cases for the robustness catalogue
(benchmarks/robustness.py) on the verbs that write result folders (``bench``, ``study``,
``synth``, ``demo``), their interruption, the statistics floor of a p99 verdict, labelled data
judged before any work, the Python API's argument types and the honest states (``bundle
verify`` claims, learning-time intervals, ``scene show`` answering as ``run``).

Each case is the user's command through the CLI in-process (a subprocess for signals) or a
call of the public API, classified like every other case of the catalogue: ``data lost`` when a
user's file or an input changed or vanished (or an earlier result was lost), ``silent wrong``
when a bad input was taken or a success exit (or a verdict) came from a partial or meaningless
result, ``traceback`` on an uncaught exception, a CLI traceback or a wrong exit code, ``hang``
when it did not answer in time.

Each category is a function ``(inputs, examples) -> (cases, note)`` listed in
:data:`CATEGORIES`, in its own module (robustness_verb_folders.py, _signals.py, _checks.py, _api.py; what
they share in robustness_verb_base.py); ``cases`` are ``(what, probe)`` pairs run by
:func:`benchmarks.robustness_inputs.run_cases`. ``tests/robustness/test_verb_promises.py``
runs the same categories on a few generated examples.
"""

from __future__ import annotations

from collections.abc import Callable

from .robustness_verb_api import (  # noqa: F401 - re-exported
    _COMMON_WRONG,
    SCENE_KINDS,
    _accepts,
    _edited_bundle,
    _kind,
    _options_classes,
    _valid,
    _verify,
    api_cases,
    honest_cases,
    probe_construct,
    probe_learning,
    probe_option,
    probe_scene_show,
    probe_verify,
    wrong_options,
    wrong_values,
)
from .robustness_verb_base import (  # noqa: F401 - re-exported
    _MARK,
    _OWN_NAME,
    FLOOR,
    START_S,
    STOP_S,
    UNSET_VAR,
    VERBS,
    Case,
    Cases,
    Inputs,
    Verb,
    _bench,
    _csv_lines,
    _demo,
    _either,
    _kept,
    _staging,
    _Stderr,
    _study,
    _synth,
    _users_folder,
    _with_leftovers,
    drawn,
    leftovers,
    tiny_fp32_bundle,
    tree,
)
from .robustness_verb_checks import BAD_ID, _bad_images, floor_cases, labelled_cases, probe_floor, probe_labelled  # noqa: F401 - re-exported
from .robustness_verb_folders import _claim_cases, _proof_cases, _result_cases, result_folder_cases, side_file_cases  # noqa: F401 - re-exported
from .robustness_verb_signals import _AT_WORK, _complete_csv, _no_finished_look, _writing, probe_signal, signal_cases  # noqa: F401 - re-exported

CATEGORIES: list[tuple[str, str, Callable[[Inputs, int], Cases]]] = [
    ("result_folders", "result folders (bench, study, synth, demo: the user's files, earlier results, --out onto "
                       "inputs; plots beside an output)", result_folder_cases),
    ("interruption", "interrupted verbs (SIGINT / SIGTERM during bench, study, synth, demo, run, compress)",
     signal_cases),
    ("statistics_floor", "statistics floor (bench / study --frames 1, 5, 50, 99, 100)", floor_cases),
    ("labelled_data", "labelled data judged before work (bad images for bench, study, calibrate-force, run)",
     labelled_cases),
    ("api_types", "Python API argument types (fixed calls; generated wrong types for GateOptions, RuntimeOptions)",
     api_cases),
    ("honest_states", "honest states (bundle verify claims, learning-time intervals, scene show as run)",
     honest_cases),
]
