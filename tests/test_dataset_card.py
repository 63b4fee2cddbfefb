"""``aas generate`` writes a dataset card (``README.md``, Hugging Face's format) that parses,
names every column of the Parquet shards with its dtype, and lets ``datasets.load_dataset``
read the folder by itself."""

from __future__ import annotations

import numpy as np
import pyarrow.parquet as pq
import pytest
import yaml

from aas_gym.cli import main
from aas_gym.experiments.card import COLUMNS
from aas_gym.experiments.generate import load_dataset

ARGS = ["--objects", "aluminium_bar,wood_bar", "--excitations", "linear", "--scenes", "single", "--single-grasps",
        "1", "--shard-size", "1", "--seed", "5", "--workers", "1"]


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("carded") / "data"
    assert main(["generate", str(out), *ARGS]) == 0
    return out


def _front_matter(text: str) -> dict:
    assert text.startswith("---\n")
    head, _, body = text[4:].partition("\n---\n")
    assert body.strip(), "the card has no body"
    return yaml.safe_load(head)


def test_card_front_matter_lists_every_column_with_its_dtype(dataset):
    card = _front_matter((dataset / "README.md").read_text())
    assert card["license"] == "apache-2.0" and card["task_categories"] and "robotics" in card["tags"]
    files = card["configs"][0]["data_files"]
    assert files == [{"split": "train", "path": "shard-*.parquet"}]
    schema = pq.read_schema(next(dataset.glob("shard-*.parquet")))
    features = {f["name"]: f for f in card["dataset_info"]["features"]}
    assert list(features) == schema.names
    assert features["features"] == {"name": "features", "sequence": "float32", "length": 140}
    assert features["position_m"]["dtype"] == "float64" and features["object"]["dtype"] == "string"
    assert card["dataset_info"]["splits"][0]["num_examples"] == len(load_dataset(dataset)) == 2


def test_card_body_explains_every_column_and_how_it_was_made(dataset):
    text = (dataset / "README.md").read_text()
    body = text.split("\n---\n", 1)[1]
    for name in pq.read_schema(next(dataset.glob("shard-*.parquet"))).names:
        assert f"| `{name}` |" in body and name in COLUMNS
    assert f"`aas generate {dataset} " in body and "--seed 5" in body
    assert "Seed 5" in body and "## Licence" in body
    assert not list(dataset.glob(".*.tmp")) and not list(dataset.glob("*.tmp"))  # written atomically


def test_hugging_face_datasets_loads_the_folder_through_its_card(dataset, tmp_path):
    hf = pytest.importorskip("datasets")
    ds = hf.load_dataset(str(dataset), split="train", cache_dir=str(tmp_path / "hf"))
    assert ds.num_rows == 2 and ds.column_names == pq.read_schema(next(dataset.glob("shard-*.parquet"))).names
    spec = ds.features["features"]  # the fixed length and dtype the card declares
    assert spec.length == 140 and spec.feature.dtype == "float32"
    ours = load_dataset(dataset).sort_values("task_id")
    got = np.array(ds.sort("task_id")["features"], dtype=np.float32)
    np.testing.assert_array_equal(got, np.stack(ours.features))
