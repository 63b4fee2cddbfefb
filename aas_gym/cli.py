"""The ``aas`` command line.

Subcommands are registered by the modules that own them, so each capability keeps its CLI
next to its code (``real.cli`` for the rig, ``aas_gym.experiments`` for the paper's runs).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from typing import Callable

# Modules that may add subcommands through ``add_subcommands(subparsers)``. A module whose
# optional dependency is missing (PyAudio for ``real``) only loses its own commands.
_PLUGIN_MODULES = ("aas_gym.experiments.cli", "aas_gym.calibration_cli", "aas_gym.demo", "real.cli")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="aas",
        description="aas-gym: active acoustic sensing for robot manipulation, simulated and real.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    parser.add_argument("--debug", action="store_true", help="show the full traceback of an error")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in _PLUGIN_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name is not None and (exc.name == name or name.startswith(exc.name + ".")):
                continue  # that capability is not in this checkout
            _missing_dependency(sub, name, exc)
            continue
        module.add_subcommands(sub)
    return parser


def _missing_dependency(sub, module_name: str, exc: ModuleNotFoundError) -> None:
    group = module_name.split(".")[0]

    def fail(_args) -> int:
        print(f"aas: the '{group}' commands need the Python package '{exc.name}', which is not installed "
              f"(install the project with its extras: pip install -e '.[real,ray]').", file=sys.stderr)
        return 2

    p = sub.add_parser(group, help=f"(unavailable: missing '{exc.name}')")
    p.set_defaults(func=fail)


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("aas-gym")
    except Exception:  # running from a source tree without an install
        return "unknown"


class UsageError(ValueError):
    """A command was given arguments it cannot use (exit code 2)."""


# Errors that mean "the input was wrong": exit 2 and say what to change. Everything else that
# is an ordinary failure (a file system refusing, a dataset that does not load) exits 1.
_USAGE_ERRORS = (UsageError, ValueError, KeyError, TypeError)
_FAILURES = (OSError, RuntimeError)


def main(argv: list[str] | None = None) -> int:
    """Run the ``aas`` command line; returns the exit code (0 ok, 1 failure, 2 usage, 130
    interrupted). Errors print one line; ``--debug`` shows the traceback."""
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)  # the command line, for dataset cards
    func: Callable[[argparse.Namespace], int] | None = getattr(args, "func", None)
    if func is None:
        parser.print_help()
        return 0
    try:
        return int(func(args) or 0)
    except (KeyboardInterrupt,) + _USAGE_ERRORS + _FAILURES as exc:
        if args.debug:
            raise
        if _interrupt_in(exc):
            hint = getattr(args, "interrupt_hint", None)
            print(f"aas {args.command}: interrupted" + (f": {hint}" if hint else ""), file=sys.stderr)
            return 130
        print(f"aas {args.command}: {_one_line(exc)}", file=sys.stderr)
        return 2 if isinstance(exc, _USAGE_ERRORS) and not isinstance(exc, _FAILURES) else 1


def _interrupt_in(exc: BaseException | None) -> bool:
    """Whether ``exc`` is a Ctrl-C or was raised by one: Python wraps an interrupt that lands in
    some hooks in another error (a descriptor's ``__set_name__`` while a lazily imported module
    defines a class: "Error calling __set_name__ on ...", a RuntimeError)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _one_line(exc: BaseException) -> str:
    text = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
    text = " ".join(str(text).split()) or type(exc).__name__
    if isinstance(exc, OSError) and exc.filename and str(exc.filename) not in text:
        text = f"{text}: {exc.filename}"
    return f"{text} (run with --debug for the traceback)" if isinstance(exc, _FAILURES) else text


if __name__ == "__main__":
    sys.exit(main())
