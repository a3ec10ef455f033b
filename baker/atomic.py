"""Atomic file output: temporary files in the target folder, renamed over the targets at the end.

- `atomic_output` / `atomic_write_bytes`: one file. A failed or interrupted write never leaves a
  partial file at the target path, and a previous good file survives until the new one is
  complete.
- `OutputSet`: all the files of one bake, all or nothing. Each file is written to its own
  temporary (`.NAME.tmpXXXXXXXX.EXT` beside the target); `commit()` renames them all over the
  targets, holding an exclusive `flock` on the output folder and with SIGINT/SIGTERM held back
  (baker/signals.py), so two bakes into the same `--out` commit one after the other and the
  files on disk always come from one run. Anything that goes wrong before the commit (an
  exception, a signal) deletes the temporaries and leaves the previous outputs byte-identical.
  A reader that must never see a commit half done takes the shared lock: `read_lock(folder)`.
- `resolve_out` / `check_outputs`: turn `--out` into output paths (`--out dir/` or an existing
  folder writes `dir/centipede.*`) and check, before any work, that they can be written.

Temporary files are created with `os.open(..., O_CREAT | O_EXCL, 0o666)`, so the kernel applies
the process's umask and outputs get the usual permissions; no process-wide state is changed.
"""

from __future__ import annotations

import errno
import fcntl
import os
import secrets
import stat
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

from baker import signals
from baker.errors import ExportError, utf8_text

#: File name used when `--out` names a folder.
DEFAULT_NAME = "centipede"
#: Longest stem kept in a temporary file's name (the rest is dropped), so a long but valid
#: output name still leaves room for `.` + stem + `.tmpXXXXXXXX` + suffix.
_TMP_STEM = 64


def _why(e: OSError) -> str:
    return e.strerror or str(e)


def is_folder(p: Path) -> bool:
    """Path.is_dir() that says False instead of raising (a name too long, a loop)."""
    try:
        return Path(p).is_dir()
    except (OSError, ValueError):
        return False


def _folder(path: Path) -> Path:
    return path.parent if str(path.parent) else Path(".")


def _check_folder(path: Path) -> Path:
    folder = _folder(path)
    if not is_folder(folder):
        raise ExportError(f"cannot write {path}: folder {folder} does not exist")
    if is_folder(path):
        raise ExportError(f"cannot write {path}: it is a folder")
    return folder


def tmp_name(path: Path) -> str:
    """A fresh hidden temporary name for `path` in its folder: `.STEM.tmpXXXXXXXX.SUFFIX`."""
    return f".{path.stem[:_TMP_STEM]}.tmp{secrets.token_hex(4)}{path.suffix}"


def _mkstemp(path: Path) -> Path:
    """Create an empty temporary file beside `path` (mode 0666 minus the umask, by the kernel)."""
    folder = _check_folder(path)
    for _ in range(100):
        tmp = folder / tmp_name(path)
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0),
                         0o666)
        except FileExistsError:
            continue
        except OSError as e:
            raise ExportError(f"cannot write {path}: {_why(e)}") from None
        os.close(fd)
        return tmp
    raise ExportError(f"cannot write {path}: no free temporary name")


def _unlink(p: Path) -> None:
    try:
        os.unlink(p)
    except OSError:
        pass


def _fsync(p: Path) -> None:
    fd = os.open(p, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _replace(tmp: Path, path: Path) -> None:
    try:
        os.replace(tmp, path)
    except OSError as e:
        _unlink(tmp)
        raise ExportError(f"cannot write {path}: {_why(e)}") from None


def check_writable(folder: Path) -> None:
    """Create `folder` if needed; ExportError (one line) unless a file can be created in it.

    Call it before a long bake so an unwritable output folder fails early.
    """
    folder = Path(folder) if str(folder) else Path(".")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ExportError(f"output folder {folder} cannot be created: {_why(e)}") from None
    if not folder.is_dir():
        raise ExportError(f"output folder {folder} is not a folder")
    probe = folder / f".baker-write-test.{secrets.token_hex(4)}"
    try:
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except OSError as e:
        raise ExportError(f"output folder {folder} is not writable: {_why(e)}") from None
    os.close(fd)
    _unlink(probe)


#: extensions `--out` may end with (dropped: `--out scene.glb` writes scene.glb, scene.usd, ...)
OUT_EXTENSIONS = (".glb", ".usd", ".usda", ".usdc", ".json")


def resolve_out(out) -> Path:
    """`--out` as the output path without extension. A value ending in a path separator, or
    naming an existing folder, means `<folder>/centipede`; one ending in an output's extension
    (OUT_EXTENSIONS, any case) is the path without it. ExportError for an empty value, or a
    name that is only such an extension (`.glb`: a hidden file `.glb.glb` is no one's wish)."""
    text = os.fspath(out) if out is not None else ""
    if not str(text).strip():
        raise ExportError("--out is empty: give an output path without extension, "
                          "e.g. outputs/centipede")
    text = str(text)
    if text.endswith(os.sep) or (os.altsep and text.endswith(os.altsep)) or is_folder(Path(text)):
        return Path(text) / DEFAULT_NAME
    path = Path(text)
    if is_special(path):
        raise ExportError(f"--out {text!r} is a device, pipe or socket, not a path: give a "
                          "folder or a path without extension, e.g. outputs/centipede")
    if path.name.lower() in OUT_EXTENSIONS:
        raise ExportError(f"--out {text!r} names only an extension: give a name, e.g. "
                          f"{path.parent / DEFAULT_NAME}{path.name}")
    if path.suffix.lower() in OUT_EXTENSIONS and path.stem:
        return path.with_suffix("")
    return path


#: the outputs USD writes: it takes their paths as UTF-8 text (a name holding a byte that is
#: not, which Linux allows, was a UnicodeEncodeError traceback once the bake was done)
USD_EXTENSIONS = (".usd", ".usda", ".usdc")


def is_special(path: Path) -> bool:
    """Whether `path` is there and is neither a folder nor a regular file (`--out /dev/null`
    wrote /dev/null.glb, /dev/null.usd and /dev/null.json beside the device)."""
    try:
        mode = path.stat().st_mode
    except (OSError, ValueError):
        return False
    return not (stat.S_ISDIR(mode) or stat.S_ISREG(mode))


def _name_max(folder: Path) -> int:
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    try:
        return int(os.pathconf(folder, "PC_NAME_MAX"))
    except (OSError, ValueError):
        return 255


def check_outputs(paths: Mapping[str, Path] | Path) -> None:
    """Check, before any work, that every output path can be written: the folder exists or can
    be created and takes new files, each name fits the file system (and leaves room for the
    temporary's), and no target is a folder. ExportError (one line) otherwise.

    paths : {format: path} (as BakeConfig.output_paths() gives), or one path.
    """
    if isinstance(paths, (str, os.PathLike)):
        paths = {"out": Path(paths)}
    paths = {k: Path(v) for k, v in paths.items()}
    for p in paths.values():
        if not p.name or p.name in (".", ".."):
            raise ExportError(f"output path {str(p)!r} has no file name")
        if p.suffix.lower() in USD_EXTENSIONS and utf8_text(str(p)) != str(p):
            raise ExportError(f"cannot write {p}: USD writes only paths that are UTF-8 text "
                              "(a byte of this one is not)")
    for folder in sorted({_folder(p) for p in paths.values()}):
        limit = _name_max(folder)
        for p in paths.values():
            if _folder(p) != folder:
                continue
            n = len(os.fsencode(p.name))
            if n > limit:
                raise ExportError(f"output name is too long: {n} bytes, at most {limit} "
                                  f"({p.name[:40]}...)")
            if len(os.fsencode(tmp_name(p))) > limit:
                raise ExportError(f"output name is too long for its temporary file ({p.name[:40]}...)")
        check_writable(folder)
        for p in paths.values():
            if _folder(p) == folder and is_folder(p):
                raise ExportError(f"cannot write {p}: it is a folder")
            if _folder(p) == folder and is_special(p):    # (a FIFO there was renamed over)
                raise ExportError(f"cannot write {p}: it is a device, pipe or socket, not a "
                                  "file")


def check_not_inputs(paths: Mapping[str, Path], inputs: Mapping[str, Path]) -> None:
    """ExportError when an output would replace an input file (`--out level` beside
    level.glb wrote the bake over the level it read); inputs: {what: path}."""
    for what, src in inputs.items():
        for p in paths.values():
            try:
                same = os.path.samefile(p, src)
            except (OSError, ValueError):   # (either not there: nothing is replaced)
                continue
            if same:
                raise ExportError(f"the output {p} is the {what} file the bake reads: give "
                                  "--out another name or folder")


@contextmanager
def _folder_lock(folders, shared: bool = False) -> Iterator[None]:
    """flock every folder (sorted, so two processes never wait on each other in a cycle)."""
    fds = []
    try:
        for folder in sorted({Path(f).resolve() for f in folders}):
            try:
                fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
            except OSError as e:
                raise ExportError(f"cannot lock output folder {folder}: {_why(e)}") from None
            fds.append(fd)
            try:
                fcntl.flock(fd, fcntl.LOCK_SH if shared else fcntl.LOCK_EX)
            except OSError as e:
                if e.errno not in (errno.ENOLCK, errno.EOPNOTSUPP, errno.EINVAL):
                    raise ExportError(f"cannot lock output folder {folder}: {_why(e)}") from None
        yield
    finally:
        for fd in fds:
            os.close(fd)          # closing the descriptor releases its flock


@contextmanager
def read_lock(folder) -> Iterator[None]:
    """Shared lock on an output folder: while held, no bake commits into it, so the files read
    inside the block all come from one run."""
    with _folder_lock([folder], shared=True):
        yield


class OutputSet:
    """The files of one bake, committed together (see the module docstring).

    Use as a context manager; leaving the block without `commit()` (an error, a signal) deletes
    every temporary:

        with OutputSet({"glb": a, "json": b}) as out:
            out.write_bytes("glb", data)
            write_something(out.temp("json"))
            written = out.commit()
    """

    def __init__(self, paths: Mapping[str, Path]):
        # the JSON report last: a reader that does not lock sees it change after the rest
        items = sorted(((k, Path(v)) for k, v in paths.items()), key=lambda kv: kv[0] == "json")
        self.paths: dict[str, Path] = dict(items)
        self._tmp: dict[str, Path] = {}
        self.committed = False

    def __enter__(self) -> "OutputSet":
        return self

    def __exit__(self, exc_type, exc, tb):
        if not self.committed:
            self.discard()
        if isinstance(exc, OSError) and not isinstance(exc, ExportError):
            raise ExportError(f"cannot write the outputs: {_why(exc)}") from None
        return False

    def temp(self, key: str) -> Path:
        """The temporary file (created empty) that becomes paths[key] at the commit."""
        if key not in self.paths:
            raise KeyError(key)
        if key not in self._tmp:
            signals.checkpoint(f"write:{key}")
            self._tmp[key] = _mkstemp(self.paths[key])
        return self._tmp[key]

    def write_bytes(self, key: str, data: bytes) -> None:
        tmp = self.temp(key)
        try:
            with open(tmp, "wb") as f:
                f.write(data)
        except OSError as e:
            raise ExportError(f"cannot write {self.paths[key]}: {_why(e)}") from None

    def discard(self) -> None:
        """Delete every temporary; the targets are untouched."""
        for tmp in self._tmp.values():
            _unlink(tmp)
        self._tmp.clear()

    def commit(self) -> dict[str, Path]:
        """Rename every temporary over its target, under the folder lock, signals held back.
        Returns {key: path}. Every key must have been written."""
        missing = [k for k in self.paths if k not in self._tmp]
        if missing:
            raise ExportError(f"nothing was written for {', '.join(missing)}")
        signals.checkpoint("commit")
        try:
            for tmp in self._tmp.values():
                _fsync(tmp)
        except OSError as e:
            raise ExportError(f"cannot write the outputs: {_why(e)}") from None
        folders = {_folder(p) for p in self.paths.values()}
        with _folder_lock(folders):
            with signals.deferred():
                # Checked again under the lock: a target that became a folder (or a vanished
                # folder) fails the whole set before anything is renamed.
                for key, path in self.paths.items():
                    if is_folder(path):
                        raise ExportError(f"cannot write {path}: it is a folder")
                    if not self._tmp[key].is_file():
                        raise ExportError(f"cannot write {path}: its temporary file vanished")
                self._rename_all()
                self.committed = True
                for folder in folders:
                    _fsync_dir(folder)
        return dict(self.paths)

    def _rename_all(self) -> None:
        """Rename the temporaries over the targets. The previous targets are kept as hard-linked
        backups until every rename is done, so a rename that fails half way (an I/O error) puts
        the old files back and removes the new ones: still all or nothing."""
        backups: dict[str, Path | None] = {}
        done: list[str] = []
        try:
            for key, path in self.paths.items():
                backups[key] = _backup(path)
            for key, path in self.paths.items():
                os.replace(self._tmp[key], path)
                done.append(key)
                del self._tmp[key]
        except OSError as e:
            for key in reversed(done):
                path, old = self.paths[key], backups.get(key)
                try:
                    if old is not None:
                        os.replace(old, path)
                        backups[key] = None
                    else:
                        os.unlink(path)
                except OSError:
                    pass
            raise ExportError(f"cannot write the outputs: {_why(e)}") from None
        finally:
            for old in backups.values():
                if old is not None:
                    _unlink(old)


def _backup(path: Path) -> Path | None:
    """A hidden hard link to `path` beside it (None when there is no file to keep, or the file
    system has no hard links: then a failed rename cannot be undone)."""
    if not path.is_file():
        return None
    for _ in range(100):
        link = path.parent / f".{path.stem[:_TMP_STEM]}.bak{secrets.token_hex(4)}{path.suffix}"
        try:
            os.link(path, link)
            return link
        except FileExistsError:
            continue
        except OSError:
            return None
    return None


def _fsync_dir(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write `data` to `path` atomically. ExportError (one line) when it cannot be written."""
    with atomic_output(Path(path)) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())


@contextmanager
def atomic_output(path: Path) -> Iterator[Path]:
    """Yield a temporary path with the same suffix (e.g. `.centipede.tmpab12cd34.usd`) in the
    same folder; on success rename it over `path`, on any error delete it and re-raise.

    OSErrors raised while writing become ExportError.
    """
    path = Path(path)
    tmp = _mkstemp(path)
    try:
        yield tmp
    except OSError as e:
        _unlink(tmp)
        raise ExportError(f"cannot write {path}: {_why(e)}") from None
    except BaseException:
        _unlink(tmp)
        raise
    if not tmp.is_file():
        raise ExportError(f"cannot write {path}: nothing was written")
    with signals.deferred():
        _replace(tmp, path)
