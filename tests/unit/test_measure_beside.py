"""parallel.fork_map_beside: the map's results in order and the `beside` callable's value; beside
runs in this process's main thread once the children are forked (a lone creature's metrics
beside the pieces of its keyframe reduction, pipeline.reduce_creatures), or on a thread of its
own beside the calls where they run here; an error in either is raised, the children ended."""

import multiprocessing
import os
import threading

import pytest

from baker import parallel
from baker.parallel import can_fork, fork_map_beside

forks = pytest.mark.skipif(not can_fork(), reason="fork_map forks on Linux only")


@forks
def test_beside_runs_here_once_the_children_are_forked():
    seen = {}

    def beside():
        seen["thread"] = threading.current_thread()
        seen["children"] = len(multiprocessing.active_children())
        return "metrics"

    out, value = fork_map_beside(lambda i: (i, os.getpid()), 4, 2, beside)
    assert [o[0] for o in out] == [0, 1, 2, 3] and value == "metrics"
    assert {o[1] for o in out} != {os.getpid()}
    assert seen == {"thread": threading.main_thread(), "children": 2}
    assert multiprocessing.active_children() == []


def test_with_one_worker_beside_runs_on_another_thread(monkeypatch):
    monkeypatch.setattr(parallel, "thread_count", lambda: 2)
    seen = []
    out, value = fork_map_beside(lambda i: i * i, 3, 1,
                                 lambda: seen.append(threading.current_thread()) or 7)
    assert out == [0, 1, 4] and value == 7
    assert seen and seen[0] is not threading.main_thread()


@forks
@pytest.mark.parametrize("workers", [1, 2])
def test_an_error_beside_is_raised_and_the_children_end(workers, monkeypatch):
    monkeypatch.setattr(parallel, "thread_count", lambda: 2)

    def beside():
        raise ValueError("no metrics")

    with pytest.raises(ValueError, match="no metrics"):
        fork_map_beside(lambda i: i, 3, workers, beside)
    assert multiprocessing.active_children() == []


def test_no_beside_is_none():
    assert fork_map_beside(lambda i: -i, 2, 1, None) == ([0, -1], None)
