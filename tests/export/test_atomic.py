"""Atomic writes: complete file or nothing; the previous file survives a failure."""

import os
import stat
import sys

import pytest

from baker.errors import ExportError
from baker.atomic import atomic_output, atomic_write_bytes, check_writable


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
