"""Every example writes where its own location says (the repository's ``outputs/`` or
``docs/``) or where ``--out`` says, never relative to the folder it is run from: no relative
``Path("...")`` and no relative path string as an argument default."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

EXAMPLES = sorted((Path(__file__).resolve().parent.parent / "examples").glob("*.py"))
_SUFFIXES = (".png", ".md", ".json", ".npz", ".parquet", ".csv")


def _relative_paths(source: str) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "Path" and node.args:
            arg = node.args[0]
            if isinstance(arg, ast.Constant) and isinstance(arg.value, str) and not arg.value.startswith("/"):
                found.append(f"Path({arg.value!r})")
        if isinstance(node, ast.keyword) and node.arg == "default" and isinstance(node.value, ast.Constant):
            value = node.value.value
            if isinstance(value, str) and ("/" in value or value.endswith(_SUFFIXES) or value in ("outputs", "recordings")):
                found.append(f"default={value!r}")
    return found


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_example_output_paths_do_not_depend_on_the_current_folder(path):
    assert _relative_paths(path.read_text()) == []


def test_the_check_sees_a_cwd_relative_default():
    source = 'ap.add_argument("--out", default="docs/images/x.png")\nout = Path("outputs")\n'
    assert sorted(_relative_paths(source)) == ["Path('outputs')", "default='docs/images/x.png'"]
