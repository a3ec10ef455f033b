"""The first of two signals wins, even when it has to wait for an import to end
(baker/signals.py: a signal in the middle of an import is delivered again once it is done), and
whichever handler Python runs first: the order is read from the wakeup pipe, where signals that
arrived together count as one moment that SIGINT wins."""

from __future__ import annotations

import os
import signal

import pytest

from baker import signals


@pytest.fixture
def fresh_state(monkeypatch):
    monkeypatch.setattr(signals, "_state", {"phase": "commit", "defer": 0, "pending": 0,
                                            "raised": 0, "first": 0, "wakeup": -1, "pid": 0})
    again = []
    monkeypatch.setattr(signals, "_again", again.append)
    return again


def test_a_signal_held_back_by_an_import_is_not_overtaken_by_a_second_one(fresh_state,
                                                                          monkeypatch):
    """Ctrl-C arrives during an import and waits for it; a SIGTERM right after it, once the
    import is done, stops the bake as the Ctrl-C (exit 130), not as SIGTERM (143)."""
    monkeypatch.setattr(signals, "_importing", lambda: True)
    signals._handler(signal.SIGINT, None)
    assert fresh_state == [signal.SIGINT]                # delivered again later
    monkeypatch.setattr(signals, "_importing", lambda: False)
    with pytest.raises(signals.Interrupted) as stop:
        signals._handler(signal.SIGTERM, None)
    assert stop.value.signum == signal.SIGINT and stop.value.exit_code == 130
    signals._handler(signal.SIGINT, None)                # the redelivery: already stopping


def test_a_single_signal_after_an_import_is_its_own(fresh_state, monkeypatch):
    monkeypatch.setattr(signals, "_importing", lambda: False)
    with pytest.raises(signals.Interrupted) as stop:
        signals._handler(signal.SIGTERM, None)
    assert stop.value.exit_code == 143


@pytest.fixture
def wakeup_pipe(monkeypatch):
    """Make a wakeup pipe holding `arrived`, as the C-level handler writes it."""
    made = []

    def make(arrived: bytes) -> None:
        r, w = os.pipe()
        made.append(r)
        os.set_blocking(r, False)
        os.write(w, arrived)
        os.close(w)
        monkeypatch.setitem(signals._state, "wakeup", r)
        monkeypatch.setitem(signals._state, "pid", os.getpid())

    yield make
    for r in made:
        os.close(r)


def test_signals_that_arrived_together_stop_the_bake_as_the_ctrl_c(fresh_state, wakeup_pipe,
                                                                  monkeypatch):
    """SIGINT and SIGTERM sent at once: the pipe held [15, 2] (the kernel gave them to
    different threads), and Python ran SIGTERM's handler first; the bake stops as SIGINT."""
    wakeup_pipe(bytes([signal.SIGTERM, signal.SIGUSR1, signal.SIGINT]))
    monkeypatch.setattr(signals, "_importing", lambda: False)
    with pytest.raises(signals.Interrupted) as stop:
        signals._handler(signal.SIGTERM, None)
    assert stop.value.exit_code == 130
    signals._handler(signal.SIGINT, None)                # its own handler: already stopping


def test_a_sigterm_alone_in_the_pipe_is_its_own(fresh_state, wakeup_pipe, monkeypatch):
    wakeup_pipe(bytes([signal.SIGTERM]))
    monkeypatch.setattr(signals, "_importing", lambda: False)
    with pytest.raises(signals.Interrupted) as stop:
        signals._handler(signal.SIGTERM, None)
    assert stop.value.exit_code == 143


def test_a_ctrl_c_whose_byte_comes_just_after_the_sigterm_still_wins(fresh_state, monkeypatch):
    """SIGINT then SIGTERM sent back to back: the thread the kernel gave the SIGINT to wrote its
    byte after the SIGTERM's, and after the SIGTERM's handler first read the pipe (a fresh
    clone's CI run stopped the bake as SIGTERM). A byte that comes within TOGETHER_S counts as
    the same moment."""
    import threading

    r, w = os.pipe()
    os.set_blocking(r, False)
    monkeypatch.setitem(signals._state, "wakeup", r)
    monkeypatch.setitem(signals._state, "pid", os.getpid())
    monkeypatch.setattr(signals, "_importing", lambda: False)
    os.write(w, bytes([signal.SIGTERM]))
    late = threading.Timer(0.2 * signals.TOGETHER_S, os.write, (w, bytes([signal.SIGINT])))
    late.start()
    try:
        with pytest.raises(signals.Interrupted) as stop:
            signals._handler(signal.SIGTERM, None)
    finally:
        late.join()
        os.close(w)
        os.close(r)
    assert stop.value.exit_code == 130
