"""baker.parallel.fork_map: the results in order whatever the number of workers, a task's
exception raised in the parent, a killed child reported as one user-facing error, and the
calls run in this process where it may not fork; thread_map: the results in order, one thread
inside a daemonic process (a `baker batch` worker), a call's exception raised in the caller."""

from __future__ import annotations

import multiprocessing
import os
import re
import signal
import threading

import numpy as np
import pytest

from baker import parallel
from baker.errors import BakerError
from baker.parallel import fork_map

forks = pytest.mark.skipif(not parallel.can_fork(), reason="fork_map forks on Linux only")


@forks
@pytest.mark.parametrize("workers", [1, 2, 3, 8])
def test_results_come_back_in_order_whatever_the_workers(workers):
    data = np.random.default_rng(5).normal(size=(7, 1000))     # inherited, not sent
    out = fork_map(lambda i: (i, os.getpid(), data[i].sum()), 7, workers)
    assert [o[0] for o in out] == list(range(7))
    assert [o[2] for o in out] == [data[i].sum() for i in range(7)]
    pids = {o[1] for o in out}
    assert (pids == {os.getpid()}) == (workers == 1)           # forked children did the work
    assert multiprocessing.active_children() == []


@forks
def test_a_tasks_exception_is_raised_in_the_parent():
    def task(i):
        if i == 3:
            raise ValueError("bad creature 3")
        return i

    with pytest.raises(ValueError, match="bad creature 3"):
        fork_map(task, 6, 2)
    assert multiprocessing.active_children() == []


@forks
def test_a_killed_child_is_one_error_naming_the_option():
    def task(i):
        if i == 1:
            os.kill(os.getpid(), signal.SIGKILL)
        return i

    with pytest.raises(BakerError) as e:
        fork_map(task, 4, 2)
    assert e.value.where == "--workers" and "worker process stopped" in str(e.value)
    assert multiprocessing.active_children() == []


@forks
def test_a_signal_during_a_map_stops_it_with_nothing_on_stderr():
    """A signal's exception in the parent while calls wait for a worker ends the map with that
    exception alone: the calls not started are not cancelled, or Python 3.11's pool, broken by
    the children's end, printed an InvalidStateError traceback from its thread (seen on stderr
    when `baker bake --creatures 8` was stopped during its solve)."""
    import subprocess
    import sys

    script = """
import os, signal, threading, time
from baker import parallel
class Stop(BaseException):
    pass
def handler(s, f):
    raise Stop()
signal.signal(signal.SIGTERM, handler)
threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGTERM)).start()
try:
    parallel.fork_map(lambda i: time.sleep(0.2) or i, 60, 2)
except Stop:
    print("stopped", len(__import__("multiprocessing").active_children()))
time.sleep(0.5)
"""
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0 and out.stdout.split() == ["stopped", "0"], out.stderr
    assert out.stderr == ""


def test_one_call_or_one_worker_runs_here():
    pid = os.getpid()
    assert fork_map(lambda i: os.getpid(), 1, 4) == [pid]
    assert fork_map(lambda i: os.getpid(), 3, 1) == [pid] * 3
    assert fork_map(lambda i: i, 0, 2) == []


def test_a_daemonic_process_does_not_fork(monkeypatch):
    monkeypatch.setattr(multiprocessing.current_process(), "daemon", True, raising=False)
    assert not parallel.can_fork()
    assert fork_map(lambda i: os.getpid(), 3, 2) == [os.getpid()] * 3


def test_available_cpus_is_positive():
    assert parallel.available_cpus() >= 1


def test_thread_map_keeps_the_order_and_a_daemonic_process_keeps_one_thread(monkeypatch):
    import threading

    out = parallel.thread_map(lambda i: (i, threading.get_ident()), range(40), threads=4)
    assert [o[0] for o in out] == list(range(40))
    assert parallel.thread_count() == parallel.available_cpus()
    monkeypatch.setattr(multiprocessing.current_process(), "daemon", True, raising=False)
    assert parallel.thread_count() == 1
    here = threading.get_ident()
    assert {o[1] for o in parallel.thread_map(lambda i: (i, threading.get_ident()),
                                              range(5))} == {here}


def test_a_map_nested_in_a_thread_maps_call_runs_on_its_thread(monkeypatch):
    import threading

    monkeypatch.setattr(parallel, "available_cpus", lambda: 2)

    def outer(i):
        me = threading.get_ident()
        inner = parallel.thread_map(lambda j: (i, j, threading.get_ident()), range(4))
        return parallel.thread_count(), me, inner

    out = parallel.thread_map(outer, range(4), threads=2)
    for i, (count, me, inner) in enumerate(out):
        assert count == 1
        assert inner == [(i, j, me) for j in range(4)]
    assert parallel.thread_count() == 2      # the calling thread keeps its CPUs


def test_an_exception_on_a_thread_is_raised_in_the_caller():
    def fail(i):
        if i == 3:
            raise ValueError("bad tile")
        return i

    with pytest.raises(ValueError, match="bad tile"):
        parallel.thread_map(fail, range(6), threads=2)


def test_in_background_gives_the_result_or_the_error(monkeypatch):
    from baker import parallel

    for threads in (1, 2):
        monkeypatch.setattr(parallel, "thread_count", lambda: threads)
        calls = []
        got = parallel.in_background(lambda a, b: calls.append(1) or a + b, 2, 3)
        assert got() == 5 and got() == 5 and calls == [1]

        def boom():
            raise ValueError("no")

        wait = parallel.in_background(boom)
        with pytest.raises(ValueError, match="no"):
            wait()


@forks
def test_a_fork_map_child_takes_its_share_of_the_cpus(monkeypatch):
    """Two workers on four CPUs cast on two threads each; on two CPUs, one each (the pool
    keeps the cores busy). The parent keeps all of them."""
    for cpus, share in ((4, 2), (2, 1), (1, 1)):
        monkeypatch.setattr(parallel, "available_cpus", lambda: cpus)
        assert fork_map(lambda i: parallel.thread_count(), 2, 2) == [share, share]
        assert parallel.thread_count() == cpus


def test_an_interrupted_process_does_not_wait_for_its_background_work():
    """A bake stopped by a signal while in_background's work runs exits at once: the thread is
    a daemon. (A ThreadPoolExecutor worker interrupted between its start and its registration
    was waited for at exit for ever: `baker navmesh` hung after SIGINT.)"""
    import subprocess
    import sys

    code = ("import time\n"
            "from baker import parallel\n"
            "parallel.thread_count = lambda: 2\n"
            "wait = parallel.in_background(time.sleep, 600)\n"
            "raise SystemExit(3)\n")
    # the work would take 600 s; the process must end long before (the timeout only stops a
    # hang, it measures nothing)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=120)
    assert done.returncode == 3


def test_a_signal_while_waiting_for_a_stack_thread_leaves_it_known_to_run():
    """on_own_stack (the USD read's thread): a signal's exception raised while the caller
    waits leaves the thread noted as running (signals.native_busy, which the `baker` command
    reads to end at once instead of finalizing beside it) until it ends; the thread is not a
    daemon, so elsewhere the interpreter waits for it at exit. (The wait was Thread.join,
    which Python 3.11 marks stopped when a signal interrupts it: the thread ran on through the
    interpreter's finalization and aborted the process.)"""
    import subprocess
    import sys

    code = ("import os, signal, sys, threading, time\n"
            "from baker import parallel, signals\n"
            "class Stop(BaseException):\n"
            "    pass\n"
            "def stop(s, f):\n"
            "    raise Stop()\n"
            "signal.signal(signal.SIGUSR2, stop)\n"
            "started, release = threading.Event(), threading.Event()\n"
            "def work():\n"
            "    started.set()\n"
            "    release.wait()\n"
            "def waiting():\n"      # the main thread in on_own_stack's wait for the thread
            "    f = sys._current_frames().get(threading.main_thread().ident)\n"
            "    names = []\n"
            "    while f is not None:\n"
            "        names, f = names + [f.f_code.co_name], f.f_back\n"
            "    return 'on_own_stack' in names and 'wait' in names and 'start' not in names\n"
            "def kick():\n"
            "    started.wait()\n"
            "    while not waiting():\n"
            "        time.sleep(0.001)\n"
            "    os.kill(os.getpid(), signal.SIGUSR2)\n"
            "threading.Thread(target=kick, daemon=True).start()\n"
            "try:\n"
            "    parallel.on_own_stack(1 << 20, work)\n"
            "except Stop:\n"
            "    pass\n"
            "print(signals.native_busy(), [(t.daemon, t.is_alive()) for t in threading.enumerate()\n"
            "                              if t.name == 'baker-background'])\n"
            "release.set()\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "True [(False, True)]", done.stdout


def test_in_background_runs_on_a_daemon_thread(monkeypatch):
    import threading

    from baker import parallel

    monkeypatch.setattr(parallel, "thread_count", lambda: 2)
    wait = parallel.in_background(lambda: (threading.current_thread().daemon,
                                           threading.current_thread() is threading.main_thread()))
    assert wait() == (True, False)


@forks
def test_a_peer_answers_in_turn_and_keeps_its_own_state():
    box = {"total": 0}

    def add(x):
        box["total"] += x                   # the child's copy
        return box["total"], os.getpid()

    peer = parallel.Peer(add)
    try:
        answers = []
        for x in (1, 2, 3):
            peer.send(x)
            answers.append(peer.receive())
    finally:
        peer.close()
    assert [a for a, _ in answers] == [1, 3, 6] and box["total"] == 0
    assert {p for _, p in answers} != {os.getpid()}
    assert multiprocessing.active_children() == []


@forks
def test_a_peers_error_is_raised_here_with_its_option():
    def fail(x):
        raise BakerError(f"no room for {x}", where="--max-memory")

    e = raised_by_peer(fail, BakerError)
    assert e.where == "--max-memory" and e.what == "no room for 1"


@forks
def test_a_killed_peer_is_one_error_naming_the_option():
    e = raised_by_peer(lambda x: os.kill(os.getpid(), signal.SIGKILL), BakerError)
    assert e.where == "--workers" and "worker process stopped" in str(e)


@forks
def test_a_peers_error_that_does_not_pickle_is_named():
    class Odd(Exception):
        def __reduce__(self):
            raise TypeError("not picklable")

    def fail(x):
        raise Odd("a local exception class")

    e = raised_by_peer(fail, RuntimeError)
    assert re.search("in a worker process: .*Odd: a local exception", str(e))


@forks
def test_closing_a_busy_peer_ends_it_quietly(capfd):
    peer = parallel.Peer(lambda x: __import__("time").sleep(x))
    peer.send(600)                  # still working: closing ends it
    peer.close()
    assert multiprocessing.active_children() == []
    assert "Traceback" not in capfd.readouterr().err


@forks
def test_a_peer_ends_when_its_parent_is_killed(tmp_path):
    import subprocess
    import sys
    import time

    script = tmp_path / "parent.py"
    script.write_text("import os, sys, time\n"
                      "from baker.parallel import Peer\n"
                      "peer = Peer(lambda x: x)\n"
                      "print(peer._proc.pid, flush=True)\n"
                      "time.sleep(600)\n")
    parent = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    child = int(parent.stdout.readline())
    parent.kill()
    parent.wait()
    for _ in range(200):            # the child sees its pipe close and exits
        if not running(child):
            break
        time.sleep(0.05)
    else:
        os.kill(child, signal.SIGKILL)
        pytest.fail("the peer outlived its killed parent")


@forks
@pytest.mark.parametrize("kind", ["fork_map", "two_peers"])
def test_children_end_when_their_parent_is_killed_outright(tmp_path, kind):
    """A bake killed with SIGKILL (a CI timeout, the OOM killer) cannot end its children: a
    fork_map child waiting on the call queue (whose write end its sister holds) waited for
    ever. They die with their parent now (Peers too, two of them forked one after the other)."""
    import subprocess
    import sys
    import time

    work = {"fork_map": "parallel.fork_map(lambda i: time.sleep(600), 4, 2)",
            "two_peers": "a, b = parallel.Peer(lambda x: x), parallel.Peer(lambda x: x)\n"
                         "time.sleep(600)"}[kind]
    script = tmp_path / "parent.py"
    script.write_text("import multiprocessing, os, threading, time\n"
                      "from baker import parallel\n"
                      "def tell():\n"
                      "    while len(multiprocessing.active_children()) < 2:\n"
                      "        time.sleep(0.05)\n"
                      "    print(*[p.pid for p in multiprocessing.active_children()], "
                      "flush=True)\n"
                      "threading.Thread(target=tell, daemon=True).start()\n" + work + "\n")
    parent = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    children = [int(x) for x in parent.stdout.readline().split()]
    assert len(children) == 2
    parent.kill()
    parent.wait()
    for _ in range(200):
        if not any(running(c) for c in children):
            break
        time.sleep(0.05)
    else:
        for c in children:
            if running(c):
                os.kill(c, signal.SIGKILL)
        pytest.fail("a child outlived its killed parent")


def running(pid: int) -> bool:
    """The process exists and is not a zombie (an orphan's may wait for a reaper)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


def raised_by_peer(fn, kind):
    """The exception of type `kind` a Peer running fn raises here at its answer to 1; the peer
    is gone after it."""
    peer = parallel.Peer(fn)
    try:
        peer.send(1)
        with pytest.raises(kind) as e:
            peer.receive()
    finally:
        peer.close()
    assert multiprocessing.active_children() == []
    return e.value


def test_off_main_thread_runs_on_one_kept_thread_and_raises_its_errors():
    """The compiled kernels' calls run on one thread other than the main one, kept between
    calls; an error there is raised in the caller."""
    names = {parallel.off_main_thread(lambda: threading.current_thread().name) for _ in range(50)}
    assert names == {"baker-compiled"}
    idents = {parallel.off_main_thread(threading.get_ident) for _ in range(5)}
    assert len(idents) == 1 and threading.get_ident() not in idents

    def fail():
        raise ValueError("in the kernel")

    with pytest.raises(ValueError, match="in the kernel"):
        parallel.off_main_thread(fail)
    assert parallel.off_main_thread(lambda x: x + 1, 41) == 42      # still serving


@forks
def test_off_main_thread_in_a_forked_child_starts_its_own_thread():
    """A fork_map child does not inherit the parent's thread (threads do not survive fork): its
    first call starts one of its own instead of waiting for ever (in a subprocess: a child
    waiting for ever fails the test at the timeout instead of hanging the suite)."""
    import subprocess
    import sys

    script = """
import os
from baker import parallel
parallel.off_main_thread(lambda: None)          # the parent's thread started
out = parallel.fork_map(lambda i: parallel.off_main_thread(lambda: (i, os.getpid())), 4, 2)
assert [i for i, _ in out] == [0, 1, 2, 3]
assert os.getpid() not in {pid for _, pid in out}
print("ok")
"""
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0 and run.stdout.split() == ["ok"], run.stderr[-2000:]


def test_compiled_call_runs_the_first_call_of_each_argument_kind_off_the_main_thread():
    """compiled_call: a kernel's first call for some argument kinds runs on off_main_thread's
    thread (which compiles it), the calls after it on the main thread; other kinds (a
    read-only array, another dtype, a non-contiguous view) are new and go to that thread
    first too."""
    seen = []

    def kernel(a, x):
        seen.append(threading.current_thread() is threading.main_thread())

    a = np.zeros((4, 3))
    parallel.compiled_call(kernel, a, 1.0)
    parallel.compiled_call(kernel, np.ones((4, 3)), 2.0)
    ro = np.zeros((4, 3))
    ro.flags.writeable = False
    parallel.compiled_call(kernel, ro, 1.0)
    parallel.compiled_call(kernel, ro, 1.0)
    parallel.compiled_call(kernel, a[:, ::2], 1.0)
    parallel.compiled_call(kernel, a.astype(np.float32), 1.0)
    parallel.compiled_call(kernel, a, 1)
    parallel.compiled_call(kernel, a, 3.0)
    assert seen == [False, True, False, True, False, False, False, True]
