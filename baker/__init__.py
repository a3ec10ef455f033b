"""baker: an offline procedural animation baker for a many-legged creature."""

import os

__version__ = "0.1.0"


def _writable(folder: str) -> bool:
    """Whether `folder` can be written, or made in its nearest existing ancestor."""
    while not os.path.isdir(folder):
        parent = os.path.dirname(folder)
        if parent == folder:
            return False
        folder = parent
    return os.access(folder, os.W_OK | os.X_OK)


def _numba_cache_folder() -> None:
    """numba keeps the compiled kernels (cache=True) beside the package's sources, else in the
    user's cache folder, and fails at import when it can write neither (an install owned by
    another user, run with HOME=/ in a container): then NUMBA_CACHE_DIR is a folder of this
    user's in the temporary folder. A NUMBA_CACHE_DIR already set is kept."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    user = os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"),
                        "numba")
    if _writable(os.path.join(os.path.dirname(os.path.abspath(__file__)), "__pycache__")) \
            or _writable(user):
        return
    # tempfile.gettempdir()'s first choices, without importing it (this runs before the
    # signal handlers are installed: the standard library's small modules only)
    tmp = next((os.environ[k] for k in ("TMPDIR", "TEMP", "TMP") if os.environ.get(k)),
               "/tmp" if os.name == "posix" else os.getcwd())
    uid = os.getuid() if hasattr(os, "getuid") else 0
    os.environ["NUMBA_CACHE_DIR"] = os.path.join(tmp, f"baker-numba-{uid}")


_numba_cache_folder()
