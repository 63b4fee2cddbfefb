"""The dependency rule, read from the source with ``ast`` (nothing under test is imported).

* ``sensors`` imports neither MuJoCo, PyAudio, gymnasium's envs, ``aas_gym`` nor ``real``.
* ``real`` imports neither ``aas_gym`` nor MuJoCo.
* A stage subpackage of ``sensors`` imports only itself and earlier stages (:data:`STAGES`);
  ``sensors/__init__.py`` is the face and may import all of them.
* No module uses a private (leading underscore) name of another module, nor a private module
  from outside its own package. ``sensors._infra`` is shared infrastructure: the one private
  package whose public names may be used anywhere.

An import inside a function counts: a lazy import is still a dependency.
"""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Import packages, and folders of scripts (not packages: their files import each other by bare name).
PACKAGES = ("sensors", "aas_gym", "real")
SCRIPT_DIRS = ("tests", "benchmarks", "examples")
#: The stage subpackages of ``sensors`` in dependency order: each may import only earlier ones.
STAGES = ("_infra", "signals", "materials", "mesh", "fem", "modal", "synthesis", "objects", "fluid",
          "calibration", "task")
FORBIDDEN = {
    "sensors": ("mujoco", "pyaudio", "gymnasium.envs", "aas_gym", "real"),
    "real": ("aas_gym", "mujoco"),
}
SHARED_PRIVATE_PACKAGE = "sensors._infra"


def is_private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def within(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


@dataclasses.dataclass(frozen=True)
class Import:
    """One imported thing: ``module`` (resolved, absolute), and ``name`` when a from-import
    takes a name that is not itself a module."""

    line: int
    module: str
    name: str | None = None

    @property
    def dotted(self) -> str:
        return f"{self.module}.{self.name}" if self.name else self.module


@dataclasses.dataclass
class Source:
    path: Path
    module: str          # dotted name, e.g. "sensors.mesh.tets" or "benchmarks._pages"
    package: str         # what relative imports are relative to
    tree: ast.Module


class Project:
    """Every Python file of the project with its dotted name, under ``root``."""

    def __init__(self, root: Path):
        self.root = root
        self.sources: list[Source] = []
        for top in PACKAGES + SCRIPT_DIRS:
            for path in sorted((root / top).rglob("*.py")):
                parts = list(path.relative_to(root).with_suffix("").parts)
                is_init = parts[-1] == "__init__"
                if is_init:
                    parts = parts[:-1]
                module = ".".join(parts)
                package = module if is_init else module.rpartition(".")[0]
                tree = ast.parse(path.read_text(encoding="utf-8"))
                for node in ast.walk(tree):  # used_chains needs each node's parent
                    for child in ast.iter_child_nodes(node):
                        child.parent = node
                self.sources.append(Source(path, module, package, tree))
        self.modules = {s.module for s in self.sources}

    def rel(self, source: Source) -> str:
        return source.path.relative_to(self.root).as_posix()

    def absolute(self, source: Source, module: str | None, level: int) -> str:
        """The absolute name of ``from <level dots><module> import ...`` in ``source``; a bare
        name a script imports from its own folder (``from _pages import ...``) gets the folder's."""
        if level:
            base = source.package.split(".")
            base = base[:len(base) - (level - 1)]
            return ".".join(base + ([module] if module else []))
        top = source.module.split(".")[0]
        if top in SCRIPT_DIRS and module and f"{source.package}.{module}" in self.modules:
            return f"{source.package}.{module}"
        return module or ""

    def imports(self, source: Source) -> list[tuple[Import, str, str]]:
        """Every import in ``source``, the local name it binds ("" for none) and the dotted name
        that local name stands for (``import a.b`` binds ``a`` to ``a``)."""
        out = []
        for node in ast.walk(source.tree):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    module = self.absolute(source, alias.name, 0)
                    if alias.asname:
                        out.append((Import(node.lineno, module), alias.asname, module))
                    else:
                        top = module.split(".")[0] if "." in alias.name else module
                        out.append((Import(node.lineno, module), alias.name.split(".")[0], top))
            elif isinstance(node, ast.ImportFrom):
                module = self.absolute(source, node.module, node.level)
                for alias in node.names:
                    local = alias.asname or alias.name
                    if alias.name == "*":
                        out.append((Import(node.lineno, module), "", module))
                    elif f"{module}.{alias.name}" in self.modules:  # a submodule, not a name
                        out.append((Import(node.lineno, f"{module}.{alias.name}"), local, f"{module}.{alias.name}"))
                    else:
                        out.append((Import(node.lineno, module, alias.name), local, f"{module}.{alias.name}"))
        return out


def stage_of(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if parts[0] == "sensors" and len(parts) > 1 else None


def private_module_violation(importer: str, module: str) -> str | None:
    """The first private package or module on ``module``'s path that ``importer`` is outside of."""
    parts = module.split(".")
    for i, part in enumerate(parts):
        owner = ".".join(parts[:i])  # the package the private part belongs to
        private = ".".join(parts[:i + 1])
        if is_private(part) and private != SHARED_PRIVATE_PACKAGE and not within(importer, owner or part):
            return private
    return None


def forbidden_imports(project: Project) -> list[str]:
    found = []
    for source in project.sources:
        top = source.module.split(".")[0]
        for imp, _, _ in project.imports(source):
            for prefix in FORBIDDEN.get(top, ()):
                if within(imp.dotted, prefix):
                    found.append(f"{project.rel(source)}:{imp.line}: {top} must not import {prefix} "
                                 f"(imports {imp.dotted})")
    return found


def later_stage_imports(project: Project) -> list[str]:
    found = []
    for source in project.sources:
        stage = stage_of(source.module)
        if stage is None:  # outside sensors, or the face sensors/__init__.py
            continue
        for imp, _, _ in project.imports(source):
            if not within(imp.module, "sensors"):
                continue
            where = f"{project.rel(source)}:{imp.line}"
            target = stage_of(imp.module)
            if target is None:
                found.append(f"{where}: stage {stage} imports the face `sensors` (which imports every stage): "
                             f"import {imp.name or 'it'} from the stage that holds it")
            elif target not in STAGES:
                found.append(f"{where}: {imp.dotted} is in no stage of STAGES")
            elif STAGES.index(target) > STAGES.index(stage):
                found.append(f"{where}: stage {stage} imports later stage {target} ({imp.dotted}); "
                             f"order: {' < '.join(STAGES)}")
    return found


def attribute_chain(node: ast.Attribute) -> list[str] | None:
    """``a.b.c`` -> ["a", "b", "c"]; None if the chain does not start at a plain name."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    return [node.id] + parts[::-1] if isinstance(node, ast.Name) else None


def used_chains(tree: ast.Module):
    """(line, ["name", "attr", ...]) for every outermost attribute chain, and for
    ``getattr/setattr/delattr(name, "attr", ...)`` and ``monkeypatch.setattr(name, "attr", ...)``."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and not isinstance(getattr(node, "parent", None), ast.Attribute):
            chain = attribute_chain(node)
            if chain:
                yield node.lineno, chain
        elif isinstance(node, ast.Call) and len(node.args) >= 2 and isinstance(node.args[0], ast.Name) \
                and isinstance(node.args[1], ast.Constant) and isinstance(node.args[1].value, str) \
                and ((isinstance(node.func, ast.Name) and node.func.id in ("getattr", "setattr", "delattr"))
                     or (isinstance(node.func, ast.Attribute) and node.func.attr in ("setattr", "delattr"))):
            yield node.lineno, [node.args[0].id, node.args[1].value]


def private_uses(project: Project) -> list[str]:
    """Private names (and private modules) of other modules, imported or reached as attributes
    (a private member of an imported class counts too)."""
    found = []
    for source in project.sources:
        where = project.rel(source)
        bound = {}  # local name -> the dotted project module or module.name it stands for
        for imp, local, target in project.imports(source):
            if imp.module.split(".")[0] not in PACKAGES + SCRIPT_DIRS:
                continue
            private = private_module_violation(source.module, imp.module)
            if private:
                found.append(f"{where}:{imp.line}: private module {private} used outside its package "
                             f"(imports {imp.dotted})")
            if imp.name and is_private(imp.name) and imp.module != source.module:
                found.append(f"{where}:{imp.line}: private name {imp.name} imported from {imp.module}")
            if local:
                bound[local] = target
        for line, chain in used_chains(source.tree):
            if chain[0] not in bound:
                continue
            # Walk down submodules (``sensors.mesh.tets``) to the first attribute that is not one.
            owner, rest = bound[chain[0]], chain[1:]
            while rest and f"{owner}.{rest[0]}" in project.modules:
                owner, rest = f"{owner}.{rest[0]}", rest[1:]
            private = private_module_violation(source.module, owner)
            if private and not private_module_violation(source.module, bound[chain[0]]):
                found.append(f"{where}:{line}: private module {private} used outside its package")
            if rest and is_private(rest[0]) and owner != source.module:
                kind = "name" if owner in project.modules else "member"
                used = ".".join(chain[:len(chain) - len(rest) + 1])
                found.append(f"{where}:{line}: private {kind} {rest[0]} of {owner} used ({used})")
    return sorted(set(found))


@pytest.fixture(scope="module")
def project() -> Project:
    return Project(ROOT)


def report(found: list[str], rule: str) -> str:
    return f"{len(found)} violation(s) of: {rule}\n" + "\n".join(found)


def test_sensors_and_real_import_no_simulator_audio_or_env_code(project):
    found = forbidden_imports(project)
    assert not found, report(found, "sensors imports no mujoco, pyaudio, gymnasium.envs, aas_gym or real; "
                                    "real imports no aas_gym or mujoco")


def test_a_sensors_stage_imports_only_earlier_stages(project):
    found = later_stage_imports(project)
    assert not found, report(found, f"a sensors stage imports only earlier ones ({' < '.join(STAGES)})")


def test_no_module_uses_another_modules_private_names(project):
    found = private_uses(project)
    assert not found, report(found, "no private (leading underscore) name or module of another module; "
                                    f"{SHARED_PRIVATE_PACKAGE} is the one shared private package")


def test_each_rule_catches_what_it_names(tmp_path):
    """The checks above pass only if they can fail: a small project breaking each rule once."""
    files = {
        "sensors/__init__.py": "from .task import grasp\n",  # the face may import every stage
        "sensors/_infra/__init__.py": "",
        "sensors/_infra/cache.py": "KEY = 1\n_SECRET = 2\n",
        "sensors/mesh/__init__.py": "",
        "sensors/mesh/tets.py": "import mujoco\ndef _orient():\n    pass\n",
        "sensors/mesh/_kernels.py": "",
        "sensors/mesh/prisms.py": "from .tets import _orient\nfrom . import _kernels\nfrom .._infra import cache\n"
                                  "from .._infra.cache import KEY\nx = cache._SECRET\n",
        "sensors/task/__init__.py": "",
        "sensors/task/grasp.py": "from gymnasium import spaces\n",
        "sensors/fem/__init__.py": "",
        "sensors/fem/assembly.py": "from ..mesh import tets\nfrom ..task.grasp import G\ntets._orient()\n"
                                   "import sensors\n",
        "real/__init__.py": "",
        "real/rig.py": "def f():\n    from aas_gym import scene\n",
        "aas_gym/__init__.py": "",
        "aas_gym/envs.py": "import sensors.mesh.tets\nsensors.mesh.tets._orient()\nimport mujoco\n"
                           "from sensors.mesh import _kernels\n",
        "tests/test_x.py": "from sensors.mesh import tets\ndef test(monkeypatch):\n"
                           "    monkeypatch.setattr(tets, '_orient', None)\n",
        "benchmarks/_pages.py": "",
        "benchmarks/run.py": "from _pages import rows\n",
    }
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    fake = Project(tmp_path)
    assert sorted(f.split(":")[:2] for f in forbidden_imports(fake)) == [["real/rig.py", "2"],
                                                                         ["sensors/mesh/tets.py", "1"]]
    assert sorted(f.split(":")[:2] for f in later_stage_imports(fake)) == [["sensors/fem/assembly.py", "2"],
                                                                     ["sensors/fem/assembly.py", "4"]]
    assert sorted(f.split(":")[:2] for f in private_uses(fake)) == [
        ["aas_gym/envs.py", "2"], ["aas_gym/envs.py", "4"], ["sensors/fem/assembly.py", "3"],
        ["sensors/mesh/prisms.py", "1"], ["sensors/mesh/prisms.py", "5"], ["tests/test_x.py", "3"]]
