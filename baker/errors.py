"""Error hierarchy and the one format a user error is shown in.

A BakerError is a user-facing problem: the CLI prints `format_error(e)`, one line
`Error: <what> (<where>)`, on stderr and exits with EXIT_USAGE (2). Anything else is a bug and
keeps its traceback. `where` names the place: a file (and key), an option, "command line".
"""

from __future__ import annotations

EXIT_USAGE = 2
_MAX_LINE = 400


class BakerError(Exception):
    """Base class for every error caused by the user's input or environment.

    message : what is wrong (one sentence, no trailing period needed)
    where   : the file, key or option it is about, or None
    """

    def __init__(self, message: str = "", where: str | None = None):
        super().__init__(message)
        self.where = None if where is None else str(where)

    def __reduce__(self):
        # pickled (a worker process's error) with its `where`
        return type(self), (self.what, self.where)

    @property
    def what(self) -> str:
        return str(self.args[0]) if self.args else ""

    def __str__(self) -> str:
        return f"{self.what} ({self.where})" if self.where else self.what


class ConfigError(BakerError):
    """Bad option values, bad rig TOML."""


class EnvironmentLoadError(BakerError):
    """The environment file is missing, unsupported, corrupt or unusable."""


class NavError(BakerError):
    """The navigation surface cannot be built or used (for example: nothing walkable)."""


class BudgetError(NavError):
    """A build would need more memory than allowed (--max-memory)."""


class RigError(BakerError):
    """The rig definition is inconsistent."""


class ExportError(BakerError):
    """An output file cannot be written."""


class JobsFileError(ConfigError):
    """A batch jobs file with one or more errors (baker/batch.py). Every error is listed, in
    the one line, which is therefore not cut at the usual length."""

    max_line = 20_000


def exception_text(exc: BaseException) -> str:
    """str(exc), or a sentence saying the message could not be read: pxr's Tf.ErrorException
    decodes USD's messages as UTF-8 in str(), and a layer holding Latin-1 text (a prim named
    "fl\\xe9or") made that raise UnicodeDecodeError, a traceback in place of the error line."""
    try:
        return str(exc)
    except UnicodeError:
        return "the reader's message is not UTF-8 text (does the file hold text in another " \
               "encoding than UTF-8?)"


def utf8_text(s: str) -> str:
    """s with what UTF-8 cannot encode written as its escape: a file name's undecodable byte
    (Linux allows any; Python holds it as a lone surrogate) becomes \\udcff, as a JSON report
    writes it."""
    return s.encode("utf-8", "backslashreplace").decode("utf-8")


def one_line(text: str, limit: int = _MAX_LINE) -> str:
    """Whitespace (newlines included) collapsed to single spaces, cut at `limit` characters."""
    s = " ".join(str(text).split())
    return s if len(s) <= limit else s[: limit - 3] + "..."


def short_path(name: str, limit: int = 60) -> str:
    """A path for a message: as it is up to `limit` characters, else its first and last
    characters round an ellipsis (a path too long for the file system can be kilobytes)."""
    half = (limit - 4) // 2
    return name if len(name) <= limit else f"{name[:half]}...{name[-half:]}"


def format_error(exc: BaseException, where: str | None = None) -> str:
    """The single stderr line for a user error: `Error: <what> (<where>)`, in UTF-8 text
    (utf8_text: a stream that encodes strictly raised UnicodeEncodeError on a path's
    undecodable byte)."""
    what = exc.what if isinstance(exc, BakerError) else exception_text(exc)
    what = one_line(what, getattr(exc, "max_line", _MAX_LINE)) or type(exc).__name__
    where = where if where is not None else getattr(exc, "where", None)
    w = one_line(where) if where else ""
    line = f"Error: {what} ({w})" if w and f"({w})" not in what else f"Error: {what}"
    return utf8_text(line)
