"""The paper's experiments in simulation: dataset generation (sharded, resumable, local
processes or Ray), the recognition and grasp-position protocols, and the report.

Exported lazily (PEP 562), like ``aas_gym`` itself: ``aas --help`` imports this package to
list its commands and should not pay for the sensor stack (~0.4 s, ``-X importtime``).
"""

from aas_gym.experiments.config import DatasetConfig, Task

__all__ = ["DatasetConfig", "Task", "generate_dataset", "load_dataset"]


def __getattr__(name: str):
    if name in ("generate_dataset", "load_dataset"):
        from aas_gym.experiments import generate

        return getattr(generate, name)
    raise AttributeError(f"module 'aas_gym.experiments' has no attribute {name!r}")
