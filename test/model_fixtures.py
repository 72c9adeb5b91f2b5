"""Model sets for tests that must not depend on the shipped model file."""

from __future__ import annotations

import math

import numpy as np

from initsel_ros.features import N_FEATURES
from initsel_ros.models import METHODS, LogisticModel, ModelSet


def constant_models(**probabilities: float) -> ModelSet:
    """Models that ignore the features and always answer ``probabilities`` (test double)."""
    models = {}
    for m in METHODS:
        p = probabilities.get(m, 0.01)
        models[m] = LogisticModel(m, np.zeros(N_FEATURES), math.log(p / (1 - p)), 0.5)
    return ModelSet(models)
