"""pytest plugin: the suite reports its own peak memory (resident set size) per process.

Every process that runs tests (the controller alone, or each xdist worker) follows
``getrusage``'s ``ru_maxrss`` after each test and remembers the test file during which its peak
last rose; the same for the processes it started and waited for (``RUSAGE_CHILDREN``: the
largest of them, e.g. a CLI subprocess). A worker sends its figures to the controller through
xdist's ``workeroutput``; the controller prints one line per process in the terminal summary,
then the overall peak, e.g. ``peak memory: 3.2 GB (worker gw1, tests/test_x.py)``, and a warning
line (the run does not fail) when it passes ``--peak-memory-warn-gb`` (default 6 GB, the budget
that lets two workers beside another job fit a 24 GB machine). GB here is 10^9 bytes.
"""

from __future__ import annotations

import resource
import sys

import pytest

DEFAULT_WARN_GB = 6.0
_KEY = "peak_memory"


def _maxrss_bytes(who: int) -> int:
    """``ru_maxrss`` in bytes (Linux reports KiB, macOS bytes). This process's own peak is read
    from Linux's ``VmHWM`` where there is one: ``ru_maxrss`` keeps the parent's peak across fork
    and exec, so a run started by a big process would report that process's peak as its own."""
    if who == resource.RUSAGE_SELF:
        try:
            with open("/proc/self/status") as status:
                for line in status:
                    if line.startswith("VmHWM:"):
                        return int(line.split()[1]) * 1024
        except OSError:
            pass
    rss = resource.getrusage(who).ru_maxrss
    return int(rss) if sys.platform == "darwin" else int(rss) * 1024


class PeakTracker:
    """This process's peak RSS, and its children's, each with the test file that raised it last."""

    def __init__(self):
        self.peaks = {"self": [_maxrss_bytes(resource.RUSAGE_SELF), "outside tests"],
                      "children": [_maxrss_bytes(resource.RUSAGE_CHILDREN), "outside tests"]}

    def after(self, test_file: str) -> None:
        for name, who in (("self", resource.RUSAGE_SELF), ("children", resource.RUSAGE_CHILDREN)):
            rss = _maxrss_bytes(who)
            if rss > self.peaks[name][0]:
                self.peaks[name] = [rss, test_file]

    def report(self) -> dict:
        """Plain data (xdist's ``workeroutput`` carries only builtins)."""
        self.after("outside tests")
        return {name: {"bytes": rss, "file": f} for name, (rss, f) in self.peaks.items()}


def pytest_addoption(parser):
    parser.addoption("--peak-memory-warn-gb", type=float, default=DEFAULT_WARN_GB,
                     help="warn in the summary when any test process's peak RSS passes this many GB "
                          f"(10^9 bytes; default {DEFAULT_WARN_GB:g}); the run does not fail")


_tracker_key = pytest.StashKey["PeakTracker"]()
_workers_key = pytest.StashKey[dict]()


def pytest_configure(config):
    config.stash[_tracker_key] = PeakTracker()
    config.stash[_workers_key] = {}


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item, nextitem):
    try:
        return (yield)
    finally:  # item.location[0]: the test's file, relative to the rootdir
        item.config.stash[_tracker_key].after(item.location[0])


def pytest_sessionfinish(session):
    workeroutput = getattr(session.config, "workeroutput", None)
    if workeroutput is not None:  # an xdist worker: hand the figures to the controller
        workeroutput[_KEY] = session.config.stash[_tracker_key].report()


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    """xdist controller: a worker finished; keep what it measured."""
    output = getattr(node, "workeroutput", None) or {}
    if _KEY in output:
        node.config.stash[_workers_key][node.workerinput["workerid"]] = output[_KEY]


def _gb(n_bytes: int) -> str:
    return f"{n_bytes / 1e9:.2f} GB"


def pytest_terminal_summary(terminalreporter, config):
    if hasattr(config, "workeroutput"):
        return
    processes = {"controller": config.stash[_tracker_key].report()}
    if config.stash[_workers_key]:  # the controller's children are the workers, reported below
        processes["controller"]["children"]["bytes"] = 0
    for worker, report in sorted(config.stash[_workers_key].items()):
        processes[f"worker {worker}"] = report
    tr = terminalreporter
    tr.write_sep("-", "peak memory (max RSS per process)")
    rows = []
    for name, report in processes.items():
        own, kids = report["self"], report["children"]
        line = f"{name}: {_gb(own['bytes'])} ({own['file']})"
        if kids["bytes"] > 0:
            line += f"; largest child process: {_gb(kids['bytes'])} ({kids['file']})"
        tr.write_line(line)
        rows.append((own["bytes"], name, own["file"]))
        rows.append((kids["bytes"], f"child of {name}", kids["file"]))
    peak, who, where = max(rows)
    tr.write_line(f"peak memory: {_gb(peak)} ({who}, {where})", bold=True)
    limit_gb = config.getoption("--peak-memory-warn-gb")
    if peak > limit_gb * 1e9:
        tr.write_sep("!", f"WARNING: peak memory {_gb(peak)} passes the {limit_gb:g} GB budget "
                          f"({who}, {where})", red=True, bold=True)
