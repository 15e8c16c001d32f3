"""``edge/report/host.py``: the one line naming the host a figure was made on."""

from __future__ import annotations

import os

from tactile_force.edge.report.host import cpu_line, cpu_model


def test_the_cpu_line_names_the_model_and_the_cores():
    assert cpu_line("Intel(R) Xeon(R) CPU", 2) == "CPU: Intel(R) Xeon(R) CPU, 2 logical cores"
    assert cpu_line("X", 1) == "CPU: X, 1 logical core"
    here = cpu_line()
    assert here.startswith(f"CPU: {cpu_model()}, ") and here.endswith(f"{os.cpu_count() or 1} logical cores"
                                                                      if (os.cpu_count() or 1) != 1 else "core")


def test_the_model_is_read_from_cpuinfo_where_there_is_one():
    try:
        with open("/proc/cpuinfo") as f:
            names = [ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")]
    except OSError:
        names = []
    model = cpu_model()
    assert model and (not names or model == names[0])
