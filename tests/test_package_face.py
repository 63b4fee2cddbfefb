"""The worked example at the top of ``sensors`` runs as written, and every name the docs cite
as ``sensors.X`` exists."""

import importlib.util
import re
from pathlib import Path

import numpy as np

import sensors

ROOT = Path(__file__).resolve().parents[1]


def test_the_worked_example_of_the_package_docstring_runs():
    doc = sensors.__doc__
    lines = []
    for line in doc.split("::\n", 1)[1].splitlines():
        if line.strip() and not line.startswith("    "):
            break                                   # the first unindented line ends the block
        lines.append(line[4:])
    code = "\n".join(lines)
    scope: dict = {}
    exec(compile(code, "sensors.__doc__", "exec"), scope)
    obs = scope["obs"]
    assert obs.features().shape == (140,) and np.all(np.isfinite(obs.features()))
    assert np.max(np.abs(obs.waveform)) > 10 * 1e-4      # the grasp is heard above the noise


def test_every_name_the_docs_cite_is_exported():
    cited = set()
    for path in [ROOT / "README.md", *(ROOT / "docs").rglob("*.md"), *(ROOT / "sensors").rglob("*.py")]:
        cited |= set(re.findall(r"`sensors\.([A-Za-z_]\w*)", path.read_text(encoding="utf-8")))
    missing = sorted(n for n in cited if not hasattr(sensors, n) and importlib.util.find_spec(f"sensors.{n}") is None)
    assert not missing, f"docs cite sensors.<name> that `import sensors` lacks: {missing}"
