"""The four models (F, E, H, R) and their plain-text model file.

A model file is JSON (never pickle)::

    {
      "format": "initsel_ros/models", "version": 2,
      "scaling": "resolution_free",
      "feature_names": [... the 23 paper feature names ...],
      "metadata": {"trained_on": ..., "date": ..., ...},
      "models": {
        "E": {"kind": "logistic", "features": [names], "weights": [floats], "bias": float,
              "threshold": float, "mean": [floats], "scale": [floats], "metrics": {...}},
        "F": {"kind": "trees", "features": [names], "bias": float, "threshold": float,
              "trees": [...], "metrics": {...}},
        ...
      }
    }

Each model declares its inputs by name (``features``): any of the 23 paper features of
:mod:`initsel_ros.features` (in the file's scaling) and of its extra features
(``EXTRA_FEATURE_NAMES``: disparity percentiles, grid occupancy and entropy, affine and
homography residuals). ``kind`` defaults to ``logistic`` and ``features`` to the 23 paper
features, so version-1 files (23-feature logistic models) load unchanged.

* ``logistic``: ``sigmoid(w . ((x - mean) / scale) + b)``;
* ``trees``: a gradient-boosted tree ensemble, ``sigmoid(bias + sum of leaf values)``
  (:mod:`initsel_ros.trees`, evaluated in numpy).

A file may also hold a ``referee``: models of another file (a distilled file's teacher) that
decide where the file's own model of the same name is unsure, its logit within ``band_logit``
of the threshold the two share::

      "referee": {"band_logit": {"R": 2.0}, "models": {"R": {... as above ...}},
                  "metadata": {...}}

The referee's inputs are computed only for those pairs (:meth:`ModelSet.predict_points`).

A model says yes when its probability is at or above ``threshold``. The set reads one input
vector (:attr:`ModelSet.input_names`): the 23 paper features, then the extra features that some
model needs; :meth:`ModelSet.input_vector` computes it, the extra features only when needed
(:meth:`ModelSet.input_values` and :meth:`ModelSet.predict_values`: the same on lists of floats,
the per-frame path). Non-finite extra features (e.g. no homography fit) count as 0, as in
training.
"""

from __future__ import annotations

import json
import logging
import math
import uuid
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from initsel_ros.config_files import config_dirs, find_config_file
from initsel_ros.errors import GeometryError, ModelFileError
from initsel_ros.features import (
    ALL_FEATURE_NAMES,
    CAMERA_FEATURE_NAMES,
    EXTRA_FEATURE_NAMES,
    FEATURE_NAMES,
    N_FEATURES,
    Camera,
    InputPlan,
    MeasuredPair,
    Scaling,
    as_camera,
    input_plan,
    model_inputs,
)
from initsel_ros.modelio import (
    MAX_FILE_BYTES,
    MAX_JSON_DEPTH,
    finite_number,
    metrics_mapping,
    name_list,
    number_list,
    parse_json_bounded,
    read_bounded,
    unit_number,
)
from initsel_ros.output import atomic_text
from initsel_ros.trees import (
    TABLE_DEPTH,
    FlatTrees,
    LeafTable,
    LogitModel,
    TreeEnsembleModel,
    sigmoid,
)
from initsel_ros.trees import prepare as prepare_tree_inputs

METHODS: tuple[str, ...] = ('F', 'E', 'H', 'R')
FILE_FORMAT = 'initsel_ros/models'
FILE_VERSION = 2
#: Versions this build reads (1: 23-feature logistic models only).
READABLE_VERSIONS = (1, 2)
PACKAGE = 'initsel_ros'
DEFAULT_MODEL_NAME = 'models.json'
KINDS = ('logistic', 'trees')

LOG = logging.getLogger(__name__)

#: Input plans a model set keeps (by image size and camera) before it starts afresh.
MAX_PLANS = 16


def _probability(z: float) -> float:
    """The logistic function of one logit (0 where exp(-z) would overflow; NaN stays NaN)."""
    if z > -700.0:
        return 1.0 / (1.0 + math.exp(-z))
    return 0.0 if z <= -700.0 else z


@dataclass(frozen=True)
class LogisticModel(LogitModel):
    """One logistic-regression classifier over standardized features.

    ``weights``, ``mean`` and ``scale`` follow ``features`` (default: the 23 paper features);
    ``mean`` and ``scale`` default to 0 and 1.
    """

    name: str
    weights: np.ndarray
    bias: float
    threshold: float = 0.5
    mean: np.ndarray | None = None
    scale: np.ndarray | None = None
    metrics: dict[str, Any] = field(default_factory=dict)
    features: tuple[str, ...] = FEATURE_NAMES
    kind: str = field(default='logistic', init=False)

    def __post_init__(self) -> None:
        where = f'model {self.name!r}'
        object.__setattr__(self, 'features', tuple(self.features))
        n = len(self.features)
        if self.mean is None:
            object.__setattr__(self, 'mean', np.zeros(n))
        if self.scale is None:
            object.__setattr__(self, 'scale', np.ones(n))
        for attr in ('weights', 'mean', 'scale'):
            arr = np.asarray(getattr(self, attr), dtype=np.float64)
            if arr.ndim != 1:
                raise ModelFileError(
                    f'{where}: {attr} must be a flat vector, got shape {arr.shape}'
                )
            object.__setattr__(self, attr, arr)
            if arr.shape != (n,):
                raise ModelFileError(f'{where}: {attr} must have {n} values, got {arr.size}')
            if not np.all(np.isfinite(arr)):
                raise ModelFileError(f'{where}: {attr} contains NaN or infinity')
        if np.any(self.scale <= 0):
            raise ModelFileError(f'{where}: every scale value must be positive')
        self.check_bias_threshold()

    def decision_function(self, X: np.ndarray) -> np.ndarray:
        """Logits of ``X`` ((N, D) or (D,) features in ``features`` order)."""
        return ((np.asarray(X, dtype=np.float64) - self.mean) / self.scale) @ self.weights + (
            self.bias
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form for the model file."""
        return {
            'kind': 'logistic',
            'features': list(self.features),
            'weights': self.weights.tolist(),
            'bias': float(self.bias),
            'threshold': float(self.threshold),
            'mean': self.mean.tolist(),
            'scale': self.scale.tolist(),
            'metrics': self.metrics,
        }

    @classmethod
    def from_dict(
        cls, name: str, data: Any, features: tuple[str, ...] = FEATURE_NAMES
    ) -> LogisticModel:
        """Inverse of :meth:`to_dict`; raises ModelFileError on any malformed entry."""
        if not isinstance(data, dict):
            raise ModelFileError(f'model {name!r}: expected a mapping, got {type(data).__name__}')
        missing = [k for k in ('weights', 'bias') if k not in data]
        if missing:
            raise ModelFileError(f'model {name!r}: missing {", ".join(missing)}')
        where = f'model {name!r}'
        n = len(features)
        return cls(
            name=name,
            weights=number_list(data['weights'], f'{where}: weights', n),
            bias=finite_number(data['bias'], f'{where}: bias'),
            threshold=unit_number(data.get('threshold', 0.5), f'{where}: threshold'),
            mean=number_list(data.get('mean', [0.0] * n), f'{where}: mean', n),
            scale=number_list(data.get('scale', [1.0] * n), f'{where}: scale', n),
            metrics=metrics_mapping(data, where),
            features=features,
        )


Model = LogisticModel | TreeEnsembleModel


def model_from_dict(name: str, data: Any) -> Model:
    """One model entry of the file, by its ``kind``; raises ModelFileError."""
    if not isinstance(data, dict):
        raise ModelFileError(f'model {name!r}: expected a mapping, got {type(data).__name__}')
    kind = data.get('kind', 'logistic')
    if kind not in KINDS:
        raise ModelFileError(f'model {name!r}: unknown kind {kind!r} (known: {", ".join(KINDS)})')
    features = name_list(
        data.get('features', list(FEATURE_NAMES)), f'model {name!r}: features', ALL_FEATURE_NAMES
    )
    if kind == 'trees':
        return TreeEnsembleModel.from_dict(name, data, features)
    return LogisticModel.from_dict(name, data, features)


def logit(p: float) -> float:
    """The logit of a probability (+-inf at 1 and 0, NaN stays NaN)."""
    if 0.0 < p < 1.0:
        return math.log(p / (1.0 - p))
    return math.inf if p >= 1.0 else -math.inf if p <= 0.0 else p


@dataclass(frozen=True)
class Referee:
    """Models that decide where a set's own model of the same name is unsure.

    Attributes:
        models: the referee's models (a subset of F, E, H, R; usually the teacher a file was
            distilled from), with the set's thresholds.
        band_logit: per model name, the half-width of the band around the threshold's logit
            in which the set's own model defers to the referee's.
    """

    models: ModelSet
    band_logit: dict[str, float]

    def __post_init__(self) -> None:
        unknown = sorted(set(self.band_logit).difference(self.models.models))
        if unknown:
            raise ModelFileError(f'referee: band_logit names models it does not hold: {unknown}')
        for name, band in self.band_logit.items():
            if not (math.isfinite(band) and band > 0.0):
                raise ModelFileError(f'referee: band_logit[{name!r}] must be > 0, got {band!r}')

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (the file's ``referee`` section)."""
        return {
            'band_logit': dict(self.band_logit),
            'metadata': self.models.metadata,
            'models': {name: model.to_dict() for name, model in self.models.models.items()},
        }


@dataclass(frozen=True)
class ModelSet:
    """The F, E, H and R models that score one input vector together.

    ``referee`` (optional) decides for a model where that model is unsure (:class:`Referee`);
    ``partial`` marks a referee's own set, which may hold a subset of the four models.
    """

    models: dict[str, Model]
    scaling: Scaling = Scaling.RESOLUTION_FREE
    feature_names: tuple[str, ...] = FEATURE_NAMES
    metadata: dict[str, Any] = field(default_factory=dict)
    referee: Referee | None = None
    partial: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, 'scaling', Scaling(self.scaling))
        object.__setattr__(self, 'feature_names', tuple(self.feature_names))
        if self.feature_names != FEATURE_NAMES:
            raise ModelFileError(
                'feature_names do not match the 23 features this version computes '
                f'(first difference at {_first_difference(self.feature_names, FEATURE_NAMES)})'
            )
        unknown = [m for m in self.models if m not in METHODS]
        if unknown:
            raise ModelFileError(
                f'unknown models: {", ".join(repr(m)[:40] for m in unknown[:5])} '
                '(a model file holds exactly F, E, H and R)'
            )
        missing = [m for m in METHODS if m not in self.models]
        if self.partial and self.models:
            missing = []
        if missing:
            raise ModelFileError(f'missing models: {", ".join(missing)} (need F, E, H and R)')
        used = {f for model in self.models.values() for f in model.features}
        extra = tuple(n for n in EXTRA_FEATURE_NAMES if n in used)
        inputs = FEATURE_NAMES + extra
        column = {n: i for i, n in enumerate(inputs)}
        names = tuple(self.models)
        logistic = [i for i, m in enumerate(names) if self.models[m].kind == 'logistic']
        trees = [i for i, m in enumerate(names) if self.models[m].kind == 'trees']
        # Logistic models: the standardization folded into one (L, D) matrix (one mat-vec).
        W = np.zeros((len(logistic), len(inputs)))
        b = np.zeros(len(logistic))
        for row, i in enumerate(logistic):
            model = self.models[names[i]]
            W[row, [column[f] for f in model.features]] = model.weights / model.scale
            b[row] = model.bias - model.weights @ (model.mean / model.scale)
        # Tree models: every tree of every model in one flat set (one vectorized walk).
        all_trees, columns, owner, tree_bias = [], [], [], []
        for k, i in enumerate(trees):
            model = self.models[names[i]]
            cols = np.array([column[f] for f in model.features], dtype=np.int64)
            all_trees += list(model.trees)
            columns += [cols] * len(model.trees)
            owner += [k] * len(model.trees)
            tree_bias.append(model.bias)
        object.__setattr__(self, '_names', names)
        object.__setattr__(self, '_inputs', inputs)
        object.__setattr__(self, '_extra', extra)
        object.__setattr__(self, '_logistic', np.array(logistic, dtype=np.int64))
        object.__setattr__(self, '_W', W)
        object.__setattr__(self, '_b', b)
        object.__setattr__(self, '_trees', np.array(trees, dtype=np.int64))
        object.__setattr__(self, '_flat', FlatTrees.build(all_trees, columns) if trees else None)
        object.__setattr__(self, '_owner', np.array(owner, dtype=np.int64))
        object.__setattr__(self, '_tree_bias', np.array(tree_bias))
        # One input vector: trees of depth <= 3 (the shipped files) as leaf tables, one step.
        shallow = bool(trees) and all(self.models[names[i]].depth <= TABLE_DEPTH for i in trees)
        starts = np.flatnonzero(np.diff(owner, prepend=-1)) if shallow else ()
        object.__setattr__(
            self, '_table', LeafTable.build(all_trees, columns, starts) if shallow else None
        )
        object.__setattr__(self, '_tree_slots', list(zip(trees, tree_bias, strict=True)))
        # Every model a shallow tree ensemble, in self._names order: the biases folded into the
        # leaves, one table look-up gives the logits (None otherwise).
        all_in_table = shallow and trees == list(range(len(names)))
        object.__setattr__(
            self,
            '_biased_table',
            self._table.with_group_offsets(tree_bias) if all_in_table else None,  # type: ignore[attr-defined]
        )
        object.__setattr__(self, '_logistic_slots', logistic)
        object.__setattr__(self, '_sanitize', bool(extra) or bool(trees))
        object.__setattr__(self, '_plans', {})  # InputPlan by image size and camera
        object.__setattr__(self, '_bounds', {})  # the referee's band by threshold values
        # The direction histogram has a pass of its own: made only when a model reads it.
        object.__setattr__(self, '_directions', bool(used & set(FEATURE_NAMES[15:])))
        if self.referee is not None:
            self._check_referee(self.referee)

    def _check_referee(self, referee: Referee) -> None:
        """A referee must read the same scaling and share the thresholds it decides on."""
        if self.partial:
            raise ModelFileError('a referee cannot have a referee of its own')
        if referee.models.scaling is not self.scaling:
            raise ModelFileError(
                f"referee: scaling {referee.models.scaling.value!r} differs from the file's "
                f'{self.scaling.value!r}'
            )
        for name in referee.band_logit:
            own, theirs = self.models[name].threshold, referee.models.models[name].threshold
            if not math.isclose(own, theirs, rel_tol=1e-9, abs_tol=1e-12):
                raise ModelFileError(
                    f"referee: model {name} has threshold {theirs!r}, the file's {own!r}: a "
                    'referee decides at the threshold of the model it stands in for'
                )

    @property
    def thresholds(self) -> dict[str, float]:
        """Decision threshold of each model, from the file."""
        return {m: self.models[m].threshold for m in self.models}

    @property
    def input_names(self) -> tuple[str, ...]:
        """Names of the input vector: the 23 paper features, then the needed extra ones."""
        return self._inputs  # type: ignore[attr-defined]

    @property
    def extra_names(self) -> tuple[str, ...]:
        """Extra features some model reads (``EXTRA_FEATURE_NAMES`` order); () for none."""
        return self._extra  # type: ignore[attr-defined]

    @property
    def kinds(self) -> dict[str, str]:
        """Kind of each model: 'logistic' or 'trees'."""
        return {m: model.kind for m, model in self.models.items()}

    def input_plan(self, width: int, height: int, camera: Camera | None = None) -> InputPlan:
        """The constants of this set's input vector at an image size and camera (fx, fy, cx,
        cy, pixels: for the features of ``CAMERA_FEATURE_NAMES``), cached."""
        plans: dict[tuple[int, int, Camera | None], InputPlan] = self._plans  # type: ignore[attr-defined]
        if camera is not None and type(camera) is not tuple:
            camera = as_camera(camera)
        plan = plans.get((width, height, camera))
        if plan is None:
            if len(plans) >= MAX_PLANS:  # a camera whose K keeps changing: no unbounded cache
                plans.clear()
            if camera is None and set(self._extra) & set(CAMERA_FEATURE_NAMES):  # type: ignore[attr-defined]
                LOG.warning(
                    'a model reads %s but no camera was given: it reads NaN (as 0)',
                    ', '.join(set(self._extra) & set(CAMERA_FEATURE_NAMES)),  # type: ignore[attr-defined]
                )
            plan = plans[width, height, camera] = input_plan(
                width,
                height,
                self.scaling,
                self._extra,  # type: ignore[attr-defined]
                self._directions,  # type: ignore[attr-defined]
                camera,
            )
        return plan

    def input_values(
        self, p0: np.ndarray, p1: np.ndarray, width: int, height: int, camera: Camera | None = None
    ) -> tuple[list[float], float]:
        """The input vector of one correspondence set as floats, and its mean disparity.

        Args:
            p0: (N, 2) reference pixels.
            p1: (N, 2) current pixels.
            width: image width, pixels.
            height: image height, pixels.
            camera: (fx, fy, cx, cy), pixels (see :meth:`input_plan`).

        Returns:
            (values in :attr:`input_names` order, NaN where an extra feature is undefined;
            mean disparity, pixels). The extra features are computed only when a model reads
            them (:func:`features.model_inputs`).
        """
        return model_inputs(p0, p1, self.input_plan(width, height, camera))

    def input_vector(
        self, p0: np.ndarray, p1: np.ndarray, width: int, height: int, camera: Camera | None = None
    ) -> np.ndarray:
        """:meth:`input_values` as a (len(input_names),) float64 array."""
        return np.array(self.input_values(p0, p1, width, height, camera)[0], dtype=np.float64)

    def predict_points(
        self,
        p0: np.ndarray,
        p1: np.ndarray,
        width: int,
        height: int,
        thresholds: Mapping[str, float] | None = None,
        camera: Camera | None = None,
    ) -> tuple[dict[str, float], float, tuple[str, ...]]:
        """Probabilities of one correspondence set, the referee deciding where it should.

        The set's own inputs and models first; then, for each model the referee covers whose
        logit lies within its band of the threshold's (``thresholds``, default the file's),
        the referee's probability replaces the model's (its inputs computed for those pairs
        only, from the same pass over the points where the fit rows allow:
        :class:`features.MeasuredPair`). ``thresholds`` may name some models only (the
        policy's overrides): the others keep the file's. ``camera``: (fx, fy, cx, cy), pixels
        (see :meth:`input_plan`).

        Returns:
            (probabilities by model name, mean disparity in pixels, the names of the models
            the referee decided).
        """
        plan = self.input_plan(width, height, camera)
        pair = MeasuredPair(p0, p1, plan)
        values, mean_disparity = pair.inputs(plan)
        probs = self.predict_values(values)
        referee = self.referee
        if referee is None:
            return probs, mean_disparity, ()
        unsure = [
            name
            for name, low, high in self._referee_bounds(thresholds)
            if low < probs[name] < high
        ]
        if not unsure:
            return probs, mean_disparity, ()
        judge = referee.models  # its inputs from the same pass where the fit rows allow
        verdict = judge.predict_values(pair.inputs(judge.input_plan(width, height, camera))[0])
        probs = {**probs, **{name: verdict[name] for name in unsure}}
        return probs, mean_disparity, tuple(unsure)

    def _referee_bounds(
        self, thresholds: Mapping[str, float] | None
    ) -> list[tuple[str, float, float]]:
        """Per refereed model, the probabilities between which its logit lies within the
        band of the threshold's (``thresholds`` over the file's): the band as probabilities,
        made once per threshold value, so the per-frame check is two comparisons."""
        referee = self.referee
        assert referee is not None
        bands = referee.band_logit
        models = self.models
        thresholds = thresholds or {}
        cuts = tuple([thresholds[n] if n in thresholds else models[n].threshold for n in bands])
        cache: dict[tuple[float, ...], list[tuple[str, float, float]]] = self._bounds  # type: ignore[attr-defined]
        bounds = cache.get(cuts)
        if bounds is None:
            bounds = cache[cuts] = [
                (name, _probability(logit(cut) - band), _probability(logit(cut) + band))
                for (name, band), cut in zip(bands.items(), cuts, strict=True)
            ]
        return bounds

    @property
    def referee_input_names(self) -> tuple[str, ...]:
        """Names of the referee's input vector; () without a referee."""
        return self.referee.models.input_names if self.referee is not None else ()

    def review_logits(
        self,
        logits: dict[str, np.ndarray],
        X_referee: np.ndarray | None,
        thresholds: Mapping[str, float] | None = None,
    ) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """:meth:`predict_points` on rows: the referee's logits (of ``X_referee``, rows in
        :attr:`referee_input_names` order) replace ``logits`` where they are in its band.

        Returns:
            (the logits by model, an (N,) bool array: the referee decided a model of the row).
        """
        n = len(logits[METHODS[0]]) if logits else 0
        referred = np.zeros(n, dtype=bool)
        if self.referee is None:
            return logits, referred
        if X_referee is None:
            raise GeometryError('this model file has a referee: its inputs are needed too')
        thresholds = {**self.thresholds, **(thresholds or {})}
        verdict = self.referee.models.logits_batch(X_referee)
        out = dict(logits)
        for name, band in self.referee.band_logit.items():
            unsure = np.abs(logits[name] - logit(thresholds[name])) < band
            out[name] = np.where(unsure, verdict[name], logits[name])
            referred |= unsure
        return out, referred

    def _logits(self, X: np.ndarray) -> np.ndarray:
        """(N, models) logits of prepared rows, in ``self.models`` order."""
        out = np.empty((len(X), len(self._names)))  # type: ignore[attr-defined]
        if len(self._logistic):  # type: ignore[attr-defined]
            out[:, self._logistic] = X @ self._W.T + self._b  # type: ignore[attr-defined]
        if self._flat is not None:  # type: ignore[attr-defined]
            leaves = self._flat.leaf_values_batch(prepare_tree_inputs(X))  # type: ignore[attr-defined]
            owner = self._owner  # type: ignore[attr-defined]
            onehot = np.zeros((len(owner), len(self._trees)))  # type: ignore[attr-defined]
            onehot[np.arange(len(owner)), owner] = 1.0
            out[:, self._trees] = leaves @ onehot + self._tree_bias  # type: ignore[attr-defined]
        return out

    def _check_inputs(self, X: np.ndarray) -> np.ndarray:
        """Inputs as float64 of the right width, non-finite values replaced by 0."""
        X = np.asarray(X, dtype=np.float64)
        n = len(self._inputs)  # type: ignore[attr-defined]
        if X.shape[-1:] != (n,):
            raise GeometryError(
                f'the models read {n} inputs ({N_FEATURES} paper features'
                f'{" + " + ", ".join(self._extra) if self._extra else ""}), '  # type: ignore[attr-defined]
                f'got shape {X.shape}; see ModelSet.input_vector'
            )
        if self._extra or self._flat is not None:  # type: ignore[attr-defined]
            X = np.where(np.isfinite(X), X, 0.0)  # missing extra features count as 0
        return X

    def predict_proba(self, x: np.ndarray) -> dict[str, float]:
        """Probabilities of one input vector (``input_names`` order), by model name."""
        return self._probabilities(self._check_inputs(x).tolist())

    def predict_values(self, values: Sequence[float]) -> dict[str, float]:
        """:meth:`predict_proba` of an input vector given as floats (:meth:`input_values`):
        the per-frame path, with no array conversion before the models."""
        if len(values) != len(self._inputs):  # type: ignore[attr-defined]
            self._check_inputs(np.asarray(values, dtype=np.float64))  # raises, saying why
        if self._sanitize and not math.isfinite(sum(values)):  # type: ignore[attr-defined]
            values = [v if math.isfinite(v) else 0.0 for v in values]
        return self._probabilities(values)

    def _probabilities(self, values: Sequence[float]) -> dict[str, float]:
        """Probabilities of finite inputs (non-finite ones already 0 where they count as 0)."""
        if self._biased_table is not None:  # type: ignore[attr-defined]
            logits = self._biased_table.sums(np.array(values, dtype=np.float32)).tolist()  # type: ignore[attr-defined]
            return dict(zip(self._names, map(_probability, logits), strict=True))  # type: ignore[attr-defined]
        logits = [0.0] * len(self._names)  # type: ignore[attr-defined]
        if self._table is not None:  # type: ignore[attr-defined]
            sums = self._table.sums(np.array(values, dtype=np.float32)).tolist()  # type: ignore[attr-defined]
            for (i, bias), total in zip(self._tree_slots, sums, strict=True):  # type: ignore[attr-defined]
                logits[i] = bias + total
        elif self._flat is not None:  # type: ignore[attr-defined]
            x32 = np.array(values, dtype=np.float32).astype(np.float64)
            leaves = self._flat.leaf_values(x32)  # type: ignore[attr-defined]
            sums = np.bincount(self._owner, weights=leaves, minlength=len(self._tree_slots))  # type: ignore[attr-defined]
            for (i, bias), total in zip(self._tree_slots, sums.tolist(), strict=True):  # type: ignore[attr-defined]
                logits[i] = bias + total
        if self._logistic_slots:  # type: ignore[attr-defined]
            z = self._W @ np.array(values, dtype=np.float64) + self._b  # type: ignore[attr-defined]
            for i, zi in zip(self._logistic_slots, z.tolist(), strict=True):  # type: ignore[attr-defined]
                logits[i] = zi
        return dict(zip(self._names, map(_probability, logits), strict=True))  # type: ignore[attr-defined]

    def logits_batch(self, X: np.ndarray) -> dict[str, np.ndarray]:
        """Logits (the probabilities before the sigmoid) of (N, D) input rows, by model, (N,)."""
        X = self._check_inputs(X).reshape(-1, len(self._inputs))  # type: ignore[attr-defined]
        Z = self._logits(X)
        return {m: Z[:, i] for i, m in enumerate(self._names)}  # type: ignore[attr-defined]

    def predict_proba_batch(self, X: np.ndarray) -> dict[str, np.ndarray]:
        """Probabilities of (N, D) input rows, by model name, each (N,)."""
        X = self._check_inputs(X).reshape(-1, len(self._inputs))  # type: ignore[attr-defined]
        P = sigmoid(self._logits(X))
        return {m: P[:, i] for i, m in enumerate(self._names)}  # type: ignore[attr-defined]

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form of the whole file."""
        data = {
            'format': FILE_FORMAT,
            'version': FILE_VERSION,
            'scaling': self.scaling.value,
            'feature_names': list(self.feature_names),
            'metadata': self.metadata,
            'models': {name: model.to_dict() for name, model in self.models.items()},
        }
        if self.referee is not None:
            data['referee'] = self.referee.to_dict()
        return data

    @classmethod
    def from_dict(cls, data: Any) -> ModelSet:
        """Validate and build from plain data; raises ModelFileError."""
        if not isinstance(data, dict):
            raise ModelFileError('the model file must hold a JSON object')
        if data.get('format') != FILE_FORMAT:
            raise ModelFileError(
                f'not an initsel_ros model file (format {data.get("format")!r}, '
                f'expected {FILE_FORMAT!r})'
            )
        if data.get('version') not in READABLE_VERSIONS:
            raise ModelFileError(
                f'unsupported model file version {data.get("version")!r} '
                f'(this build reads {", ".join(map(str, READABLE_VERSIONS))})'
            )
        try:
            scaling = Scaling(data.get('scaling', Scaling.RESOLUTION_FREE.value))
        except ValueError as exc:
            raise ModelFileError(f'unknown scaling {data.get("scaling")!r}') from exc
        models = data.get('models')
        if not isinstance(models, dict):
            raise ModelFileError('"models" must map model names to their coefficients')
        names = data.get('feature_names', list(FEATURE_NAMES))
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise ModelFileError('"feature_names" must be a list of names')
        if not isinstance(data.get('metadata', {}) or {}, dict):
            raise ModelFileError('"metadata" must be a mapping')
        return cls(
            models={name: model_from_dict(name, m) for name, m in models.items()},
            scaling=scaling,
            feature_names=tuple(names),
            metadata=dict(data.get('metadata', {}) or {}),
            referee=_referee_from_dict(data.get('referee'), scaling, tuple(names)),
        )

    def save(self, path: Path | str) -> None:
        """Write the JSON model file (atomically: temporary file, then rename).

        Raises:
            OutputError: ``path`` is a folder.
        """
        with atomic_text(path) as handle:
            handle.write(dumps(self.to_dict()))

    @classmethod
    def load(cls, path: Path | str) -> ModelSet:
        """Read and validate a model file; every problem is a ModelFileError naming it.

        The file is opened non-blocking and must be a regular file of at most
        ``MAX_FILE_BYTES`` whose JSON nests at most ``MAX_JSON_DEPTH`` levels.
        """
        path = Path(path)
        try:
            data = parse_json_bounded(read_bounded(path))
            return cls.from_dict(data)
        except ModelFileError as exc:
            raise ModelFileError(f'{path}: {exc}') from exc


def _referee_from_dict(
    data: Any, scaling: Scaling, feature_names: tuple[str, ...]
) -> Referee | None:
    """The file's ``referee`` section (None when absent); raises ModelFileError."""
    if data is None:
        return None
    if not isinstance(data, dict):
        raise ModelFileError('"referee" must be a mapping')
    models, bands = data.get('models'), data.get('band_logit')
    if not isinstance(models, dict) or not models:
        raise ModelFileError('referee: "models" must map model names to their coefficients')
    unknown = [m for m in models if m not in METHODS]
    if unknown:
        raise ModelFileError(f'referee: unknown models {unknown[:5]!r}')
    if not isinstance(bands, dict) or not bands:
        raise ModelFileError('referee: "band_logit" must map model names to numbers')
    metadata = data.get('metadata', {}) or {}
    if not isinstance(metadata, dict):
        raise ModelFileError('referee: "metadata" must be a mapping')
    try:
        judge = ModelSet(
            models={name: model_from_dict(name, m) for name, m in models.items()},
            scaling=scaling,
            feature_names=feature_names,
            metadata=dict(metadata),
            partial=True,
        )
    except ModelFileError as exc:
        raise ModelFileError(f'referee: {exc}') from exc
    band = {str(k): finite_number(v, f'referee: band_logit[{k!r}]') for k, v in bands.items()}
    return Referee(judge, band)


def dumps(data: Any) -> str:
    """JSON text, indented, with every flat list of numbers on one line (trees stay short)."""
    token = uuid.uuid4().hex
    inline: list[str] = []

    def collapse(value: Any) -> Any:
        if isinstance(value, dict):
            return {k: collapse(v) for k, v in value.items()}
        if isinstance(value, list):
            if value and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in value
            ):
                inline.append(json.dumps(value))
                return f'{token}:{len(inline) - 1}'
            return [collapse(v) for v in value]
        return value

    text = json.dumps(collapse(data), indent=2)
    for i, body in enumerate(inline):
        text = text.replace(f'"{token}:{i}"', body, 1)
    return text + '\n'


def _first_difference(a: tuple[str, ...], b: tuple[str, ...]) -> str:
    for i, (x, y) in enumerate(zip(a, b, strict=False)):
        if x != y:
            return f'index {i}: {x!r} vs {y!r}'
    return f'length {len(a)} vs {len(b)}'


def default_model_path() -> Path:
    """Path of the packaged default model file ``config/models.json``."""
    return find_config_file(DEFAULT_MODEL_NAME)


__all__ = [
    'DEFAULT_MODEL_NAME',
    'FILE_FORMAT',
    'FILE_VERSION',
    'MAX_FILE_BYTES',
    'MAX_JSON_DEPTH',
    'METHODS',
    'READABLE_VERSIONS',
    'LogisticModel',
    'Model',
    'ModelSet',
    'Referee',
    'TreeEnsembleModel',
    'config_dirs',
    'default_model_path',
    'dumps',
    'find_config_file',
    'logit',
    'model_from_dict',
]
