"""The README's data-flow diagram (How it works) names real code: every dotted name in it
resolves to a module, function, class or attribute of the package, and every Class.attribute
to a class of the package that has it."""

from __future__ import annotations

import importlib
import pkgutil
import re
from pathlib import Path

import pytest

import baker

README = Path(__file__).resolve().parents[2] / "README.md"
#: a dotted name: module path or Class.attribute (file names and placeholders are not code)
NAME = re.compile(r"(?<![\w/<.-])([A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)+)(?![\w/>-])")
NOT_CODE = {"toml", "glb", "usd", "json", "py", "obj", "usda"}


def diagram() -> str:
    text = README.read_text(encoding="utf-8")
    section = text.split("## How it works", 1)[1]
    return section.split("```", 2)[1]


def names() -> list[str]:
    found = {m.group(1) for m in NAME.finditer(diagram())}
    return sorted(n for n in found if n.rsplit(".", 1)[1] not in NOT_CODE)


def _classes() -> dict[str, list[type]]:
    out: dict[str, list[type]] = {}
    for mod in pkgutil.walk_packages(baker.__path__, "baker."):
        if mod.name.endswith("__main__"):          # runs the CLI
            continue
        try:
            m = importlib.import_module(mod.name)
        except ImportError:  # pragma: no cover - an optional extra (preview) missing
            continue
        for k, v in vars(m).items():
            if isinstance(v, type) and v.__module__ == m.__name__:
                out.setdefault(k, []).append(v)
    return out


def _resolves(name: str, classes: dict) -> bool:
    parts = name.split(".")
    for cut in range(len(parts), 0, -1):          # the longest module prefix, then attributes
        try:
            obj = importlib.import_module("baker." + ".".join(parts[:cut]))
        except ImportError:
            continue
        for attr in parts[cut:]:
            if not hasattr(obj, attr):
                break
            obj = getattr(obj, attr)
        else:
            return True
    head, rest = parts[0], parts[1:]             # Class.attribute
    return any(all(hasattr(c, a) for a in rest[:1]) for c in classes.get(head, []))


def test_the_diagram_names_real_code():
    found = names()
    assert len(found) > 40          # the diagram is there and read
    classes = _classes()
    missing = [n for n in found if not _resolves(n, classes)]
    assert not missing, missing


@pytest.mark.parametrize("stale", ["body.step", "legs.step"])
def test_stale_names_are_not_in_the_diagram(stale):
    """The names the issue found stale (no such functions) stay out."""
    assert stale not in names()
