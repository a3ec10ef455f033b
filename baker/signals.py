"""SIGINT, SIGTERM, SIGHUP and the other signals that end a process by default: a clean stop with
exit code 128 + the signal number (130, 143, 129; SIGQUIT 131, SIGALRM 142, SIGUSR2 140,
SIGXCPU 152).

`install()` (called by the console entry point, baker/entry.py, before any heavy import) makes
both signals raise `Interrupted` in the main thread. `Interrupted` is a BaseException but not a
KeyboardInterrupt, so neither click nor an `except Exception` swallows it; it unwinds the bake,
whose `finally` blocks and the output set (baker/atomic.py) delete every temporary file, and the
entry point prints one line and exits with 128 + the signal number. Only the first signal
raises; later ones (a second Ctrl-C while the bake cleans up) are ignored, so cleanup finishes.
A signal that arrives while a module is being imported is not raised there (a half-imported
module, and libraries that catch BaseException around optional imports, would turn it into a
traceback): the handler sends it again RETRY_S later, until no import is in progress.

A stop while a thread runs native code that nothing can stop (`native_thread`: USD's reader,
parallel.on_own_stack) does not wait for it: once the bake has unwound (its temporaries
deleted) and the line is printed, the entry point ends the process at once (`exit_now`).
Python's finalization would otherwise run beside that thread, and the thread, reaching for the
interpreter as it went, aborted the process ("terminate called without an active exception",
signal 6) after the line was printed.

`deferred()` holds signals back around a critical section (the renames of a commit): a signal
that arrives inside it is raised when it ends, so the outputs are either all old or all new.

This module only imports the standard library: it must be cheap to import before numpy.

Test hook (harmless when unset; read at every checkpoint):
    BAKER_TEST_PAUSE_AT=<phase>   at checkpoint <phase> print "baker-test: at <phase>" on
                                  stdout and sleep (up to 60 s, or until SIGUSR1) so a test can
                                  send a signal, or change the files, while the bake is in that
                                  phase.
    BAKER_TEST_MARKS=1            print "baker-test: at <phase>" at every checkpoint, no sleep.
    With either set, a signal that stops the process prints "baker-test: at interrupted".
`mark(name)` prints the same line from any thread, without a phase or a pause: "read:usd" and
"read:usd:done" around the USD read on its thread.
Phases: "start" (handlers installed, nothing heavy imported), every pipeline stage as it starts
("load", "navmesh", "rig", "simulate", "pose", "metrics", "export"), "write:<format>" before each
file is written to its temporary, and "commit" (every temporary written, nothing renamed yet);
"batch" once `baker batch` has checked its jobs file and starts its workers.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from contextlib import contextmanager

#: SIGHUP too: a terminal that closes (or an ssh session that drops) hangs up its jobs; SIGQUIT
#: (Ctrl-\\), SIGALRM (`timeout -s ALRM`), SIGUSR2 and SIGXCPU (a CPU-time limit, `ulimit -t`,
#: sends it before SIGKILL) would otherwise end the process where it stands, temporaries left.
#: SIGUSR1 is left alone: the test hook below resumes a paused bake with it.
HANDLED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT, signal.SIGALRM,
           signal.SIGUSR2, signal.SIGXCPU)


class Interrupted(BaseException):
    """Raised in the main thread by a HANDLED signal once `install()` has run."""

    def __init__(self, signum: int, phase: str = ""):
        self.signum = int(signum)
        self.phase = phase
        super().__init__(f"interrupted by {self.name}")

    @property
    def name(self) -> str:
        return signal.Signals(self.signum).name

    @property
    def exit_code(self) -> int:
        """128 + the signal number: 130 for SIGINT, 143 for SIGTERM (the shell convention)."""
        return 128 + self.signum


#: raised: the signal number once Interrupted was raised (0 before)
_state = {"phase": "start", "defer": 0, "pending": 0, "raised": 0, "first": 0, "wakeup": -1,
          "pid": 0}


#: How long to wait before looking again when a signal arrives in the middle of an import.
RETRY_S = 0.05
#: [s] signals this close together count as one moment (SIGINT, the user's Ctrl-C, wins it)
TOGETHER_S = 0.05


def _importing() -> bool:
    """True while a module is being imported (CPython keeps a lock per module being imported;
    False where that detail is missing)."""
    boot = sys.modules.get("_frozen_importlib")
    return bool(getattr(boot, "_module_locks", None))


def _again(signum: int) -> None:
    """Deliver `signum` to this process again in RETRY_S (from a timer thread)."""
    import threading

    t = threading.Timer(RETRY_S, os.kill, (os.getpid(), signum))
    t.daemon = True
    t.start()


def _first(signum: int) -> int:
    """The first SIGINT or SIGTERM this process received. Python runs its handlers after the
    fact, in an order of its own: a signal that arrives while another's handler runs has its
    handler run inside that one, first (Ctrl-C then a SIGTERM at once stopped a bake as
    SIGTERM). The C-level handler writes each signal's number to the wakeup pipe as it arrives;
    the first handler to run reads what is there. Signals that arrived together (there at that
    read, or within TOGETHER_S of it when no SIGINT is, in whatever order the kernel gave them
    to the process's threads) count as one moment, and SIGINT, the user's Ctrl-C, wins it.
    `signum` when there is no pipe."""
    if not _state["first"] and _state["wakeup"] >= 0 and _state["pid"] == os.getpid():
        arrived = _read_wakeup()
        # a Ctrl-C sent just before may still be on its way: the kernel hands each signal to
        # one of the process's threads, and the one carrying it can write its byte after
        # another thread has written the later signal's
        end = time.monotonic() + TOGETHER_S
        while signal.SIGINT not in arrived and time.monotonic() < end:
            arrived += _read_wakeup(end - time.monotonic())
        # (a handler run inside this one, while it waited, may have decided already)
        _state["first"] = _state["first"] or min((b for b in arrived if b in HANDLED), default=0)
    _state["first"] = _state["first"] or int(signum)
    return _state["first"]


def _read_wakeup(wait: float = 0.0) -> bytes:
    """What the wakeup pipe holds, after waiting up to `wait` seconds for something to come."""
    fd = _state["wakeup"]
    if wait > 0.0:
        import select

        try:
            select.select([fd], [], [], wait)
        except (OSError, ValueError):
            return b""
    try:
        return os.read(fd, 4096)
    except OSError:                     # nothing there (non-blocking), or closed
        return b""


def _handler(signum, frame):
    if _state["raised"]:
        return                      # already stopping: let the cleanup finish
    # the first signal wins: over one that arrives while its handler runs, or while it waits
    # for an import to end
    signum = _first(signum)
    if _state["defer"]:
        _state["pending"] = _state["pending"] or signum
        return
    if _importing():
        # Raising inside an import leaves half-imported modules, and some libraries catch
        # BaseException around their optional imports: come back once the import is done.
        _again(signum)
        return
    _state["raised"] = signum
    if os.environ.get("BAKER_TEST_PAUSE_AT") or os.environ.get("BAKER_TEST_MARKS"):
        # the test hook: a test may wait for this before its next signal (os.write: the
        # handler may run in the middle of a print)
        os.write(1, b"baker-test: at interrupted\n")
    raise Interrupted(signum, _state["phase"])


def finished() -> None:
    """The command has returned (its files committed or refused): from here on SIGINT and
    SIGTERM are ignored. Python puts its handlers back to the defaults as the interpreter
    ends, and a Ctrl-C then (just after a bake's success line) killed the process with no
    message and exit code 130 though its files were whole. Main thread only."""
    import threading

    if threading.current_thread() is threading.main_thread():
        for s in HANDLED:
            signal.signal(s, signal.SIG_IGN)


#: the "finished" events (threading.Event) of threads running native code (native_thread)
_NATIVE: list = []


def native_thread(finished) -> None:
    """Note a thread that runs native code which cannot be interrupted (a USD read), by the
    threading.Event it sets as it ends: a signal that stops the process before then ends the
    process without Python's finalization (native_busy, exit_now). (Not Thread.is_alive:
    Python 3.11's Thread.join, interrupted by a signal's exception, marks a thread that is
    still running as stopped.)"""
    _NATIVE[:] = [e for e in _NATIVE if not e.is_set()] + [finished]


def native_busy() -> bool:
    """Whether a thread noted by native_thread is still running."""
    return any(not e.is_set() for e in _NATIVE)


def exit_now(code: int) -> None:
    """End the process with `code` at once: standard streams and logging flushed, no atexit
    hooks and no interpreter finalization (a native_thread still running would crash in it).
    For the entry point, after an interrupted command has unwound and its line is printed."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, OSError, ValueError):
            pass
    logging = sys.modules.get("logging")
    if logging is not None:
        try:
            logging.shutdown()
        except Exception:  # pragma: no cover - a handler that fails to flush
            pass
    os._exit(code)


def stopping() -> int:
    """The signal number once one has interrupted the process, else 0."""
    return _state["raised"]


def install() -> None:
    """Make the HANDLED signals raise Interrupted (main thread only; a no-op elsewhere)."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        return
    if _state["pid"] != os.getpid():
        r, w = os.pipe()
        os.set_blocking(r, False)
        os.set_blocking(w, False)
        signal.set_wakeup_fd(w, warn_on_full_buffer=False)
        _state.update(wakeup=r, pid=os.getpid(), first=0)
    for s in HANDLED:
        signal.signal(s, _handler)


def phase() -> str:
    """The phase the last checkpoint named."""
    return _state["phase"]


@contextmanager
def deferred():
    """Hold SIGINT/SIGTERM back inside the block; one that arrived is raised at its end."""
    _state["defer"] += 1
    try:
        yield
    finally:
        _state["defer"] -= 1
    if not _state["defer"] and _state["pending"] and not _state["raised"]:
        signum, _state["pending"] = _state["pending"], 0
        _state["raised"] = signum
        raise Interrupted(signum, _state["phase"])


def mark(name: str) -> None:
    """The test hook's line for `name` ("baker-test: at <name>", when BAKER_TEST_MARKS or
    BAKER_TEST_PAUSE_AT is set), with no phase change and no pause: for work on a thread of
    its own (the USD read's, "read:usd" as it starts and "read:usd:done" as it ends)."""
    if os.environ.get("BAKER_TEST_PAUSE_AT") or os.environ.get("BAKER_TEST_MARKS"):
        os.write(1, f"baker-test: at {name}\n".encode())


def checkpoint(name: str) -> None:
    """Record the current phase (named in the interruption message) and run the test hook.

    An Interrupted that some library swallowed (a few optional imports catch BaseException,
    trimesh's among them) is raised again here, so the bake still stops before its commit."""
    if _state["raised"] and not _state["defer"]:
        raise Interrupted(_state["raised"], _state["phase"])
    _state["phase"] = name
    pause = os.environ.get("BAKER_TEST_PAUSE_AT")
    if pause != name and not os.environ.get("BAKER_TEST_MARKS"):
        return
    resume, old = [], None
    if pause == name:
        try:    # installed before the marker is printed: a test may resume us at once
            old = signal.signal(signal.SIGUSR1, lambda *a: resume.append(1))
        except ValueError:              # not the main thread: sleep the whole time
            pass
    try:
        sys.stdout.write(f"baker-test: at {name}\n")
        sys.stdout.flush()
        if pause == name:
            end = time.monotonic() + 60.0
            while time.monotonic() < end and not resume:
                time.sleep(0.02)
    finally:
        if old is not None:
            signal.signal(signal.SIGUSR1, old)
