"""Baselines for ``aas_gym/ContactFormation-v0``: which contact formation holds now, from the
streamed sound or from proprioception alone (scikit-learn classifiers).

Episodes are played with the scripted motion of the env (the reports do not move anything);
every step gives one sample: the streamed features (the 140-d features of the latest complete
excitation period, in dB, plus the level of this step's audio in 24 log-spaced bands, which
reacts within the step), the proprioception (TCP pose and velocity, gripper opening, speed
and motor force) and the true formation. Classifiers are trained on some episodes and tested
on others (never the same episode on both sides), and reported per class.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aas_gym.envs.contact_formation import FORMATIONS

__all__ = ["CLASSIFIERS", "FormationData", "collect", "evaluate", "format_table", "step_band_levels"]

#: Bands of the per-step audio level [Hz].
BAND_EDGES_HZ = np.geomspace(50.0, 20000.0, 25)


@dataclass
class FormationData:
    """One row per env step: ``acoustic`` (features), ``proprio``, ``label`` (index into
    ``FORMATIONS``) and ``episode`` (which episode it came from)."""

    acoustic: np.ndarray
    proprio: np.ndarray
    label: np.ndarray
    episode: np.ndarray


def step_band_levels(audio: np.ndarray, sample_rate_hz: float) -> np.ndarray:
    """Level [dB re 1e-6] of one step's samples in each band of ``BAND_EDGES_HZ``."""
    spectrum = np.abs(np.fft.rfft(audio * np.hanning(audio.size))) ** 2
    f = np.fft.rfftfreq(audio.size, 1.0 / sample_rate_hz)
    idx = np.searchsorted(f, BAND_EDGES_HZ)
    power = np.add.reduceat(spectrum, idx[:-1])[: len(BAND_EDGES_HZ) - 1] / audio.size
    return 10 * np.log10(power + 1e-12) + 120.0


def collect(n_episodes: int, *, seed: int = 0, steps: int = 200, progress: bool = True, **env_kwargs) -> FormationData:
    """Play ``n_episodes`` of ContactFormation-v0 (seeds ``seed``, ``seed + 1``, ...) for
    ``steps`` steps each and gather one row per step."""
    import gymnasium as gym
    from tqdm.auto import tqdm

    import aas_gym  # noqa: F401  (registers the env)

    env = gym.make("aas_gym/ContactFormation-v0", max_episode_steps=steps, disable_env_checker=True,
                   acoustic={"cadence": "stream", "feature_scale": "db"}, **env_kwargs)
    fs = env.unwrapped.excitation.sample_rate_hz
    rows_a, rows_p, labels, episodes = [], [], [], []
    with tqdm(total=n_episodes * steps, unit="step", disable=not progress, desc="contact formations") as bar:
        for e in range(n_episodes):
            env.reset(seed=seed + e)
            for _ in range(steps):
                obs, _, _, truncated, info = env.step(0)
                rows_a.append(np.concatenate([obs["acoustic"], step_band_levels(obs["audio"], fs)]))
                rows_p.append(np.concatenate([obs["tcp"], obs["tcp_velocity"], obs["gripper"]]))
                labels.append(info["formation_index"])
                episodes.append(e)
                bar.update()
                if truncated:
                    break
    env.close()
    return FormationData(np.array(rows_a, np.float32), np.array(rows_p, np.float32), np.array(labels),
                         np.array(episodes))


#: The classifiers :func:`evaluate` offers: random forests of 200 trees, or scikit-learn's
#: histogram gradient boosting (its defaults).
CLASSIFIERS = ("forest", "boosting")


def _classifier(name: str, seed: int):
    from sklearn.ensemble import HistGradientBoostingClassifier, RandomForestClassifier

    if name == "forest":
        return RandomForestClassifier(n_estimators=200, random_state=seed, n_jobs=1)
    if name == "boosting":
        return HistGradientBoostingClassifier(random_state=seed)
    raise ValueError(f"classifier must be one of {CLASSIFIERS}, got {name!r}")


def evaluate(data: FormationData, *, test_fraction: float = 0.3, seed: int = 0, classifier: str = "forest") -> dict:
    """Train each baseline on some episodes and test it on the others.

    Returns ``{baseline: {"accuracy", "balanced_accuracy", "recall": {formation: r},
    "n_test": {formation: n}}}`` for ``sound`` (streamed features), ``proprioception`` and
    ``sound + proprioception``; ``classifier`` one of :data:`CLASSIFIERS` (``seed``)."""
    from sklearn.metrics import balanced_accuracy_score, recall_score
    from sklearn.model_selection import GroupShuffleSplit

    split = GroupShuffleSplit(n_splits=1, test_size=test_fraction, random_state=seed)
    train, test = next(split.split(data.label, data.label, data.episode))
    inputs = {"sound": data.acoustic, "proprioception": data.proprio,
              "sound + proprioception": np.hstack([data.acoustic, data.proprio])}
    labels = list(range(len(FORMATIONS)))
    out = {}
    for name, x in inputs.items():
        clf = _classifier(classifier, seed)
        clf.fit(x[train], data.label[train])
        pred = clf.predict(x[test])
        truth = data.label[test]
        recall = recall_score(truth, pred, labels=labels, average=None, zero_division=0)
        out[name] = {"accuracy": float(np.mean(pred == truth)),
                     "balanced_accuracy": float(balanced_accuracy_score(truth, pred)),
                     "recall": {f: float(r) for f, r in zip(FORMATIONS, recall)},
                     "n_test": {f: int(np.sum(truth == k)) for k, f in enumerate(FORMATIONS)}}
    return out


def format_table(results: dict) -> str:
    """Markdown table: per baseline, the recall of each formation, accuracy and balanced accuracy."""
    n = next(iter(results.values()))["n_test"]
    head = "| baseline | " + " | ".join(f"{f} (n={n[f]})" for f in FORMATIONS) + " | accuracy | balanced |"
    lines = [head, "|---" * (len(FORMATIONS) + 3) + "|"]
    for name, r in results.items():
        cells = " | ".join(f"{100 * r['recall'][f]:.1f} %" for f in FORMATIONS)
        lines.append(f"| {name} | {cells} | {100 * r['accuracy']:.1f} % | {100 * r['balanced_accuracy']:.1f} % |")
    return "\n".join(lines)
