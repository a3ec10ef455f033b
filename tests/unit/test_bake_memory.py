"""A bake's memory estimate (baker/memory.py): a bake over the limit is refused before it starts,
with a crowd and a length that really fit the same limit and are the largest that do; the CLI
says so in one line, exit 2, and leaves the previous outputs as they were."""

import re

import pytest

from baker import memory
from baker.errors import BudgetError

GB = 1e9


def test_estimate_is_linear_in_creatures_and_frames():
    lone = memory.estimate(1, 1801)
    assert lone == pytest.approx(memory.BASE_BYTES + 1801 * memory.SOLVE_BYTES_PER_FRAME)
    assert memory.estimate(1, 3601) - lone == pytest.approx(1800 * memory.SOLVE_BYTES_PER_FRAME)
    # a crowd keeps every creature, and solves one per worker at a time
    one, two = memory.estimate(100, 1801, 2), memory.estimate(200, 1801, 2)
    assert two - one == pytest.approx(100 * (memory.CREATURE_BYTES
                                             + 1801 * memory.CREATURE_BYTES_PER_FRAME))
    assert memory.estimate(100, 1801, 4) > one > memory.estimate(100, 1801, 1)
    assert memory.estimate(3, 1801, 8) == memory.estimate(3, 1801, 3)


def test_the_issues_crowd_and_the_default_bake_fit_a_24_gb_machine():
    """The default bake and 100 creatures for a minute (measured: about 6 GB) pass the default
    limit of a 24 GB machine; 1000 creatures for a minute (about 60 GB) do not."""
    cap = memory.USABLE_SHARE * 24 * GB
    assert memory.estimate(1, 1801, 2) < 1 * GB
    assert 5 * GB < memory.estimate(100, 1801, 2) < 8 * GB
    assert memory.estimate(1000, 1801, 2) > 2.5 * cap
    memory.check(100, 60.0, 30, 2, cap / 1e6)


@pytest.mark.parametrize("limit_gb", [0.9, 2.0, 6.0, 20.0])
@pytest.mark.parametrize("creatures,seconds,fps,workers", [
    (1000, 60.0, 30, 2), (300, 60.0, 30, 2), (50, 600.0, 30, 8), (1, 3600.0, 30, 2),
    (1, 900.0, 60, 1), (2, 3600.0, 24, 2), (1000, 5.0, 30, 1)])
def test_refusal_names_the_largest_crowd_and_the_longest_bake_that_fit(
        limit_gb, creatures, seconds, fps, workers):
    cap_mb = limit_gb * 1e3
    frames = int(round(seconds * fps)) + 1
    if memory.estimate(creatures, frames, workers) <= cap_mb * 1e6:
        memory.check(creatures, seconds, fps, workers, cap_mb)        # fits: no error
        return
    with pytest.raises(BudgetError) as ei:
        memory.check(creatures, seconds, fps, workers, cap_mb)
    msg = str(ei.value)
    assert ei.value.where == ("--creatures" if creatures > 1 else "--seconds")
    assert f"{limit_gb:.3g} GB limit" in msg and "raise --max-memory" in msg
    most = re.search(r"at most (\d+) creatures", msg)
    if most:
        n = int(most.group(1))
        assert 2 <= n < creatures
        memory.check(n, seconds, fps, workers, cap_mb)
        with pytest.raises(BudgetError):
            memory.check(n + 1, seconds, fps, workers, cap_mb)
    longest = re.search(r"at most ([0-9.]+) s", msg)
    if longest:
        s = float(longest.group(1))
        assert 0 < s < seconds
        memory.check(creatures, s, fps, workers, cap_mb)
        with pytest.raises(BudgetError):
            memory.check(creatures, round(s + 0.1, 1), fps, workers, cap_mb)
    if not most and creatures > 1:        # not even two creatures fit this long a bake
        with pytest.raises(BudgetError):
            memory.check(2, seconds, fps, workers, cap_mb)
    if not longest:                       # not even a tenth of a second fits this crowd
        with pytest.raises(BudgetError):
            memory.check(creatures, 0.1, fps, workers, cap_mb)


def test_cli_refuses_a_crowd_over_the_limit_and_keeps_the_outputs(tmp_path, capsys):
    from baker.cli import main

    out = tmp_path / "bake"
    kept = tmp_path / "bake.glb"
    kept.write_bytes(b"a previous bake")
    code = main(["bake", "--creatures", "1000", "--max-memory", "5000", "--out", str(out)])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert "1000 creatures for 60 s" in err and "(--creatures)" in err
    assert kept.read_bytes() == b"a previous bake"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bake.glb"]
