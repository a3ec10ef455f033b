"""The navigation budget (navmesh/budget.py): a build over the memory limit is refused before any
ray is cast, and the cell size the message names really fits the same limit."""

import re

import numpy as np
import pytest

from baker.errors import BudgetError
from baker.navmesh import budget


@pytest.mark.parametrize("limit_mb", [600, 2000, 8000, 12640, 30000])
@pytest.mark.parametrize("side_m,cell", [(22.5, 0.0036), (200.0, 0.015), (5.0, 0.0005)])
def test_suggested_cell_size_fits(limit_mb, side_m, cell):
    n = int(np.ceil(side_m / cell))
    if budget.estimate(n * n, 55_000).bytes <= limit_mb * 1e6:
        pytest.skip("fits this limit")
    with budget.memory_limit(limit_mb):
        with pytest.raises(BudgetError) as ei:
            budget.check(n, n, cell, 55_000)
        fit = float(re.search(r"--cell-size ([0-9.e-]+)", str(ei.value)).group(1))
        assert fit > cell
        m = int(np.ceil(side_m / fit))
        est = budget.check(m, m, fit, 55_000)  # does not raise
        assert est.bytes <= limit_mb * 1e6


def test_default_limit_is_half_the_ram(monkeypatch):
    import os
    import resource

    ram = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    monkeypatch.setattr(budget, "CGROUP_FILES", ())
    monkeypatch.setattr(resource, "getrlimit", lambda r: (resource.RLIM_INFINITY,) * 2)
    assert budget.limit() == pytest.approx(ram / 2)
    with budget.memory_limit(100):
        assert budget.limit() == 100e6
    assert budget.limit() == pytest.approx(ram / 2)


def test_estimate_covers_measured_peaks():
    """Peak RSS of whole builds of the default scene (55k triangles), measured with
    benchmarks/bench_nav_budget.py: the estimate is above each, by at most 30 %."""
    measured = {562_500: 415e6, 2_250_000: 779e6, 5_062_500: 1376e6, 9_000_000: 2441e6}
    for cols, peak in measured.items():
        est = budget.estimate(cols, 55_000).bytes
        assert peak <= est <= 1.3 * peak + 150e6, (cols, peak, est)


@pytest.mark.parametrize("cell", [0.03, 0.015])
def test_estimate_covers_a_real_build(cell):
    """A whole build of the default scene in its own process: its peak RSS is under the
    estimate, and the estimate is not far above it (benchmarks/bench_nav_budget.py's child)."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    bench = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_nav_budget.py"
    ns: dict = {}
    exec(compile(bench.read_text(), str(bench), "exec"), ns)
    out = subprocess.run([sys.executable, "-c", ns["CHILD"], str(cell)], capture_output=True,
                         text=True, check=True)
    r = json.loads(out.stdout.strip().splitlines()[-1])
    assert r["peak_mb"] <= r["est_mb"] <= 1.5 * r["peak_mb"] + 150, r


def test_default_limit_is_half_of_a_smaller_address_space_or_cgroup_limit(monkeypatch, tmp_path):
    """Under `ulimit -v` (or a container's memory limit) a build the RAM would allow ran out of
    memory half way; it is now refused at once, with a cell size that fits."""
    import resource

    monkeypatch.setattr(budget, "CGROUP_FILES", ())
    monkeypatch.setattr(resource, "getrlimit", lambda r: (6e9, 6e9))
    assert budget.default_limit() == pytest.approx(3e9)
    with pytest.raises(BudgetError, match="--cell-size"):
        budget.check(8000, 8000, 0.005, 55_000)
    v2, v1 = tmp_path / "memory.max", tmp_path / "limit_in_bytes"
    v2.write_text("max\n")
    v1.write_text("2000000000\n")
    monkeypatch.setattr(budget, "CGROUP_FILES", (str(v2), str(v1)))
    assert budget.default_limit() == pytest.approx(1e9)
    v1.write_text(str(2**63 - 4096))                   # cgroup v1's "unlimited"
    assert budget.default_limit() == pytest.approx(3e9)
