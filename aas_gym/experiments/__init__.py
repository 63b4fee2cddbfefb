"""The paper's experiments in simulation: dataset generation (sharded, resumable, local
processes or Ray), the recognition and grasp-position protocols, and the report."""

from aas_gym.experiments.config import DatasetConfig, Task
from aas_gym.experiments.generate import generate_dataset, load_dataset

__all__ = ["DatasetConfig", "Task", "generate_dataset", "load_dataset"]
