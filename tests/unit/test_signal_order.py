"""The first of two signals wins, even when it has to wait for an import to end
(baker/signals.py: a signal in the middle of an import is delivered again once it is done)."""

from __future__ import annotations

import signal

import pytest

from baker import signals


@pytest.fixture
def fresh_state(monkeypatch):
    monkeypatch.setattr(signals, "_state", {"phase": "commit", "defer": 0, "pending": 0,
                                            "raised": 0, "queued": 0})
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
