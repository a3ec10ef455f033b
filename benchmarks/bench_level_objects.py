"""Levels made of many objects: a 2 s bake on a glTF level of N placements of a small mesh
(the corpus floor and box, 14 triangles), N = 300, 3,000 and 30,000, run as the CLI. Prints
each bake's wall time, its growth per object and the load / write split (the JSON report's
stage timings). Run from the repo root:  python benchmarks/bench_level_objects.py
"""

from __future__ import annotations

import copy
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "tools"))
from bad_inputs import good_gltf, pack_glb  # noqa: E402


def level(n: int) -> bytes:
    doc, blob = good_gltf()
    doc = copy.deepcopy(doc)
    sun = doc["nodes"][1]
    doc["nodes"] = [{"mesh": 0, "translation": [5.0 * (i % 200), 0.0, 5.0 * (i // 200)]}
                    for i in range(n)] + [sun]
    doc["scenes"][0]["nodes"] = list(range(n + 1))
    return pack_glb(doc, blob)


def main():
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for n in (300, 3_000, 30_000):
            path = tmp / f"objects_{n}.glb"
            path.write_bytes(level(n))
            t = time.perf_counter()
            subprocess.run([sys.executable, "-m", "baker", "bake", str(path), "--seconds", "2",
                            "--no-cache", "--out", str(tmp / f"out_{n}" / "c")], check=True,
                           capture_output=True)
            wall = time.perf_counter() - t
            stages = json.loads((tmp / f"out_{n}" / "c.json").read_text())["timings_s"]
            rows.append((n, wall, stages))
    print("objects   wall s   ms per object   load s   export s")
    for n, wall, st in rows:
        print(f"{n:7,d}  {wall:7.2f}  {1e3 * wall / n:14.3f}  {st.get('load', 0):7.2f}  "
              f"{st.get('export', 0):8.2f}")
    (n0, w0, _), (n1, w1, _) = rows[1], rows[2]
    print(f"growth 3,000 -> 30,000 objects: {(w1 - w0) / (n1 - n0) * 1e3:.3f} ms per object "
          f"({w1 / w0:.1f}x the time for 10x the objects)")


if __name__ == "__main__":
    main()
