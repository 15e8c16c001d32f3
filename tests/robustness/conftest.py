"""Shared settings of the robustness suite: bounded hypothesis runs (the suite stays well
under a minute), no example database written into the repo."""

from __future__ import annotations

from hypothesis import HealthCheck, settings

settings.register_profile("robustness", max_examples=30, deadline=None, database=None,
                          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

#: Use as a decorator on every @given test here: ``@ROBUST``.
ROBUST = settings(settings.get_profile("robustness"))
