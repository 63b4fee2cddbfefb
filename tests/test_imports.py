"""Imports stay cheap: what `import sensors`, `import aas_gym`, `import real` and `aas --help`
load (modules, not seconds: times are measured in benchmarks, never asserted)."""

from __future__ import annotations

import subprocess
import sys

import pytest

HEAVY = ("sklearn", "scipy.signal", "scipy.optimize", "matplotlib", "pyaudio", "torch", "ray")
# What each import leaves to first use (benchmarks/imports.py measures the time it saves).
DEFERRED = {
    "sensors": ("numba", "llvmlite", "scipy.linalg", "scipy.sparse", "threadpoolctl", "tqdm", "mujoco", "gymnasium"),
    "aas_gym": ("numba", "scipy", "mujoco", "sensors"),
    "real": ("numba", "scipy", "mujoco", "sensors"),
}


def _loaded(code: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys; print(' '.join(sys.modules))"],
                         capture_output=True, text=True, check=True)
    return set(out.stdout.split())


@pytest.mark.parametrize("module", ["sensors", "aas_gym", "real"])
def test_import_loads_no_heavy_module(module):
    loaded = _loaded(f"import {module}")
    assert not [m for m in HEAVY if m in loaded]
    assert not [m for m in DEFERRED[module] if m in loaded]


def test_deferred_numba_kernels_match_their_python_source():
    """The kernels numba compiles on first use give the numbers of their plain-Python source
    (and the low-rank trace kernel those of LAPACK's solve)."""
    code = """
import sys
import numpy as np
from sensors.synthesis import fingertip as ft, low_rank_kernels as kernels
from sensors._infra.jit import jitted
assert "numba" not in sys.modules
rng = np.random.default_rng(0)
k, n = 6, 5
iu, ju = np.triu_indices(k)
R = rng.standard_normal((4, n, iu.size))
fast, slow = np.empty(n, complex), np.empty(n, complex)
jitted(vars(kernels), "newton_traces", callees=("recip", "_unpack", "_eliminate"), error_model="numpy")(
    R, iu, ju, k, fast)
kernels.newton_traces(R, iu, ju, k, slow)
M, dM = np.zeros((2, n, k, k), complex)
M[:, iu, ju] = M[:, ju, iu] = -(R[0] + 1j * R[1])
dM[:, iu, ju] = dM[:, ju, iu] = R[2] + 1j * R[3]
exact = np.einsum("aii->a", np.linalg.solve(M + np.eye(k), dM))
assert np.allclose(fast, slow, rtol=1e-12) and np.allclose(fast, exact, rtol=1e-10)
p = ft.FingertipModel(grip_force_n=1.0)._params()
fe = np.sin(np.arange(300) * 0.3) * 5.0
out, min_f, _ = ft._simulate_one_sided(p, fe, 44100.0, 2)
ref, ref_min, _ = ft._simulate(p, fe, 44100.0, 2, np.zeros(8))
assert np.allclose(out, ref, rtol=1e-12, atol=1e-12) and np.isclose(min_f, ref_min) and min_f < 1.0
"""
    assert "numba" in _loaded(code)


def test_aas_help_loads_neither_the_sensor_stack_nor_mujoco():
    loaded = _loaded("import contextlib, io\nfrom aas_gym.cli import build_parser\n"
                     "with contextlib.redirect_stdout(io.StringIO()):\n    build_parser().format_help()")
    assert "sensors.synthesis.modal_system" not in loaded and "pyaudio" not in loaded and "mujoco" not in loaded
    assert not [m for m in HEAVY if m in loaded]


def test_the_object_catalog_names_objects_without_mujoco():
    # The real rig names its objects through the same catalog: no MuJoCo, no envs behind it.
    loaded = _loaded("from sensors.objects import get_object\n"
                     "assert get_object('mug').solid().material.name == 'ceramic'\n"
                     "assert get_object('steel_bar').label == 'steel_bar'")
    assert not [m for m in ("mujoco", "gymnasium", "aas_gym") if m in loaded]


def test_lazy_exports_resolve():
    import real
    import sensors

    assert sensors.SpectralFeatures.__module__ == "sensors.signals.transformers"
    assert callable(sensors.calibrate) and real.PyAudioRig.__module__ == "real.rig"
    with pytest.raises(AttributeError):
        sensors.no_such_name  # noqa: B018


def _real_import_graph() -> tuple[dict[str, set[str]], list[str], list[str]]:
    """``real``'s modules -> the modules of ``real`` each imports (every import statement, also
    inside functions and under ``if TYPE_CHECKING:``), read from the source with ``ast``; the
    absolute imports of other top-level packages; and the private names imported from a module."""
    import ast
    from pathlib import Path

    import real

    folder = Path(real.__file__).parent
    modules = {p.stem: p for p in folder.glob("*.py")}  # "__init__" is the package
    graph: dict[str, set[str]] = {name: set() for name in modules}
    outside, private = [], []
    for name, path in modules.items():
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    top, _, rest = alias.name.partition(".")
                    if top == "real":
                        graph[name].add(rest.split(".")[0] or "__init__")
                    else:
                        outside.append(f"{name}: {alias.name}")
            elif isinstance(node, ast.ImportFrom):
                if node.level == 0 and not (node.module or "").startswith("real"):
                    outside.append(f"{name}: {node.module}")
                    continue
                if node.level > 1:
                    raise AssertionError(f"real/{name}.py imports from above the package: {ast.unparse(node)}")
                target = (node.module or "").removeprefix("real").lstrip(".").split(".")[0]
                if target:
                    graph[name].add(target)
                    private += [f"{name}: {target}.{a.name}" for a in node.names if a.name.startswith("_")]
                else:  # from . import x: a submodule (or a name of real/__init__.py)
                    graph[name] |= {a.name if a.name in modules else "__init__" for a in node.names}
    return graph, outside, private


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import circle of ``graph`` (its modules in order, the first repeated at the end), or None."""
    state: dict[str, str] = {}

    def visit(node: str, path: list[str]) -> list[str] | None:
        state[node] = "open"
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == "open":
                return path[path.index(nxt):] + [nxt]
            if nxt not in state:
                found = visit(nxt, path + [nxt])
                if found:
                    return found
        state[node] = "done"
        return None

    for start in sorted(graph):
        if start not in state:
            found = visit(start, [start])
            if found:
                return found
    return None


def test_cycle_finder_finds_circles_and_only_circles():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"a"}}) == ["a", "a"]
    assert _cycle({"a": {"b", "c"}, "b": {"c"}, "c": set(), "d": {"a", "c"}}) is None


def test_real_imports_form_no_circle_and_stay_off_aas_gym_and_mujoco():
    """real/ runs on a robot computer without MuJoCo, and its modules import one another one
    way only (data and settings at the bottom, the rig above its sessions), type-only imports
    included; no module imports another's private name."""
    graph, outside, private = _real_import_graph()
    assert {"records", "settings", "errors", "devices", "streams", "session", "rig"} <= set(graph)
    assert graph["rig"] >= {"session", "settings", "records"} and "rig" not in graph["session"]
    assert _cycle(graph) is None, " -> ".join(_cycle(graph))
    # the plain data of the rig stands alone
    assert graph["records"] == set() and graph["settings"] == set()
    assert not [m for m in outside if m.split(": ")[1].split(".")[0] in ("aas_gym", "mujoco")]
    assert not private, private
