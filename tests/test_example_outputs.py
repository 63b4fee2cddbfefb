"""Every example writes where its own location says (the repository's ``outputs/`` or
``docs/``) or where ``--out`` says, never relative to the folder it is run from: no relative
``Path("...")`` and no relative path string as an argument default."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

EXAMPLES = sorted((Path(__file__).resolve().parent.parent / "examples").glob("*.py"))
_SUFFIXES = (".png", ".md", ".json", ".npz", ".parquet", ".csv")


#: Calls that write the file named by their first argument.
_WRITERS = {name: name for name in ("savefig", "imsave", "savez", "savez_compressed", "save", "open", "to_parquet",
                                    "to_csv", "atomic_write_text", "atomic_savefig")}


def _relative_text(node: ast.AST) -> bool:
    """A string literal (or f-string) that is a relative path."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return not node.value.startswith("/") and node.value.endswith(_SUFFIXES)
    if isinstance(node, ast.JoinedStr):
        head = node.values[0] if node.values else None
        return not (isinstance(head, ast.Constant) and str(head.value).startswith("/"))
    return False


def _is_script_folder(node: ast.AST) -> bool:
    return isinstance(node, ast.Name) and node.id in ("HERE", "ROOT")


def _names_an_argument(node: ast.AST) -> bool:
    return isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "args"


def _relative_paths(source: str) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "Path" and node.args:
            arg = node.args[0]
            if isinstance(arg, ast.Constant) and isinstance(arg.value, str) and not arg.value.startswith("/"):
                found.append(f"Path({arg.value!r})")
        if isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", None)) in _WRITERS \
                and node.args and _relative_text(node.args[0]):
            found.append(f"{_WRITERS[getattr(node.func, 'attr', getattr(node.func, 'id', None))]}({ast.unparse(node.args[0])})")
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div) and _is_script_folder(node.left) \
                and _names_an_argument(node.right):
            found.append(f"{ast.unparse(node)}")  # a caller's relative --out re-anchored to the script
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


def test_the_check_sees_cwd_relative_writes_and_a_reanchored_out():
    source = ('fig.savefig("spectrum.png")\nnp.savez(f"run_{i}.npz", x=x)\nopen("log.json", "w")\n'
              'out = (HERE / args.out).resolve()\nfig.savefig(OUT / "a.png")\nopen(path)\n')
    assert sorted(_relative_paths(source)) == ["HERE / args.out", "open('log.json')", "savefig('spectrum.png')",
                                               "savez(f'run_{i}.npz')"]
