"""A lone creature's metrics run on a thread beside the keyframe reduction
(pipeline.measure_beside); a crowd's run at once (its creatures share the worker processes).
Either way the caller gets measure_creatures' own result, and its errors."""

import threading

import pytest

from baker import parallel, pipeline


@pytest.fixture
def recorded(monkeypatch):
    calls = []

    def fake(cfg, trajs, env, nav, workers=1):
        calls.append(threading.current_thread())
        if trajs == ["broken"]:
            raise ValueError("no metrics")
        return [f"motion of {t}" for t in trajs], None if len(trajs) == 1 else "crowd"

    monkeypatch.setattr(pipeline, "measure_creatures", fake)
    return calls


def test_a_lone_creature_is_measured_on_another_thread(recorded, monkeypatch):
    monkeypatch.setattr(parallel, "thread_count", lambda: 2)
    wait = pipeline.measure_beside(None, ["a"], None, None, 2)
    assert wait() == (["motion of a"], None)
    assert recorded and recorded[0] is not threading.main_thread()


def test_a_crowd_is_measured_at_once(recorded):
    wait = pipeline.measure_beside(None, ["a", "b"], None, None, 2)
    assert recorded == [threading.main_thread()]          # before the wait
    assert wait() == (["motion of a", "motion of b"], "crowd")


def test_on_one_thread_the_metrics_run_at_the_wait(recorded, monkeypatch):
    monkeypatch.setattr(parallel, "thread_count", lambda: 1)
    wait = pipeline.measure_beside(None, ["a"], None, None, 1)
    assert recorded == []
    assert wait() == (["motion of a"], None)
    assert recorded == [threading.main_thread()]


def test_an_error_in_the_metrics_is_raised_at_the_wait(recorded, monkeypatch):
    monkeypatch.setattr(parallel, "thread_count", lambda: 2)
    wait = pipeline.measure_beside(None, ["broken"], None, None, 2)
    with pytest.raises(ValueError, match="no metrics"):
        wait()
