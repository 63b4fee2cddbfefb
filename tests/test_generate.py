"""Dataset generation: deterministic bytes, resumable after a kill, same output on Ray."""

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from aas_gym.experiments.config import DatasetConfig
from aas_gym.experiments.generate import MANIFEST, generate_dataset, load_dataset

# Two objects, one excitation, tiny counts: every code path, a few seconds of simulation.
SMALL = dict(objects=("aluminium_bar", "wood_bar"), excitations=("linear",), single_grasps=2,
             multi_grasps=1, positions=2, position_repeats=1, shard_size=2, seed=7)


def _bytes(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.glob("shard-*.parquet"))}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("ref")
    generate_dataset(DatasetConfig(**SMALL), out, workers=1, progress=False)
    return out


def test_dataset_content(reference):
    df = load_dataset(reference)
    config = DatasetConfig(**SMALL)
    assert len(df) == len(config.tasks()) * len(config.excitations)
    assert set(df.scene) == {"single", "multi", "position"}
    feats = np.stack(df.features)
    assert feats.shape == (len(df), 140) and np.all(np.isfinite(feats)) and np.all(feats >= 0)
    pos = df[df.scene == "position"].sort_values("task_id")
    np.testing.assert_allclose(sorted(set(pos.position_m)), [0.0, 0.005])
    manifest = json.loads((reference / ".dataset.json").read_text())
    assert manifest["fingerprint"] == config.fingerprint()


def test_same_seed_same_bytes_and_another_seed_differs(reference, tmp_path):
    generate_dataset(DatasetConfig(**SMALL), tmp_path / "again", workers=2, progress=False)
    assert _bytes(tmp_path / "again") == _bytes(reference)
    other = dict(SMALL, seed=8, scenes=("single",))
    generate_dataset(DatasetConfig(**other), tmp_path / "other", workers=1, progress=False)
    a = np.stack(load_dataset(tmp_path / "other").features)
    ref = load_dataset(reference)
    b = np.stack(ref[ref.scene == "single"].features)
    assert not np.allclose(a, b)


def test_resume_after_kill_loses_and_duplicates_nothing(reference, tmp_path):
    out = tmp_path / "killed"
    code = (
        "import sys; from aas_gym.experiments.config import DatasetConfig;"
        "from aas_gym.experiments.generate import generate_dataset;"
        f"generate_dataset(DatasetConfig(**{SMALL!r}), {str(out)!r}, workers=1, progress=False,"
        " on_shard=lambda i: print('shard', i, flush=True))"
    )
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    first = proc.stdout.readline()  # one shard is on disk: kill mid-way through the next
    assert first.startswith("shard")
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    n_before = len(list(out.glob("shard-*.parquet")))
    assert 1 <= n_before < len(DatasetConfig(**SMALL).shards())
    done = []
    generate_dataset(DatasetConfig(**SMALL), out, workers=1, progress=False, on_shard=done.append)
    assert len(done) == len(DatasetConfig(**SMALL).shards()) - n_before  # only the missing ones
    assert _bytes(out) == _bytes(reference)
    assert not list(out.glob(".*.tmp"))


def test_a_shard_has_the_same_bytes_whatever_the_thread_count(reference):
    """A fresh worker on a machine with many cores: PARDISO and BLAS would sum in another
    order with more threads. The shard runs single-threaded whatever the environment says
    (the libraries load before the limit), so the bytes match the reference's."""
    code = ("import sys; from aas_gym.experiments.config import DatasetConfig;"
            "from aas_gym.experiments.generate import compute_shard;"
            f"sys.stdout.buffer.write(compute_shard(DatasetConfig(**{SMALL!r}).to_dict(), 0))")
    for threads in ("1", "6"):
        env = dict(os.environ, OMP_NUM_THREADS=threads, MKL_NUM_THREADS=threads, OPENBLAS_NUM_THREADS=threads,
                   PYTHONPATH=os.pathsep.join(filter(None, [str(Path(__file__).parents[1]),
                                                            os.environ.get("PYTHONPATH")])))
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, check=True).stdout
        assert out == _bytes(reference)["shard-00000.parquet"], f"{threads} threads"


def test_another_config_in_the_same_folder_is_refused(reference, tmp_path):
    out = tmp_path / "d"
    generate_dataset(DatasetConfig(**dict(SMALL, scenes=("position",))), out, progress=False)
    with pytest.raises(FileExistsError, match="another configuration"):
        generate_dataset(DatasetConfig(**dict(SMALL, scenes=("position",), seed=1)), out, progress=False)


def test_a_dataset_begun_by_other_code_is_not_finished_by_this_code(tmp_path, monkeypatch):
    # A dataset begun before a physics change (here: the source hash differs) would otherwise
    # be resumed silently, its old shards mixed with new ones.
    import aas_gym.experiments.config as config_mod
    import aas_gym.experiments.generate as generate_mod

    out = tmp_path / "d"
    config = DatasetConfig(**dict(SMALL, scenes=("position",)))
    generate_dataset(config, out, progress=False)
    monkeypatch.setattr(config_mod, "code_version", lambda: "0123456789abcdef")
    monkeypatch.setattr(generate_mod, "code_version", config_mod.code_version)
    with pytest.raises(FileExistsError, match="begun by other aas-gym code"):
        generate_dataset(config, out, progress=False)
    generate_dataset(config, out, progress=False, overwrite=True)
    assert json.loads((out / MANIFEST).read_text())["code_version"] == "0123456789abcdef"


def test_source_hash_changes_with_any_module(tmp_path):
    import shutil

    import sensors
    from aas_gym.experiments.config import source_hash

    pkg = tmp_path / "sensors"
    shutil.copytree(Path(sensors.__file__).parent, pkg, ignore=shutil.ignore_patterns("__pycache__"))
    before = source_hash(pkg)
    assert source_hash(pkg) == before
    deep = pkg / "calibration" / next(p.name for p in (pkg / "calibration").glob("*.py"))
    deep.write_text(deep.read_text() + "\n# edited\n")
    assert source_hash(pkg) != before


def test_source_hash_changes_with_an_mjcf_asset(tmp_path):
    """A dataset made with another robot or scene model is another dataset."""
    import shutil

    from aas_gym.assets import ASSETS_DIR
    from aas_gym.experiments.config import source_hash

    assets = tmp_path / "assets"
    shutil.copytree(ASSETS_DIR, assets)
    before = source_hash(assets)
    hand = assets / "franka_hand.xml"
    hand.write_text(hand.read_text().replace("<mujoco", "<mujoco ", 1))
    assert source_hash(assets) != before


@pytest.mark.slow
def test_ray_gives_the_same_bytes(reference, tmp_path):
    pytest.importorskip("ray")
    generate_dataset(DatasetConfig(**SMALL), tmp_path / "ray", ray_address="local", progress=False)
    assert _bytes(tmp_path / "ray") == _bytes(reference)


def test_bad_config_is_named():
    with pytest.raises(ValueError, match="excitations"):
        DatasetConfig(excitations=("chirp",))
    with pytest.raises(ValueError, match="single_grasps"):
        DatasetConfig(single_grasps=-1)


def test_report_from_a_dataset(tmp_path):
    from aas_gym.experiments.report import run_protocols, write_report

    # Four grasps per object: KNN (k = 3) needs three training samples in every CV fold.
    config = DatasetConfig(**dict(SMALL, scenes=("single", "multi"), single_grasps=4))
    generate_dataset(config, tmp_path / "data", progress=False)
    rec, pos = run_protocols(load_dataset(tmp_path / "data"))
    assert {(r.protocol, r.classifier) for r in rec} == {(p, c) for p in ("single", "transfer") for c in ("KNN", "SVM", "MLP")}
    assert all(0 <= r.accuracy <= 100 and r.confusion.sum() > 0 for r in rec)
    path = write_report(rec, pos, tmp_path / "report")
    text = path.read_text()
    assert "| linear | single -> single (5-fold) |" in text and "78.6" in text  # the paper's KNN figure beside ours
    assert (tmp_path / "report" / "confusion.png").stat().st_size > 0


def test_report_sets_the_papers_accuracies_beside_the_papers_objects_only():
    from aas_gym.experiments.protocols import CLASSIFIERS, RecognitionResult
    from aas_gym.experiments.report import recognition_table

    def results(labels):
        return [RecognitionResult("linear", "single", c, 50.0, list(labels), np.eye(len(labels))) for c in CLASSIFIERS]

    paper = recognition_table(results(["wood_bar", "pla_tube"]))
    assert "KNN sim / paper" in paper and "50.0 / 78.6" in paper  # the paper's KNN, linear, 5-fold
    everyday = recognition_table(results(["mug", "wood_bar"]))
    assert "paper" not in everyday and "78.6" not in everyday
    assert "| linear | single -> single (5-fold) | 50.0 | 50.0 | 50.0 |" in everyday


def test_report_spectra_come_from_the_dataset(reference):
    from aas_gym.experiments.run import dataset_spectra
    from sensors import feature_frequencies_hz

    df = load_dataset(reference)
    curves = dataset_spectra(df, "linear")
    panels = {c[0] for c in curves}
    assert any(p.startswith("material") for p in panels) and any(p.startswith("contact") for p in panels)
    title, label, f, a = next(c for c in curves if c[0].startswith("material") and c[1] == "wood")
    np.testing.assert_array_equal(f, feature_frequencies_hz())  # the whole band, 3-10 kHz
    rows = df[(df.scene == "single") & (df.object == "wood_bar") & (df.excitation == "linear")]
    np.testing.assert_allclose(a, np.mean(np.stack(rows.features), axis=0))
