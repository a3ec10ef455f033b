"""Atomic file output: write to a temporary file in the target folder, then rename over the target.

A failed or interrupted write never leaves a partial file at the target path, and a previous good
file survives until the new one is complete.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from baker.errors import ExportError


def _check_folder(path: Path) -> Path:
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ExportError(f"cannot write {path}: folder {folder} does not exist")
    if path.is_dir():
        raise ExportError(f"cannot write {path}: it is a folder")
    return folder


def _mkstemp(path: Path) -> Path:
    folder = _check_folder(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.tmp", suffix=path.suffix, dir=folder)
    except OSError as e:
        raise ExportError(f"cannot write {path}: {e.strerror or e}") from None
    os.close(fd)
    return Path(tmp)


def _replace(tmp: Path, path: Path) -> None:
    try:
        # mkstemp creates files 0600; give the output the usual permissions (umask applies)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except OSError as e:
        _unlink(tmp)
        raise ExportError(f"cannot write {path}: {e.strerror or e}") from None


def _unlink(p: Path) -> None:
    try:
        os.unlink(p)
    except OSError:
        pass


def check_writable(folder: Path) -> None:
    """Create `folder` if needed; ExportError (one line) unless a file can be created in it.

    Call it before a long bake so an unwritable output folder fails early.
    """
    folder = Path(folder) if str(folder) else Path(".")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ExportError(f"output folder {folder} cannot be created: {e.strerror or e}") from None
    if not folder.is_dir():
        raise ExportError(f"output folder {folder} is not a folder")
    try:
        fd, tmp = tempfile.mkstemp(prefix=".baker-write-test.", dir=folder)
    except OSError as e:
        raise ExportError(f"output folder {folder} is not writable: {e.strerror or e}") from None
    os.close(fd)
    _unlink(Path(tmp))


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write `data` to `path` atomically. ExportError (one line) when it cannot be written."""
    with atomic_output(Path(path)) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())


@contextmanager
def atomic_output(path: Path) -> Iterator[Path]:
    """Yield a temporary path with the same suffix (e.g. `.centipede.tmpab12.usd`) in the same
    folder; on success rename it over `path`, on any error delete it and re-raise.

    OSErrors raised while writing become ExportError.
    """
    path = Path(path)
    tmp = _mkstemp(path)
    try:
        yield tmp
    except OSError as e:
        _unlink(tmp)
        raise ExportError(f"cannot write {path}: {e.strerror or e}") from None
    except BaseException:
        _unlink(tmp)
        raise
    if not tmp.is_file():
        raise ExportError(f"cannot write {path}: nothing was written")
    _replace(tmp, path)
