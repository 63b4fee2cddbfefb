"""Cache keys hash modules by dotted name and code only: a move leaves every key, an edit does not."""

import sys
import textwrap

import pytest

from sensors._infra import cache as cache_mod

CODE = """
def stiffness(e, a):
    return e * a * {factor}
"""


def _write_package(root, package, module, doc, imports, factor=2.0):
    folder = root.joinpath(*package.split("."))
    for i in range(1, len(package.split(".")) + 1):
        root.joinpath(*package.split(".")[:i]).mkdir(exist_ok=True)
        (root.joinpath(*package.split(".")[:i]) / "__init__.py").touch()
    (folder / f"{module}.py").write_text(f'"""{doc}"""\n{imports}\n' + textwrap.dedent(CODE.format(factor=factor)))


@pytest.fixture
def on_path(tmp_path):
    sys.path.insert(0, str(tmp_path))
    yield tmp_path
    sys.path.remove(str(tmp_path))
    for name in [n for n in sys.modules if n.startswith(("kflat", "knested"))]:
        del sys.modules[name]


def test_a_moved_module_keeps_its_key_and_an_edited_one_does_not(on_path):
    # The same module before and after a move into a subpackage: its relative imports and its
    # docstring change with the move, its code does not.
    _write_package(on_path, "kflat", "fem", "Assembly.", "from .materials import x\nimport math")
    _write_package(on_path, "knested.fem", "assembly", "FEM assembly, moved.", "from ..materials.solids import x")
    _write_package(on_path, "knested.edit", "assembly", "Assembly.", "from .materials import x", factor=3.0)
    before = cache_mod.source_version("kflat.fem")
    assert cache_mod.source_version("knested.fem.assembly") == before
    assert cache_mod.source_version("knested.edit.assembly") != before


def test_the_shipped_keys_name_existing_modules():
    # Every module the keys name is found (a move that forgot to rename one fails here, loudly,
    # instead of keying on nothing).
    for name in cache_mod.SOURCE_MODULES:
        assert cache_mod.source_version(name)
    with pytest.raises(ValueError, match="no Python source"):
        cache_mod.source_version("sensors.no_such_module")



_TWO_THREADS = """
import threading
from sensors._infra import cache
calls, started = [], threading.Barrier(2)

def slow_version(*modules):
    calls.append(modules)
    threading.Event().wait(0.05)  # let the other thread arrive while this one computes
    return "v"

cache.source_version = slow_version

def ask(out):
    started.wait()
    out.append(cache.code_version())

results = []
threads = [threading.Thread(target=ask, args=(results,)) for _ in range(2)]
for t in threads:
    t.start()
for t in threads:
    t.join()
print(results, len(calls))
"""


def test_the_code_version_is_computed_once_when_two_threads_ask_at_once():
    """A cold object build asks for it in CoACD's thread and the modes' at the same moment (in a
    fresh process: this one may have computed it already)."""
    import os
    import subprocess
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run([sys.executable, "-c", _TWO_THREADS], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.split() == ["['v',", "'v']", "1"]


def test_a_key_without_code_ignores_the_code_version(monkeypatch):
    """``content_key(code=False)`` (CoACD's pieces, whose code is in their own key part) stays
    when the FE modules' code version changes; a default key does not."""
    parts = ("coacd", [1.0, 2.0], {"threshold": 0.03})
    before = cache_mod.content_key(*parts), cache_mod.content_key(*parts, code=False)
    monkeypatch.setattr(cache_mod, "code_version", lambda: "another version")
    after = cache_mod.content_key(*parts), cache_mod.content_key(*parts, code=False)
    assert before[0] != after[0] and before[1] == after[1]
