"""Atomic writes: complete file or nothing; the previous file survives a failure."""

import os
import stat
import sys
import threading
import time
from pathlib import Path

import pytest

from baker.errors import ExportError
from baker.atomic import (OutputSet, atomic_output, atomic_write_bytes, check_outputs,
                          check_writable, read_lock, resolve_out)


def test_writes_and_replaces(tmp_path):
    p = tmp_path / "out.glb"
    atomic_write_bytes(p, b"first")
    atomic_write_bytes(p, b"second")
    assert p.read_bytes() == b"second"
    assert [x.name for x in tmp_path.iterdir()] == ["out.glb"]
    mode = stat.S_IMODE(os.stat(p).st_mode)
    assert mode & 0o044          # readable by others (umask permitting), not mkstemp's 0600


def test_missing_folder_is_a_one_line_export_error(tmp_path):
    with pytest.raises(ExportError) as e:
        atomic_write_bytes(tmp_path / "nope" / "out.glb", b"x")
    assert "\n" not in str(e.value) and "nope" in str(e.value)


def test_check_writable_creates_the_folder_or_fails_in_one_line(tmp_path):
    check_writable(tmp_path / "new" / "deeper")
    assert (tmp_path / "new" / "deeper").is_dir()
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(ExportError) as e:
        check_writable(blocker / "sub")
    assert "\n" not in str(e.value) and "sub" in str(e.value)


@pytest.mark.skipif(sys.platform == "win32" or os.geteuid() == 0,
                    reason="permission bits do not stop root / Windows")
def test_unwritable_folder(tmp_path):
    d = tmp_path / "ro"
    d.mkdir()
    (d / "out.glb").write_bytes(b"old")
    d.chmod(0o555)
    try:
        with pytest.raises(ExportError) as e:
            atomic_write_bytes(d / "out.glb", b"new")
        assert "\n" not in str(e.value)
        with pytest.raises(ExportError):
            check_writable(d)
        assert (d / "out.glb").read_bytes() == b"old"
    finally:
        d.chmod(0o755)


def test_failure_inside_atomic_output_keeps_the_old_file(tmp_path):
    p = tmp_path / "centipede.usd"
    p.write_bytes(b"good")
    with pytest.raises(RuntimeError):
        with atomic_output(p) as tmp:
            assert tmp.parent == tmp_path and tmp.suffix == ".usd" and tmp.name.startswith(".centipede.tmp")
            tmp.write_bytes(b"partial")
            raise RuntimeError("boom")
    assert p.read_bytes() == b"good"
    assert [x.name for x in tmp_path.iterdir()] == ["centipede.usd"]


def test_oserror_inside_atomic_output_becomes_export_error(tmp_path):
    p = tmp_path / "centipede.usda"
    with pytest.raises(ExportError):
        with atomic_output(p) as tmp:
            raise OSError(28, "No space left on device")
    assert list(tmp_path.iterdir()) == []


def test_failed_write_keeps_old_file(tmp_path, monkeypatch):
    p = tmp_path / "out.glb"
    p.write_bytes(b"good")

    def broken_replace(src, dst):
        raise OSError(5, "Input/output error")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(ExportError):
        atomic_write_bytes(p, b"new")
    assert p.read_bytes() == b"good"
    assert [x.name for x in tmp_path.iterdir()] == ["out.glb"]


def test_target_is_a_folder(tmp_path):
    (tmp_path / "x.glb").mkdir()
    with pytest.raises(ExportError):
        atomic_write_bytes(tmp_path / "x.glb", b"data")


def test_successful_atomic_output(tmp_path):
    p = tmp_path / "a.usda"
    with atomic_output(p) as tmp:
        tmp.write_text("#usda 1.0\n")
    assert p.read_text() == "#usda 1.0\n"
    assert [x.name for x in tmp_path.iterdir()] == ["a.usda"]


def test_permission_denied_is_export_error(tmp_path, monkeypatch):
    real_open = os.open

    def denied(path, flags, *a, **k):       # creating a file is refused, as in a read-only folder
        if flags & os.O_CREAT:
            raise PermissionError(13, "Permission denied")
        return real_open(path, flags, *a, **k)

    (tmp_path / "out.glb").write_bytes(b"old")
    monkeypatch.setattr(os, "open", denied)
    with pytest.raises(ExportError) as e:
        atomic_write_bytes(tmp_path / "out.glb", b"new")
    assert "Permission denied" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(ExportError):
        check_writable(tmp_path)
    assert (tmp_path / "out.glb").read_bytes() == b"old"


# ----------------------------------------------------------------------------- OutputSet

def _set(tmp_path, names=("c.glb", "c.usd", "c.json")):
    return {n.split(".")[1]: tmp_path / n for n in names}


def test_output_set_commits_every_file_together(tmp_path, monkeypatch):
    def no_umask(*a):
        raise AssertionError("os.umask changes process-wide state")

    monkeypatch.setattr(os, "umask", no_umask)
    paths = _set(tmp_path)
    with OutputSet(paths) as out:
        for k in paths:
            out.write_bytes(k, k.encode())
        assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith(".")) == []
        assert out.commit() == dict(out.paths)
    assert list(out.paths)[-1] == "json"                   # the report is renamed last
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.glb", "c.json", "c.usd"]
    for k, p in paths.items():
        assert p.read_bytes() == k.encode()
        assert stat.S_IMODE(os.stat(p).st_mode) & 0o044


@pytest.mark.parametrize("fail_after", [0, 1, 2, 3])
@pytest.mark.parametrize("error", [RuntimeError, KeyboardInterrupt, OSError])
def test_output_set_failure_before_commit_changes_nothing(tmp_path, fail_after, error):
    paths = _set(tmp_path)
    for k, p in paths.items():
        p.write_bytes(b"old " + k.encode())
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    with pytest.raises((error, ExportError)):
        with OutputSet(paths) as out:
            for i, k in enumerate(paths):
                if i == fail_after:
                    raise error("boom")
                out.write_bytes(k, b"new")
            if fail_after == 3:
                raise error("boom")
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_output_set_target_turned_folder_renames_nothing(tmp_path):
    paths = _set(tmp_path)
    for p in paths.values():
        p.write_bytes(b"old")
    with pytest.raises(ExportError) as e:
        with OutputSet(paths) as out:
            for k in paths:
                out.write_bytes(k, b"new")
            paths["usd"].unlink()
            paths["usd"].mkdir()
            out.commit()
    assert "folder" in str(e.value)
    assert paths["glb"].read_bytes() == b"old" and paths["json"].read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.glb", "c.json", "c.usd"]


def test_commit_waits_for_a_reader(tmp_path):
    paths = _set(tmp_path, ("c.glb", "c.json"))
    for p in paths.values():
        p.write_bytes(b"old")
    out = OutputSet(paths)
    for k in paths:
        out.write_bytes(k, b"new")
    done = threading.Event()
    with read_lock(tmp_path):
        t = threading.Thread(target=lambda: (out.commit(), done.set()))
        t.start()
        time.sleep(0.2)
        assert not done.is_set()                      # the commit waits for the reader
        assert all(p.read_bytes() == b"old" for p in paths.values())
    t.join()
    assert done.is_set() and all(p.read_bytes() == b"new" for p in paths.values())


@pytest.mark.parametrize("text,expected", [
    ("out/c", "out/c"), ("out/", "out/centipede"), ("c", "c"), ("/", "/centipede"),
    ("a/b/", "a/b/centipede"), ("out/c.glb", "out/c"), ("c.USDA", "c"), ("a/c.json", "a/c"),
    ("a/c.usd", "a/c"), ("a/c.v2", "a/c.v2"), ("a/c.glb.bak", "a/c.glb.bak"), (".glbx", ".glbx"), ("a/.cfg", "a/.cfg")])
def test_resolve_out(text, expected):
    assert resolve_out(text) == Path(expected)


def test_resolve_out_existing_folder(tmp_path):
    assert resolve_out(tmp_path) == tmp_path / "centipede"
    assert resolve_out(str(tmp_path / "..")) == tmp_path / ".." / "centipede"


@pytest.mark.parametrize("text", ["", "  ", ".glb", "a/.USD", "out/.json"])
def test_resolve_out_empty(text):
    """An empty value, or a name that is only an output's extension (it would write the
    hidden `.glb.glb`), is an error."""
    with pytest.raises(ExportError):
        resolve_out(text)


def test_check_outputs_root_folder():
    """`--out /` means `/centipede.*`: fine for root, one-line error for anyone else."""
    paths = {"json": Path("/centipede.json")}
    if os.geteuid() == 0:
        check_outputs(paths)
        assert not Path("/centipede.json").exists()
    else:
        with pytest.raises(ExportError):
            check_outputs(paths)


@pytest.mark.parametrize("n,ok", [(200, True), (250, True), (251, False), (300, False)])
def test_check_outputs_name_length(tmp_path, n, ok):
    paths = {"json": tmp_path / ("x" * n + ".json")}
    if ok:
        check_outputs(paths)
        assert list(tmp_path.iterdir()) == []
    else:
        with pytest.raises(ExportError) as e:
            check_outputs(paths)
        assert "too long" in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("fail_at", [0, 1, 2])
def test_a_rename_failing_half_way_puts_the_old_files_back(tmp_path, monkeypatch, fail_at):
    """An I/O error on the k-th rename of a commit: the renamed ones are rolled back from their
    hard-linked backups, so the folder holds exactly the old files (a new file whose target did
    not exist before is removed)."""
    paths = _set(tmp_path)
    for k in ("glb", "json"):
        paths[k].write_bytes(b"old " + k.encode())          # no old usd: it is new
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    real_replace = os.replace
    calls = []

    def flaky(src, dst):
        if not Path(src).name.startswith(".c.bak"):
            calls.append(dst)
            if len(calls) == fail_at + 1:
                raise OSError(5, "Input/output error")
        return real_replace(src, dst)

    with pytest.raises(ExportError) as e:
        with OutputSet(paths) as out:
            for k in paths:
                out.write_bytes(k, b"new")
            monkeypatch.setattr(os, "replace", flaky)
            out.commit()
    assert "Input/output error" in str(e.value)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before
