"""What native libraries write straight to the process's stderr, held back while they read a
file.

USD's C++ code reports most problems as diagnostics (trapped with Tf.DiagnosticTrap by the
callers), but some it prints itself on file descriptor 2: a corrupt crate file gave
`failed call to posix_madvise(...)` above the one `Error:` line of a refused level. While
`held_stderr()` is open, descriptor 2 points at a temporary file; what was written there goes
to the log at debug level when it closes.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import tempfile

log = logging.getLogger(__name__)

#: the most bytes of held output kept for the log
_KEPT = 4096


@contextlib.contextmanager
def held_stderr(what: str):
    """Descriptor 2 pointed at a temporary file for the block (`what`: the file read, for the
    log); restored however the block ends. Python's own sys.stderr is flushed first and is
    held too (nothing in a file reader writes to it). Where there is no descriptor 2 or no
    temporary file to be had, the block runs as it is."""
    with contextlib.ExitStack() as stack:
        try:
            with contextlib.suppress(ValueError, AttributeError):  # a closed or absent stderr
                sys.stderr.flush()
            tmp = stack.enter_context(tempfile.TemporaryFile())
            saved = os.dup(2)
        except OSError:
            saved = None
        if saved is None:
            yield
            return
        stack.callback(os.close, saved)
        os.dup2(tmp.fileno(), 2)
        try:
            yield
        finally:
            with contextlib.suppress(ValueError, AttributeError):
                sys.stderr.flush()
            os.dup2(saved, 2)
            tmp.seek(0)
            text = tmp.read(_KEPT).decode("utf-8", "replace").strip()
            if text:
                log.debug("native output while reading %s: %s", what, " ".join(text.split()))
