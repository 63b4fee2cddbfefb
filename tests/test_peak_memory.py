"""The suite's own peak-memory report (tests/peak_memory.py), run on a tiny generated suite."""

import os
import re
from pathlib import Path

import pytest

TESTS_DIR = Path(__file__).resolve().parent

BIG = """
import numpy as np

def test_allocates():
    block = np.ones(400_000_000 // 8)  # 0.4 GB, written (resident)
    assert block.sum() == block.size
"""

SMALL = """
def test_small():
    assert 1 + 1 == 2
"""


@pytest.fixture
def suite(pytester, monkeypatch):
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(TESTS_DIR), os.environ.get("PYTHONPATH", "")]))
    pytester.makepyfile(test_big=BIG, test_small=SMALL)
    return pytester


def peak_line(result):
    lines = [line for line in result.outlines if line.startswith("peak memory: ")]
    assert len(lines) == 1, result.stdout.str()
    return re.fullmatch(r"peak memory: (\d+\.\d+) GB \((.+), (.+)\)", lines[0]).groups()


def test_each_worker_reports_its_peak_and_the_file_that_raised_it(suite):
    result = suite.runpytest_subprocess("-p", "peak_memory", "-p", "no:cacheprovider", "-n", "2",
                                        "--dist", "loadfile", "--peak-memory-warn-gb", "0.3")
    result.assert_outcomes(passed=2)
    gb, who, where = peak_line(result)
    assert float(gb) >= 0.4 and re.fullmatch(r"worker gw[01]", who) and where == "test_big.py"
    workers = [line for line in result.outlines if line.startswith("worker gw")]
    assert len(workers) == 2, result.stdout.str()
    assert any("WARNING: peak memory" in line and "0.3 GB budget" in line for line in result.outlines)


def test_single_process_run_under_budget_has_no_warning(suite):
    result = suite.runpytest_subprocess("-p", "peak_memory", "-p", "no:cacheprovider", "test_small.py")
    result.assert_outcomes(passed=1)
    gb, who, where = peak_line(result)
    assert who == "controller" and float(gb) < 6.0
    assert not any("WARNING" in line for line in result.outlines)
