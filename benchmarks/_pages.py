"""What the per-object benchmarks share: one row per item, printed as it lands, and the
Markdown page with the machine it ran on."""

from __future__ import annotations

import argparse
import os
import platform
from pathlib import Path

from sensors._infra.atomic import atomic_write_text


def machine_line() -> str:
    """The machine, Python and the 1-minute load average now (busy cores inflate wall times)."""
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    busy = " (other jobs shared the cores: wall times are upper bounds)" if load > 0.75 * (os.cpu_count() or 1) else ""
    return (f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}; "
            f"1-minute load average at the end of the run {load:.1f}{busy}.")


def parse_args(description: str, items_name: str, default_items, page_name: str, argv=None,
               flags: dict[str, str] | None = None) -> argparse.Namespace:
    """``[items ...] [--out OUT]``: which items to run (default all) and the page to write
    (default docs/benchmarks/<page_name>); ``flags`` adds on/off options (``{"--name": help}``)."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument(items_name, nargs="*", default=list(default_items))
    for flag, text in (flags or {}).items():
        parser.add_argument(flag, action="store_true", help=text)
    parser.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "docs" / "benchmarks" / page_name))
    return parser.parse_args(argv)


def rows_to_page(items, run, table, out, title: str, written_by: str, explanation: str) -> list[dict]:
    """``run(item)`` for each item (its row printed at once), then ``out`` written atomically:
    title, how it was written, the machine, ``explanation`` and ``table(rows)``."""
    rows = []
    for item in items:
        rows.append(run(item))
        print(table(rows[-1:]).splitlines()[-1], flush=True)
    text = f"# {title}\n\nWritten by {written_by}.\n\n{machine_line()}\n\n{explanation}\n\n{table(rows)}"
    atomic_write_text(Path(out), text)
    print(f"wrote {out}")
    return rows
