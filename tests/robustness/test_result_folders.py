"""Every verb that writes a folder of results publishes it whole: a new or empty --out, or
(--force) an earlier result of the same verb whose record proves every entry; never a half
folder after an interruption (exit 130 for SIGINT, 143 for SIGTERM, the previous result left as
it was). The output is claimed before the work (a second run is refused), judged before the work
(a link, a mount point, a read-only parent, too little space), and what appeared in it while the
verb ran is never deleted."""

from __future__ import annotations

import errno
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from tactile_force.edge.cli import main
from tactile_force.edge.files import atomic
from tactile_force.edge.files.atomic import OUTPUT_MARK, foreign_files, staged_folder
from tactile_force.edge.files.claim import OutputBusy, OutputClaim
from tactile_force.edge.files.guard import OutputRefused

TF_CLI = Path(__file__).with_name("tf_cli.py")


def test_staged_folder_publishes_whole_or_leaves_the_previous_result(tmp_path):
    out = tmp_path / "r"
    with staged_folder(out, "bench") as tmp:
        (tmp / "a.txt").write_text("1")
        assert not out.exists()  # nothing visible until the block ends
    assert (out / "a.txt").read_text() == "1" and foreign_files(out, "bench") == []
    record = json.loads((out / OUTPUT_MARK).read_text())
    assert record["verb"] == "bench" and record["format"] == 2
    assert record["files"] == {"a.txt": {"size": 1, "sha256": hashlib.sha256(b"1").hexdigest()}}
    assert (record["folder"]["st_dev"], record["folder"]["st_ino"]) == (out.stat().st_dev, out.stat().st_ino)
    with pytest.raises(KeyboardInterrupt), staged_folder(out, "bench", force=True) as tmp:
        (tmp / "a.txt").write_text("half")
        raise KeyboardInterrupt
    assert (out / "a.txt").read_text() == "1"  # the previous result, untouched
    assert [p.name for p in tmp_path.iterdir()] == ["r"]  # no staging, no claim file left


def test_foreign_files_name_what_the_verb_did_not_write(tmp_path):
    out = tmp_path / "r"
    with staged_folder(out, "study") as tmp:
        (tmp / "bundles").mkdir()
        (tmp / "bundles" / "x.onnx").write_text("x")
    (out / "bundles" / "NOTES.txt").write_text("mine")
    assert foreign_files(out, "study") == ["bundles/NOTES.txt"]
    assert foreign_files(out, "bench") == ["bundles", "bundles/NOTES.txt", "bundles/x.onnx"]  # another verb's


SYNTH = ["synth", "--n", "3", "--seed", "0", "--no-progress"]


def test_synth_never_adds_to_or_replaces_a_folder_unasked(tmp_path, capsys):
    out = tmp_path / "d"
    assert main([*SYNTH, "--out", str(out)]) == 0
    first = (out / "forces" / "force_0.txt").read_text()
    assert main([*SYNTH, "--out", str(out), "--seed", "1"]) == 2  # exists: --force needed
    assert "--force" in capsys.readouterr().err
    assert main([*SYNTH, "--out", str(out), "--seed", "1", "--force"]) == 0  # its own earlier dataset
    assert (out / "forces" / "force_0.txt").read_text() != first
    (out / "my_labels.txt").write_text("mine")
    assert main([*SYNTH, "--out", str(out), "--force"]) == 2  # a file synth did not write: never deleted
    assert (out / "my_labels.txt").read_text() == "mine"


def test_demo_replaces_only_its_own_earlier_result(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--grasps", "1"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert Path(summary["readings_csv"]) == out / "readings.csv"  # the published path, not the staging one
    assert main(["demo", "--out", str(out), "--grasps", "1"]) == 2
    assert main(["demo", "--out", str(out), "--grasps", "1", "--force"]) == 0
    (out / "notes.md").write_text("mine")
    assert main(["demo", "--out", str(out), "--grasps", "1", "--force"]) == 2
    assert (out / "notes.md").read_text() == "mine"


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_synth_leaves_no_half_dataset(tmp_path, sig):
    out = tmp_path / "d"
    proc = subprocess.Popen([sys.executable, "-m", "tactile_force.edge.cli", "synth", "--out", str(out), "--n",
                             "100000", "--no-progress"], stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    staging: list[Path] = []
    while time.monotonic() < deadline and not staging:  # rendering has started
        staging = [p for p in tmp_path.iterdir() if p.name.startswith(".d.") and p.name.endswith(".partial")]
        time.sleep(0.05)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not list((staging[0] / "images").glob("*.png")):
        time.sleep(0.05)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + int(sig), err
    assert "Traceback" not in err
    assert not out.exists() and list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------- the record proves what the verb wrote
def _tree(root: Path) -> dict[str, str]:
    """relative path -> sha256 (files), 'dir' (folders), '-> target' (links), links not followed."""
    out: dict[str, str] = {}
    for p in sorted(root.rglob("*")):
        rel = str(p.relative_to(root))
        out[rel] = (f"-> {os.readlink(p)}" if p.is_symlink() else "dir" if p.is_dir()
                    else hashlib.sha256(p.read_bytes()).hexdigest())
    return out


def _synth(out: Path, *extra: str) -> int:
    return main([*SYNTH, "--out", str(out), *extra])


@pytest.fixture
def earlier(tmp_path) -> Path:
    """An earlier synth dataset made in place (its record proves it)."""
    out = tmp_path / "d"
    assert _synth(out) == 0
    return out


def test_a_names_only_record_listing_a_users_file_proves_nothing(tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("my notes\n")
    for verb in ("synth", "bench"):  # an earlier version's record: names only
        (out / OUTPUT_MARK).write_text(json.dumps({"verb": verb, "files": ["notes.txt"]}))
        before = _tree(out)
        argv = ([*SYNTH, "--out", str(out)] if verb == "synth" else
                ["bench", "--frames", "100", "--cadence-frames", "100", "--fps", "200", "--out", str(out)])
        assert main([*argv, "--force"]) == 2
        err = capsys.readouterr().err
        assert "notes.txt" in err and "names only" in err, err
        assert _tree(out) == before


def test_a_record_copied_with_its_folder_proves_nothing_there(earlier, tmp_path, capsys):
    copy = Path(shutil.copytree(earlier, tmp_path / "backup", symlinks=True))  # the user's backup copy
    before = _tree(copy)
    assert _synth(copy, "--force") == 2
    assert "another folder" in capsys.readouterr().err
    assert _tree(copy) == before


@pytest.mark.parametrize("change", ["link", "empty folder", "edited file", "added file", "special file"])
def test_force_keeps_what_the_user_changed_in_a_result_and_names_it(earlier, tmp_path, capsys, change):
    target = tmp_path / "elsewhere.txt"
    target.write_text("the link's target\n")
    name = {"link": "images/0.png", "empty folder": "my_plots", "edited file": "forces/force_0.txt",
            "added file": "images/my.png", "special file": "fifo"}[change]
    p = earlier / name
    if change == "link":  # a recorded file replaced by a link to the user's own file
        p.unlink()
        p.symlink_to(target)
    elif change == "empty folder":
        p.mkdir()
    elif change == "edited file":
        p.write_text("9.000000\n")  # same length as a recorded label: only the hash tells
    elif change == "added file":
        p.write_bytes(b"mine")
    else:
        os.mkfifo(p)
    before = _tree(earlier) if change != "special file" else None
    assert _synth(earlier, "--force") == 2
    err = capsys.readouterr().err
    assert name in err and "Traceback" not in err, err
    assert os.path.lexists(p) and target.read_text() == "the link's target\n"
    if before is not None:
        assert _tree(earlier) == before


def test_force_replaces_a_result_whose_files_the_user_deleted(earlier):
    (earlier / "images" / "0.png").unlink()  # nothing to lose: a recorded file that is gone
    ino = earlier.stat().st_ino
    assert _synth(earlier, "--force", "--seed", "2") == 0
    assert earlier.stat().st_ino != ino and foreign_files(earlier, "synth") == []


def test_what_appears_in_the_output_while_the_verb_works_is_never_deleted(tmp_path):
    out = tmp_path / "r"
    with staged_folder(out, "bench") as tmp:
        (tmp / "a.txt").write_text("1")
    with pytest.raises(OutputRefused, match="late.txt"), staged_folder(out, "bench", force=True) as tmp:
        (tmp / "a.txt").write_text("2")
        (out / "late.txt").write_text("written while the verb ran")
    assert (out / "late.txt").read_text() == "written while the verb ran" and (out / "a.txt").read_text() == "1"
    new = tmp_path / "new"
    with pytest.raises(OutputRefused, match="appeared"), staged_folder(new, "bench") as tmp:
        (tmp / "a.txt").write_text("2")
        new.mkdir()
        (new / "mine.txt").write_text("mine")
    assert [p.name for p in new.iterdir()] == ["mine.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["new", "r"]  # no staging, no claim file


def test_without_an_exchange_the_two_renames_keep_the_same_promises(tmp_path, monkeypatch):
    monkeypatch.setattr(atomic, "exchange", lambda a, b: False)  # a file system without RENAME_EXCHANGE
    out = tmp_path / "r"
    with staged_folder(out, "bench") as tmp:
        (tmp / "a.txt").write_text("1")
    with staged_folder(out, "bench", force=True) as tmp:
        (tmp / "a.txt").write_text("2")
    assert (out / "a.txt").read_text() == "2"
    with pytest.raises(OutputRefused, match="late.txt"), staged_folder(out, "bench", force=True) as tmp:
        (tmp / "a.txt").write_text("3")
        (out / "late.txt").write_text("mine")
    assert (out / "a.txt").read_text() == "2" and (out / "late.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]


def test_an_earlier_result_caught_between_two_renames_is_put_back(tmp_path):
    out = tmp_path / "r"
    with staged_folder(out, "bench") as tmp:
        (tmp / "a.txt").write_text("1")
    os.rename(out, tmp_path / ".r.0123.old")  # killed after moving the old result aside
    (tmp_path / ".r.4567.partial").mkdir()  # ... and a staging folder that is not ours: kept
    with pytest.raises(OutputRefused, match="already exists"), staged_folder(out, "bench") as tmp:
        pass
    assert (out / "a.txt").read_text() == "1"
    assert sorted(p.name for p in tmp_path.iterdir()) == [".r.4567.partial", "r"]


# ---------------------------------------------------------------- one run per output, judged before the work
def _popen(*argv: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, str(TF_CLI), *argv], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)


def _wait_for(what, proc: subprocess.Popen, timeout: float = 180.0) -> None:
    end = time.monotonic() + timeout
    while not what():
        assert proc.poll() is None, f"ended (exit {proc.returncode}) before it was at work: {proc.stderr.read()}"
        assert time.monotonic() < end, "not at work in time"
        time.sleep(0.05)


def _staged_images(parent: Path, name: str) -> bool:
    return any(list((p / "images").glob("*.png")) for p in parent.glob(f".{name}.*.partial"))


def test_a_second_run_into_the_same_output_is_refused_while_the_first_runs(tmp_path, capsys):
    out = tmp_path / "d"
    first = _popen("synth", "--out", str(out), "--n", "150", "--no-progress")
    try:
        _wait_for(lambda: _staged_images(tmp_path, "d"), first)
        assert _synth(out) == 2
        err = capsys.readouterr().err
        assert "is writing it now" in err and f"pid {first.pid}" in err, err
        assert first.wait(timeout=600) == 0, first.stderr.read()
    finally:
        first.kill()
        first.wait()
    assert len(list((out / "images").glob("*.png"))) == 150
    assert _synth(out) == 2  # a second run after the first: the result exists, --force needed
    assert "--force" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d"]


def test_the_claim_is_exclusive_within_one_process_too(tmp_path):
    with OutputClaim(tmp_path / "r", "bench"), pytest.raises(OutputBusy, match="is writing it now"):
        OutputClaim(tmp_path / "r", "demo").acquire()
    assert list(tmp_path.iterdir()) == []


def test_a_kill_9_leaves_nothing_after_the_next_run(tmp_path):
    out = tmp_path / "d"
    proc = _popen("synth", "--out", str(out), "--n", "100000", "--no-progress")
    try:
        _wait_for(lambda: _staged_images(tmp_path, "d"), proc)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".partial")]  # what kill -9 leaves
    assert _synth(out) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d"]


@pytest.mark.parametrize("target_empty", [True, False])
def test_out_a_symbolic_link_is_refused_never_replaced(tmp_path, capsys, target_empty):
    folder = tmp_path / "my_folder"
    folder.mkdir()
    if not target_empty:
        (folder / "notes.txt").write_text("mine")
    link = tmp_path / "link"
    link.symlink_to(folder)
    for force in ((), ("--force",)):
        assert _synth(link, *force) == 2
        err = capsys.readouterr().err
        assert f"--out {link}: is a symbolic link" in err and str(folder) in err, err
    assert link.is_symlink() and os.readlink(link) == str(folder)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link", "my_folder"]
    assert [p.name for p in folder.iterdir()] == ([] if target_empty else ["notes.txt"])


def _no_work(monkeypatch) -> list[int]:
    """synth's renderer replaced by a counter: a refusal 'before the work' never calls it."""
    from tactile_force.edge.synthetic import generate

    calls: list[int] = []
    monkeypatch.setattr(generate, "generate_dataset", lambda *a, **k: calls.append(1))
    return calls


@pytest.fixture
def small_fs(tmp_path):
    """A real small tmpfs (needs root and mount): the only way to get a mount point, a full disk
    and a read-only file system without faking the OS."""
    if os.geteuid() != 0 or not shutil.which("mount"):
        pytest.skip("needs root and mount(8) for a real tmpfs")
    mounts: list[Path] = []

    def make(name: str, size_kib: int, *opts: str) -> Path:
        p = tmp_path / name
        p.mkdir()
        r = subprocess.run(["mount", "-t", "tmpfs", "-o", ",".join([f"size={size_kib}k", *opts]), "tmpfs", str(p)],
                           capture_output=True, text=True)
        if r.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here: {r.stderr.strip()}")
        mounts.append(p)
        return p

    yield make
    for p in mounts:
        subprocess.run(["umount", str(p)], capture_output=True)


def test_out_a_mount_point_is_refused_before_the_work(small_fs, monkeypatch, capsys):
    calls = _no_work(monkeypatch)
    mnt = small_fs("mnt", 4096)
    assert _synth(mnt) == 2
    err = capsys.readouterr().err
    assert f"--out {mnt}: is a mount point" in err and ".partial" not in err, err
    assert calls == [] and list(mnt.iterdir()) == []


def test_out_under_a_read_only_parent_is_refused_before_the_work(small_fs, monkeypatch, capsys):
    calls = _no_work(monkeypatch)
    ro = small_fs("ro", 512, "ro")
    assert _synth(ro / "d") == 2
    err = capsys.readouterr().err
    assert f"--out {ro / 'd'}:" in err and "read-only file system" in err and ".partial" not in err, err
    assert calls == []


def test_out_under_a_folder_without_write_permission_is_refused_before_the_work(tmp_path, monkeypatch, capsys):
    if os.geteuid() == 0:
        pytest.skip("root writes through permission bits (the read-only file system case covers root)")
    calls = _no_work(monkeypatch)
    parent = tmp_path / "locked"
    parent.mkdir(mode=0o555)
    assert _synth(parent / "d") == 2
    assert "not a writable folder" in capsys.readouterr().err and calls == []


def test_too_little_space_for_the_expected_size_is_refused_before_the_work(small_fs, monkeypatch, capsys):
    calls = _no_work(monkeypatch)
    fs = small_fs("small", 1024)
    assert main(["synth", "--n", "100", "--no-progress", "--out", str(fs / "d")]) == 2
    err = capsys.readouterr().err
    assert f"--out {fs / 'd'}: the result needs about" in err and "free" in err, err
    assert calls == [] and list(fs.iterdir()) == []


def test_a_full_disk_while_writing_names_the_output_and_leaves_nothing(small_fs, capsys):
    fs = small_fs("full", 1600)  # room for the expected 64 kB a sample, not for the real ~117 kB
    out = fs / "d"
    assert main(["synth", "--n", "20", "--no-progress", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"error: {out}" in err and "No space left on device" in err and ".partial" not in err, err
    assert list(fs.iterdir()) == []  # nothing published, no staging, no claim file


def test_an_os_error_without_a_path_names_the_output(tmp_path, monkeypatch, capsys):
    """The write boundary faked (named): an OSError carrying no file name, as a full disk raises
    from ``write()``, comes out naming --out (this case needs no root)."""
    from tactile_force.edge.data import dataset

    def full(path: Path, data: bytes) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(dataset.AuthorsDatasetWriter, "_atomic_write", staticmethod(full))
    out = tmp_path / "d"
    assert _synth(out) == 2
    err = capsys.readouterr().err
    assert f"error: {out}: No space left on device" in err, err
    assert list(tmp_path.iterdir()) == []


def test_an_error_while_the_earlier_result_is_checked_at_publish_puts_it_back(tmp_path, monkeypatch):
    out = tmp_path / "r"
    with staged_folder(out, "bench") as tmp:
        (tmp / "a.txt").write_text("1")
    real = atomic.verify

    def failing(folder, verb, known=None):
        if Path(folder) != out:  # the earlier folder, swapped to the hidden path
            raise OSError(errno.EIO, "Input/output error")
        return real(folder, verb, known)

    monkeypatch.setattr(atomic, "verify", failing)
    with pytest.raises(OSError), staged_folder(out, "bench", force=True) as tmp:
        (tmp / "a.txt").write_text("2")
    assert (out / "a.txt").read_text() == "1" and sorted(p.name for p in tmp_path.iterdir()) == ["r"]


@pytest.mark.parametrize("handler", ["python's", "ignored"])
def test_ctrl_c_while_publishing_waits_until_the_swap_is_whole(tmp_path, monkeypatch, handler):
    # The SIGINT handler the swap meets is set here: a pytest started in the background by a
    # non-interactive shell inherits SIGINT ignored, and an ignored Ctrl-C stays ignored.
    before = signal.signal(signal.SIGINT, signal.default_int_handler if handler == "python's" else signal.SIG_IGN)
    try:
        out = tmp_path / "r"
        with staged_folder(out, "bench") as tmp:
            (tmp / "a.txt").write_text("1")
        real = atomic.verify
        sent = []

        def interrupted(folder, verb, known=None):
            if Path(folder) != out:  # the earlier folder, swapped to the hidden path
                # Ctrl-C in the middle of the swap, aimed at the thread doing it: a process-wide
                # kill may reach another thread, and the handler would then run when it happens to.
                signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)
                sent.append(folder)
            return real(folder, verb, known)

        monkeypatch.setattr(atomic, "verify", interrupted)
        if handler == "python's":
            with pytest.raises(KeyboardInterrupt), staged_folder(out, "bench", force=True) as tmp:
                (tmp / "a.txt").write_text("2")
        else:  # ignored before the swap, ignored after it: the verb ends normally
            with staged_folder(out, "bench", force=True) as tmp:
                (tmp / "a.txt").write_text("2")
        assert len(sent) == 1  # the signal was sent while the earlier folder sat at the hidden path
        assert (out / "a.txt").read_text() == "2"  # delivered once the new result was whole in place
        assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]  # the earlier one removed, nothing hidden
    finally:
        signal.signal(signal.SIGINT, before)
