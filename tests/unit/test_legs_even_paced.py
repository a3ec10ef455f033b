"""legs._even_paced (every span re-paced in one batch) against _even_piece (one span at a
time, the loop it replaced): the same bits, ties and flat stretches included."""

import numpy as np

from baker.locomotion.legs import _even_paced, _even_piece


def _case(seed: int, F: int = 40, L: int = 6, flat: bool = False):
    rng = np.random.default_rng(seed)
    rel = rng.normal(size=(F, L, 3))
    step = np.abs(rng.normal(size=(F - 1, L))) * 0.1
    if flat:                                # zero steps: repeated cum values, searchsorted ties
        step[rng.random(step.shape) < 0.4] = 0.0
    spans = []
    for _ in range(12):
        a = int(rng.integers(0, F - 3))
        b = int(rng.integers(a + 2, F))
        spans.append((a, b, int(rng.integers(0, L))))
    return rel, step, spans


def test_even_paced_same_bits_as_one_at_a_time():
    for seed in range(20):
        for flat in (False, True):
            rel, step, spans = _case(seed, flat=flat)
            got = _even_paced(rel, step, spans)
            for (a, b, ll), (total, new) in zip(spans, got):
                want_total, want_new = _even_piece(rel[a:b + 1, ll], step[a:b, ll])
                assert np.array_equal(np.float64(total), np.float64(want_total))
                assert new.shape == want_new.shape
                assert np.array_equal(new.view(np.uint64), want_new.view(np.uint64))


def test_even_paced_all_zero_steps_and_non_finite_fallback():
    rel, step, spans = _case(3)
    step[:] = 0.0
    for (a, b, ll), (total, new) in zip(spans, _even_paced(rel, step, spans)):
        want_total, want_new = _even_piece(rel[a:b + 1, ll], step[a:b, ll])
        assert total == want_total == 0.0
        assert np.array_equal(new, want_new)
    step[5, :] = np.nan
    for (a, b, ll), (total, new) in zip(spans, _even_paced(rel, step, spans)):
        want_total, want_new = _even_piece(rel[a:b + 1, ll], step[a:b, ll])
        assert np.array_equal(new, want_new, equal_nan=True)
    assert _even_paced(rel, step, []) == []
