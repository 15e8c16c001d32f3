"""README and docs match the code: every command, link and repo path they name exists."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from tactile_force.edge.cli import COMMANDS

REPO = Path(__file__).resolve().parents[1]
PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md")), *sorted((REPO / "docs" / "benchmarks").glob("*.md"))]
TOP = ("edge/", "export/", "firmware_bridge/", "benchmarks/", "tests/", "docs/", ".ci/")


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_every_command_and_path_named_exists(page):
    text = page.read_text()
    for cmd in re.findall(r"tactile-force ([a-z][a-z-]+)", text):
        assert cmd in COMMANDS, f"{page.name}: 'tactile-force {cmd}' is not a command"
    for link in re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text):
        if "://" in link:
            continue
        assert (page.parent / link).exists(), f"{page.name}: broken link {link}"
    for path in re.findall(r"`((?:%s)[A-Za-z0-9_./-]+)`" % "|".join(re.escape(t) for t in TOP), text):
        if any(ch in path for ch in "*<>") or path.endswith("/N.png"):
            continue
        if path.startswith("benchmarks/cache/"):  # git-ignored outputs a page's command makes (the study's bundles)
            continue
        assert (REPO / path.rstrip("/")).exists(), f"{page.name}: names {path}, which does not exist"


def test_readme_has_no_placeholders():
    text = (REPO / "README.md").read_text()
    assert not re.search(r"\b[A-Z]+_(TABLE|RESULT)\b", text)


def test_readme_is_newcomer_sized():
    lines = (REPO / "README.md").read_text().splitlines()
    assert len(lines) <= 150, f"README.md has {len(lines)} lines; keep it at most 150 (details go to docs/)"


def _ci_job(number: int) -> list[str]:
    """The command lines of .ci/run's job ``number`` (``pip install -q`` read as ``pip install``)."""
    text = (REPO / ".ci" / "run").read_text()
    job = text.split(f"== job {number}/")[1].split("== job ")[0]
    return [line.strip().replace("pip install -q ", "pip install ") for line in job.splitlines()]


def test_the_readme_test_command_is_what_ci_runs():
    readme = (REPO / "README.md").read_text()
    blocks = [line.strip() for line in readme.splitlines() if line.startswith("    ") and "pytest" in line]
    assert len(blocks) == 1, f"README.md: expected one indented test command, found {blocks}"
    ci = _ci_job(3)
    for command in (c.strip() for c in blocks[0].split("&&")):
        assert command in ci, f"README.md's test command '{command}' is not what .ci/run's job 3 runs"
    for torch in re.findall(r"`(pip install torch==[0-9.]+)`", readme):
        assert torch in ci, f"README.md says CI runs '{torch}'; .ci/run's job 3 does not"


def test_a_missing_shared_data_skip_says_what_the_data_is_and_where_it_comes_from(tmp_path, monkeypatch):
    from tests import conftest

    monkeypatch.setattr(conftest, "SHARED_DATA", tmp_path / "nowhere")
    with pytest.raises(pytest.skip.Exception) as skip:
        conftest.shared_data("aurova_digit_grasp")
    reason = str(skip.value)
    for what in ("DIGIT frames", "forces", "depth", "backgrounds", "ball presses", "GelSight", "AUROVA-LAB",
                 "README.md", "TACTILE_FORCE_SHARED_DATA", str(tmp_path / "nowhere")):
        assert what in reason, f"the skip reason does not say {what!r}: {reason}"
    assert "to ../shared/data" not in reason  # the default that was missing is no advice
