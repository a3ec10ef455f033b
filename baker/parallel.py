"""A crowd's per-creature work on forked worker processes (`baker bake --workers N`), and
large GIL-free work (ray batches, the navigation build's tiles) on threads.

fork_map(fn, n, workers) returns [fn(0), ..., fn(n - 1)], in that order, with the calls shared
among up to `workers` processes forked from this one. A child inherits everything `fn` reads
(the environment, its Embree scene, the run records) by copy-on-write, so only the index goes
to it and only the result comes back (pickled). Each call does exactly what it does in this
process, so the results, and the files, are the same bits whatever the number of workers.

The calls run here, one after another, when there is one worker or one call, where fork is not
the platform's safe way to start a process (it is on Linux; macOS and Windows start fresh
interpreters, which would have to load the level again), and inside a daemonic process (a
`baker batch` worker, which may not have children: the batch already keeps the cores busy).

Peer(fn) is one forked child that answers requests in turn (send, then receive fn(request)),
keeping its own state between them: a crowd's run steps some of its followers on each of a
few while this process steps the rest (run.group).

thread_map(fn, items) is the same map on threads of this process, for calls that spend their
time in numpy or Embree with the GIL released.

Only the standard library (and baker.signals, which imports only it) is imported here.
"""

from __future__ import annotations

import functools
import multiprocessing
import os
import signal
import sys
import threading
import warnings

from baker.signals import HANDLED, native_thread

#: the function the forked children call (set just before the pool forks them)
_TASK = None
#: in a fork_map child: the processes of its pool (they share this machine's CPUs)
_SHARE = 1
#: `on` on a thread_map's threads: maps nested in its calls run on the calling thread (two
#: bands of columns on two CPUs, each casting its rays on two threads, made four threads
#: that slowed the navigation build)
_MAPPED = threading.local()


def available_cpus() -> int:
    """The CPUs this process may run on (its affinity mask where the OS has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - macOS, Windows
        return max(1, os.cpu_count() or 1)


def thread_count() -> int:
    """Threads for GIL-free work (thread_map): the CPUs this process may use, or 1 inside a
    daemonic process (a `baker batch` worker: the batch already keeps the cores busy) and on a
    thread_map's thread (the map already keeps them busy); in a fork_map child, its share of
    them (one each for two workers on two CPUs)."""
    if multiprocessing.current_process().daemon or getattr(_MAPPED, "on", False):
        return 1
    return max(1, available_cpus() // _SHARE)


def can_fork() -> bool:
    """True where fork_map may fork: Linux, and not inside a daemonic process."""
    return sys.platform.startswith("linux") and not multiprocessing.current_process().daemon


def _child_start(workers: int, parent: int) -> None:
    """A fork_map child (or a Peer's): its share of the CPUs (thread_count), its signals
    (_child_signals), and its end with its parent's (_die_with_parent)."""
    global _SHARE
    _SHARE = max(1, int(workers))
    _child_signals()
    _die_with_parent(parent)


#: prctl's option for the signal a process gets when its parent dies (linux/prctl.h)
_PR_SET_PDEATHSIG = 1


def _die_with_parent(parent: int) -> None:
    """Linux: this child is killed when `parent` (the process that forked it) dies. A parent
    killed outright (SIGKILL: a CI timeout, the OOM killer) cannot end its children, and a
    fork_map child never saw it go: it waits on the call queue, whose write end its sister
    children hold too, and waited for ever (with its copy of the level's memory). (A Peer
    also ends when its pipe closes.)"""
    if not sys.platform.startswith("linux"):   # pragma: no cover - fork is Linux only here
        return
    import ctypes

    try:
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):           # pragma: no cover - no prctl in this libc
        return
    if os.getppid() != parent:      # it died before the call above
        os._exit(1)


def _child_signals() -> None:
    """A child leaves Ctrl-C, a hang-up and the other stopping signals (sent to the terminal's
    whole process group) to its parent, which stops the pool, and dies at SIGTERM (the pool's
    terminate), instead of raising baker.signals.Interrupted in a task."""
    for s in HANDLED:
        signal.signal(s, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        signal.set_wakeup_fd(-1)
    except ValueError:  # pragma: no cover - not the main thread
        pass


def _call(i: int):
    return _TASK(i)


def fork_map(fn, n: int, workers: int) -> list:
    """[fn(i) for i in range(n)], on up to `workers` forked processes (see the module).

    A child that dies (killed, out of memory) stops the map with a BakerError; an exception in
    the parent (a signal's Interrupted) ends the children at once."""
    return _fork_map(fn, n, workers, None)[0]


def fork_map_beside(fn, n: int, workers: int, beside) -> tuple:
    """(fork_map(fn, n, workers), beside()): `beside` runs in this process while the calls
    are made, on its main thread once the children are forked (no thread of this process is
    busy while it forks: a child must not inherit a lock such a thread holds, numba's compiler
    lock among them), or, where the calls run here, on a thread of its own beside them
    (in_background: for work that releases the GIL)."""
    return _fork_map(fn, n, workers, beside)


def _fork_map(fn, n: int, workers: int, beside) -> tuple:
    global _TASK
    workers = min(int(workers), int(n))
    if workers <= 1 or not can_fork():
        wait = in_background(beside) if beside is not None else (lambda: None)
        return [fn(i) for i in range(n)], wait()
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    from baker.errors import BakerError

    before = {p.pid for p in multiprocessing.active_children()}
    _TASK = fn
    pool = None
    try:
        with warnings.catch_warnings():     # Python 3.12+: fork with the ray caster's threads
            warnings.filterwarnings("ignore", r".*fork\(\) may lead to deadlocks",
                                    DeprecationWarning)
            pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork"),
                                       initializer=_child_start,
                                       initargs=(workers, os.getpid()))
            # waited for one by one, never cancelled: an interrupted pool.map cancels the calls
            # not started, and Python 3.11's pool, broken by the children's end below, then
            # fails to mark them ("Exception in thread ... InvalidStateError" on stderr)
            futures = [pool.submit(_call, i) for i in range(n)]
            # (a "fork" pool starts all its children at the first submit)
            value = beside() if beside is not None else None
            out = [f.result() for f in futures]
        pool.shutdown()
        return out, value
    except BrokenProcessPool:
        raise BakerError(f"a worker process stopped (killed, or out of memory) with {workers} "
                         "workers; try fewer", where="--workers") from None
    finally:
        _TASK = None
        if pool is not None:
            _end(p for p in multiprocessing.active_children() if p.pid not in before)
            # the pool's own thread joins them too: wait for it, so none is left when we return
            pool.shutdown(wait=True)


def _end(children) -> None:
    """Stop forked children: SIGTERM, and SIGKILL for one still there after 5 s (a child
    forked with the parent's handler, before its own took over)."""
    children = list(children)
    for p in children:
        p.terminate()
    for p in children:
        p.join(5.0)
        if p.is_alive():
            p.kill()
            p.join()


class Peer:
    """A forked child process that answers requests in turn: `send(request)`, then
    `receive()` gives fn(request), computed in the child while this process goes on. The child
    inherits everything fn reads, as a fork_map child does, and keeps its own state between
    requests (fn may change what it reads). Linux only (can_fork); `close()` ends it. `share`:
    the processes sharing the CPUs (the child's ray threads are its share, thread_count).

    An exception in fn is raised again by receive() (as a RuntimeError naming it, when it
    cannot be sent back); a child that dies (killed, out of memory) makes receive() raise a
    BakerError. The child exits when this process closes the pipe or dies."""

    def __init__(self, fn, share: int = 2):
        ctx = multiprocessing.get_context("fork")
        self._conn, child = ctx.Pipe()
        with warnings.catch_warnings():     # Python 3.12+: fork with the ray caster's threads
            warnings.filterwarnings("ignore", r".*fork\(\) may lead to deadlocks",
                                    DeprecationWarning)
            self._proc = ctx.Process(target=_peer_serve,
                                     args=(child, fn, share, self._conn, os.getpid()),
                                     daemon=True, name="baker-peer")
            self._proc.start()
        child.close()
        self._poller = _poller(self._conn)

    def send(self, request) -> None:
        try:
            self._conn.send(request)
        except OSError:
            self._stopped()

    def receive(self):
        try:
            _spin(self._poller)
            kind, value = self._conn.recv()
        except (EOFError, OSError):
            self._stopped()
        if kind == "error":
            raise value
        return value

    def _stopped(self):
        from baker.errors import BakerError

        raise BakerError("a worker process stopped (killed, or out of memory); try "
                         "--workers 1", where="--workers") from None

    def close(self) -> None:
        """End the child (at once if it is still working)."""
        if self._proc is None:
            return
        proc, self._proc = self._proc, None
        try:
            self._conn.send(None)
        except OSError:
            pass
        self._conn.close()
        proc.join(0.5)
        if proc.is_alive():
            _end([proc])


#: [s] how long a Peer's ends poll for the other's message before they sleep in the read: a
#: process woken from a sleep on a pipe took about half a millisecond on a 2-core virtual
#: machine, more than a small crowd's step
SPIN = 0.02


def _poller(conn):
    """A select.poll object watching `conn` for a message (a cheaper check than
    Connection.poll, which builds a selector at each call)."""
    import select

    p = select.poll()
    p.register(conn.fileno(), select.POLLIN)
    return p


def _spin(poller) -> None:
    """Poll until a message is there (or the pipe closes) or SPIN seconds pass, yielding the
    CPU between polls: on a machine busier than its cores (other jobs, a CI runner), a spin
    that kept its CPU delayed the other end it waits for by a time slice a step (a crowd of 10
    for 20 s on 2 workers under a load of 4: 33 s, against 5 s yielding)."""
    if poller.poll(0):
        return
    import time

    end = time.perf_counter() + SPIN
    while time.perf_counter() < end:
        if poller.poll(0):
            return
        os.sched_yield()


def _peer_serve(conn, fn, share: int, parent_end, parent: int) -> None:
    """A Peer's child: answer requests until None or the pipe closes; after an error, stop.
    It closes its copy of the parent's end first, so that the pipe closes when the parent
    dies (killed, it cannot say so)."""
    parent_end.close()
    _child_start(share, parent)
    poller = _poller(conn)
    while True:
        try:
            _spin(poller)
            request = conn.recv()
        except (EOFError, OSError):
            return
        if request is None:
            return
        try:
            reply = ("ok", fn(request))
        except BaseException as exc:  # handed to the parent, which raises it
            reply = ("error", exc)
        try:
            _reply(conn, reply)
        except OSError:
            return                      # the parent has gone (or stopped listening)
        if reply[0] == "error":
            return


def _reply(conn, reply: tuple) -> None:
    """Send a Peer's reply; an error that does not pickle goes as a RuntimeError naming it."""
    try:
        conn.send(reply)
    except OSError:
        raise
    except Exception:
        import traceback

        conn.send(("error", RuntimeError("in a worker process: " + "".join(
            traceback.format_exception_only(reply[1])).strip())))


_ONE_ARENA = False


def one_malloc_arena() -> None:
    """Have glibc's malloc serve every thread from one arena (M_ARENA_MAX = 1), once, before
    baker starts threads. By default each thread gets its own arena, whose freed blocks the
    others do not reuse: two threads building the navigation surface raised its peak memory by
    a fifth (0.015 m cells on the rainforest floor: 720-735 MB against 599 MB), past the
    budget's estimate. A no-op where malloc is not glibc's."""
    global _ONE_ARENA
    if _ONE_ARENA:
        return
    _ONE_ARENA = True
    if not sys.platform.startswith("linux"):
        return
    import ctypes

    try:
        ctypes.CDLL(None).mallopt(-8, 1)     # M_ARENA_MAX (malloc.h)
    except (OSError, AttributeError):  # pragma: no cover - not glibc
        pass


def thread_map(fn, items, threads: int | None = None) -> list:
    """[fn(x) for x in items], in that order, on up to `threads` threads (default:
    thread_count()). For work that releases the GIL (numpy on large arrays, Embree's
    queries); no call may write what another reads or writes."""
    items = list(items)
    threads = min(len(items), thread_count() if threads is None else int(threads))
    if threads <= 1:
        return [fn(x) for x in items]
    from concurrent.futures import ThreadPoolExecutor

    one_malloc_arena()

    def mapped(x):
        _MAPPED.on = True      # a map on this thread runs on it alone (thread_count)
        return fn(x)

    with ThreadPoolExecutor(threads) as pool:
        return list(pool.map(mapped, items))


def in_background(fn, *args):
    """Start fn(*args) on a thread of its own. Returns a callable that waits for fn's result
    (or raises its error). For work that releases the GIL, overlapping other such work. When
    baker runs on one thread (thread_count() == 1), fn runs at the first wait instead.

    The thread is a daemon: a bake stopped by a signal (baker.signals raises in the main
    thread, possibly while the thread starts) exits without waiting for it. (A
    ThreadPoolExecutor's worker, interrupted between its start and its registration, was
    never told to stop, and the interpreter waited for it at exit for ever.)"""
    if thread_count() <= 1:
        return functools.cache(lambda: fn(*args))
    return _on_thread(fn, args)


#: threading.stack_size() is the process's: set around one thread's start at a time
_STACK_LOCK = threading.Lock()


def on_own_stack(stack_bytes: int, fn, *args):
    """fn(*args) on a thread of its own with a stack of `stack_bytes`, this thread waiting for
    it (its error raised here). For native code that recurses once per level of a file's
    nesting (USD's readers): how deep a file it reads then does not depend on the calling
    thread's stack (8 MB for Linux's main thread under the usual `ulimit -s`, less for other
    threads: 512 KB on macOS). Where such a thread cannot be started (no memory for its
    stack), fn runs on this thread.

    A signal's exception (baker.signals) is raised here while fn still runs: the thread is
    noted as native (signals.native_thread: the `baker` command then ends without Python's
    finalization, which the thread crashed in) and is not a daemon (elsewhere the interpreter
    waits for it at exit instead of tearing it down in the middle of native code)."""
    with _STACK_LOCK:
        try:
            old = threading.stack_size(stack_bytes)
        except (ValueError, RuntimeError):  # pragma: no cover - a platform without the setting
            return fn(*args)
        try:
            wait = _on_thread(fn, args, native=True)
        except RuntimeError:        # "can't start new thread"
            wait = None
        finally:
            threading.stack_size(old)
    return fn(*args) if wait is None else wait()


def off_main_thread(fn, *args):
    """fn(*args), run on a thread other than the main one (on this one when it is not the
    main one), the main thread waiting for it. For compiled code (numba) whose results are
    boxed in C: Python runs signal handlers in the main thread only, and a handler that raised
    there (baker.signals stops a bake so) while numba boxed a result left its dispatcher
    returning with an exception set, and the process crashed. Waiting for the thread, the main
    thread raises cleanly. The calls run on one daemon thread kept for them (`_Worker`):
    the keyframe reduction makes thousands of short calls, and starting a thread for each
    cost 0.1-0.6 ms."""
    if threading.current_thread() is not threading.main_thread():
        return fn(*args)
    global _WORKER
    if _WORKER is None:
        _WORKER = _Worker()
    return _WORKER.call(fn, args)


def compiled_call(kernel, *args) -> None:
    """kernel(*args) for a numba kernel that returns nothing and writes its results into
    arrays it is given, on the main thread once it is compiled for these argument types (the
    calls after off_main_thread's hop, 0.1-0.3 ms a call on a busy machine, more than many
    calls). The first call for a kernel and argument types runs on off_main_thread's thread,
    which compiles it (or loads it from numba's cache): a signal whose handler raises during a
    compile on the main thread lands in LLVM's callbacks, which print the exception they
    ignore. Returning nothing keeps the direct calls safe from such a handler: a result boxed
    on the main thread is what made numba's dispatcher return with an exception set
    (off_main_thread). The argument types are told apart by what numba's typing reads (an
    array's dtype, dimensions, layout, writeability and alignment, a scalar's type), each
    kernel's kept in a set of this process's."""
    key = (kernel, tuple(_arg_kind(a) for a in args))
    if key in _COMPILED:
        kernel(*args)
        return
    off_main_thread(kernel, *args)
    _COMPILED.add(key)


def _arg_kind(a) -> tuple:
    flags = getattr(a, "flags", None)
    if flags is None:
        return (type(a),)
    return (type(a), a.dtype.str, a.ndim, flags.c_contiguous, flags.f_contiguous,
            flags.writeable, flags.aligned)


#: (kernel, argument kinds) compiled in this process (compiled_call)
_COMPILED: set = set()


class _Worker:
    """A daemon thread that runs off_main_thread's calls, one at a time, in the order given.
    A call interrupted in the main thread (a signal's exception while it waits) still runs to
    its end there, and the next one after it; the thread is not waited for at exit, and a
    forked child starts its own (os.register_at_fork below)."""

    def __init__(self):
        import queue

        one_malloc_arena()
        self.tasks = queue.SimpleQueue()
        threading.Thread(target=self._serve, name="baker-compiled", daemon=True).start()

    def _serve(self) -> None:
        while True:
            fn, args, box, done = self.tasks.get()
            _into(box, fn, args)
            done.set()

    def call(self, fn, args):
        box: dict = {}
        done = threading.Event()
        self.tasks.put((fn, args, box, done))
        done.wait()
        return _out_of(box)


#: off_main_thread's thread, started at its first call (None in a forked child until then)
_WORKER: _Worker | None = None


def _forget_worker() -> None:
    global _WORKER
    _WORKER = None


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_worker)


def _on_thread(fn, args, native: bool = False):
    """Start fn(*args) on a daemon thread (`native`: a thread of native code that cannot be
    stopped, on_own_stack's); returns the callable that waits for its result. The wait is for
    an event the thread sets as it ends, not Thread.join: Python 3.11's join, interrupted by
    a signal's exception, marks the thread as stopped while it still runs (and the interpreter
    then does not wait for it at exit)."""
    one_malloc_arena()
    box: dict = {}
    finished = threading.Event()
    thread = threading.Thread(target=_into, args=(box, fn, args, finished),
                              name="baker-background", daemon=not native)
    if native:
        native_thread(finished)
    try:
        thread.start()
    except RuntimeError:    # "can't start new thread": nothing runs (a signal's exception
        finished.set()      # here comes once the thread has started)
        raise

    def wait():
        finished.wait()
        thread.join()
        return _out_of(box)

    return wait


def _into(box: dict, fn, args, finished=None) -> None:
    """box["value"] = fn(*args), or box["error"] its exception (for _out_of, on the thread
    that waits for it); then `finished` set."""
    try:
        box["value"] = fn(*args)
    except BaseException as exc:  # handed to the waiting thread by _out_of
        box["error"] = exc
    finally:
        if finished is not None:
            finished.set()


def _out_of(box: dict):
    """The value _into put in box, or its error raised."""
    if "error" in box:
        raise box["error"]
    return box["value"]
