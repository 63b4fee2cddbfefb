"""Generated datasets load through the clients users reach for (pandas, pyarrow's dataset API,
Hugging Face datasets), and a shard that is not this dataset's is never trusted: another
configuration's shard or flipped bytes are recomputed on resume and an error on load."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from aas_gym.experiments.config import DatasetConfig
from aas_gym.experiments.generate import MANIFEST, ShardError, generate_dataset, load_dataset, shard_path

TINY = dict(objects=("aluminium_bar", "wood_bar"), excitations=("linear",), scenes=("single",), single_grasps=2,
            shard_size=2, seed=3)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("ds")
    generate_dataset(DatasetConfig(**TINY), out, workers=1, progress=False)
    return out


def test_pandas_pyarrow_and_hugging_face_read_the_folder(dataset):
    import pandas as pd
    import pyarrow.dataset as ds

    ours = load_dataset(dataset)
    assert (dataset / MANIFEST).exists() and not (dataset / "dataset.json").exists()
    # the card (README.md) is not Parquet: folder readers skip it as the generate docstring says
    by_pandas = pd.read_parquet(dataset, ignore_prefixes=[".", "_", "README"])
    assert len(by_pandas) == len(ours) == 4
    by_arrow = ds.dataset(sorted(dataset.glob("shard-*.parquet")), format="parquet").to_table()
    assert by_arrow.num_rows == 4
    hf = pytest.importorskip("datasets")
    by_hf = hf.load_dataset("parquet", data_dir=str(dataset), split="train", cache_dir=str(dataset.parent / "hf"))
    assert by_hf.num_rows == 4
    got = np.array(by_hf.sort("task_id")["features"], dtype=np.float32)
    np.testing.assert_array_equal(got, np.stack(ours.sort_values("task_id").features))


def _copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def test_a_shard_of_another_seed_is_recomputed_on_resume_and_refused_on_load(dataset, tmp_path):
    other = tmp_path / "other"
    generate_dataset(DatasetConfig(**dict(TINY, seed=4)), other, workers=1, progress=False)
    mixed = _copy(dataset, tmp_path / "mixed")
    shutil.copyfile(shard_path(other, 0), shard_path(mixed, 0))
    with pytest.raises(ShardError, match="shard-00000.parquet belongs to another configuration"):
        load_dataset(mixed)
    generate_dataset(DatasetConfig(**TINY), mixed, workers=1, progress=False)
    assert shard_path(mixed, 0).read_bytes() == shard_path(dataset, 0).read_bytes()


def test_flipped_bytes_in_a_shard_are_caught(dataset, tmp_path):
    bad = _copy(dataset, tmp_path / "bad")
    data = bytearray(shard_path(bad, 1).read_bytes())
    middle = len(data) // 2
    data[middle:middle + 64] = bytes(b ^ 0xFF for b in data[middle:middle + 64])
    shard_path(bad, 1).write_bytes(bytes(data))
    with pytest.raises(ShardError, match="shard-00001.parquet"):
        load_dataset(bad)
    generate_dataset(DatasetConfig(**TINY), bad, workers=1, progress=False)
    assert load_dataset(bad).equals(load_dataset(dataset))


def test_a_dataset_with_the_old_manifest_name_still_loads_and_resumes(dataset, tmp_path):
    old = _copy(dataset, tmp_path / "old")
    (old / MANIFEST).rename(old / "dataset.json")
    assert len(load_dataset(old)) == 4
    generate_dataset(DatasetConfig(**TINY), old, workers=1, progress=False)
    assert (old / MANIFEST).exists() and not (old / "dataset.json").exists()
