"""The paper's evaluation protocols on a generated dataset.

- Object recognition: KNN (k = 3, Euclidean), SVM (RBF) and MLP (learning rate 1e-3, 1000
  iterations, random_state 1), scikit-learn defaults otherwise; stratified 5-fold CV within
  single-object scenes, and training on all single-object data, testing on multi-object data.
- Grasp position: KNN regressor (k = 3), 3-fold CV, RMSE per object and excitation.

One deviation, for the simulator's sake: features are log-amplitudes, standardized. The
simulated amplitudes span many decades and are far from unit scale (a sensor gain is
arbitrary), which an MLP with default settings does not train on. The log/standardize step is
part of each pipeline, fitted on training folds only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sklearn.base import clone
from sklearn.metrics import accuracy_score, confusion_matrix
from sklearn.model_selection import KFold, StratifiedKFold, cross_val_predict
from sklearn.neighbors import KNeighborsClassifier, KNeighborsRegressor
from sklearn.neural_network import MLPClassifier
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import FunctionTransformer, StandardScaler
from sklearn.svm import SVC

#: Paper Table II (%): excitation -> protocol -> (KNN, SVM, MLP).
PAPER_RECOGNITION = {
    "impulse": {"single": (75.7, 69.3, 81.4), "transfer": (47.1, 55.7, 51.4)},
    "linear": {"single": (78.6, 77.1, 80.0), "transfer": (67.1, 60.0, 72.9)},
    "exponential": {"single": (67.1, 66.4, 82.9), "transfer": (70.0, 70.0, 84.3)},
}
#: Best grasp-position RMSE in the paper: wood bar, linear sweep.
PAPER_BEST_POSITION_RMSE_MM = 0.9
CLASSIFIERS = ("KNN", "SVM", "MLP")


def _log_amplitude(x: np.ndarray) -> np.ndarray:
    return np.log10(np.abs(x) + 1e-15)


def make_classifier(name: str):
    """The paper's classifier ``name`` behind log-amplitude standardization."""
    models = {
        "KNN": KNeighborsClassifier(n_neighbors=3, metric="euclidean"),
        "SVM": SVC(kernel="rbf"),
        "MLP": MLPClassifier(learning_rate_init=1e-3, max_iter=1000, random_state=1),
    }
    if name not in models:
        raise ValueError(f"unknown classifier {name!r}; known: {CLASSIFIERS}")
    return on_log_features(models[name])


def on_log_features(model):
    """``model`` behind the log-amplitude and standardization step (fitted on training data)."""
    return make_pipeline(FunctionTransformer(_log_amplitude), StandardScaler(), model)


@dataclass
class RecognitionResult:
    excitation: str
    protocol: str  # "single" (5-fold CV), "transfer" (single -> multi) or "geometry" (held-out shapes)
    classifier: str
    accuracy: float
    labels: list[str]
    confusion: np.ndarray


def recognition(features: np.ndarray, labels: np.ndarray, *, excitation: str, seed: int = 0,
                test_features: np.ndarray | None = None, test_labels: np.ndarray | None = None
                ) -> list[RecognitionResult]:
    """Accuracy and confusion matrix of each classifier.

    Without test data: stratified 5-fold CV on ``features``. With test data: train on all of
    ``features``, test on ``test_features`` (the single -> multi-object transfer).
    """
    names = sorted(set(labels))
    out = []
    for clf_name in CLASSIFIERS:
        model = make_classifier(clf_name)
        if test_features is None:
            n_splits = min(5, int(min(np.unique(labels, return_counts=True)[1])))
            if n_splits < 2:
                raise ValueError("need at least two samples per object for cross-validation")
            cv = StratifiedKFold(n_splits=n_splits, shuffle=True, random_state=seed)
            pred = cross_val_predict(model, features, labels, cv=cv)
            truth, protocol = labels, "single"
        else:
            pred = clone(model).fit(features, labels).predict(test_features)
            truth, protocol = test_labels, "transfer"
        out.append(RecognitionResult(excitation, protocol, clf_name, 100.0 * accuracy_score(truth, pred),
                                     names, confusion_matrix(truth, pred, labels=names)))
    return out


def held_out_geometry(features: np.ndarray, materials: np.ndarray, shapes: np.ndarray, *, excitation: str,
                      seed: int = 0) -> list[RecognitionResult]:
    """Material recognition on shapes never seen in training: each shape whose material also
    comes in another shape is held out in turn, the classifier trained on every other shape
    and tested on it; accuracy and confusion (over materials) of the pooled predictions.
    ``seed`` is unused (the split is deterministic); kept for the protocols' common call."""
    del seed
    shapes = np.asarray(shapes)
    materials = np.asarray(materials)
    testable = [s for s in sorted(set(shapes))
                if len(set(shapes[materials == materials[shapes == s][0]])) > 1]
    if not testable:
        raise ValueError("held-out geometry needs a material that comes in at least two shapes")
    names = sorted(set(materials))
    out = []
    for clf_name in CLASSIFIERS:
        truth, pred = [], []
        for shape in testable:
            test = shapes == shape
            model = clone(make_classifier(clf_name)).fit(features[~test], materials[~test])
            truth.append(materials[test])
            pred.append(model.predict(features[test]))
        truth, pred = np.concatenate(truth), np.concatenate(pred)
        out.append(RecognitionResult(excitation, "geometry", clf_name, 100.0 * accuracy_score(truth, pred),
                                     names, confusion_matrix(truth, pred, labels=names)))
    return out


@dataclass
class PositionResult:
    object_name: str
    excitation: str
    rmse_mm: float
    true_mm: np.ndarray
    predicted_mm: np.ndarray


def grasp_position(features: np.ndarray, positions_m: np.ndarray, *, object_name: str, excitation: str,
                   seed: int = 0) -> PositionResult:
    """KNN regression (k = 3) of the grasp position, 3-fold CV; RMSE in millimetres."""
    model = on_log_features(KNeighborsRegressor(n_neighbors=3))
    cv = KFold(n_splits=3, shuffle=True, random_state=seed)
    pred = cross_val_predict(model, features, positions_m, cv=cv)
    rmse_mm = 1e3 * float(np.sqrt(np.mean((pred - positions_m) ** 2)))
    return PositionResult(object_name, excitation, rmse_mm, 1e3 * positions_m, 1e3 * pred)
