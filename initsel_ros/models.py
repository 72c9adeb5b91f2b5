"""The four logistic-regression models (F, E, H, R) and their plain-text model file.

A model file is JSON (never pickle)::

    {
      "format": "initsel_ros/models", "version": 1,
      "scaling": "resolution_free",
      "feature_names": [... 23 names ...],
      "metadata": {"trained_on": ..., "date": ..., ...},
      "models": {
        "E": {"weights": [23 floats], "bias": float, "threshold": float,
              "mean": [23 floats], "scale": [23 floats], "metrics": {...}},
        ...
      }
    }

A model scores ``sigmoid(w . ((x - mean) / scale) + b)``, where ``x`` are the features of
:mod:`initsel_ros.features` in the file's scaling; it says yes when the probability is at or
above ``threshold``.
"""

from __future__ import annotations

import json
import math
import numbers
import os
import stat
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from initsel_ros.errors import ModelFileError
from initsel_ros.features import FEATURE_NAMES, N_FEATURES, Scaling

METHODS: tuple[str, ...] = ('F', 'E', 'H', 'R')
FILE_FORMAT = 'initsel_ros/models'
FILE_VERSION = 1
PACKAGE = 'initsel_ros'
DEFAULT_MODEL_NAME = 'models.json'
#: A model file larger than this is refused before reading (real ones are well under 1 MiB).
MAX_FILE_BYTES = 16 * 1024 * 1024
#: Deepest JSON nesting a model file may have (real ones nest about 5 levels).
MAX_JSON_DEPTH = 64


def _sigmoid(z: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * z))  # overflow-free logistic


@dataclass(frozen=True)
class LogisticModel:
    """One logistic-regression classifier over standardized features."""

    name: str
    weights: np.ndarray
    bias: float
    threshold: float = 0.5
    mean: np.ndarray = field(default_factory=lambda: np.zeros(N_FEATURES))
    scale: np.ndarray = field(default_factory=lambda: np.ones(N_FEATURES))
    metrics: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        where = f'model {self.name!r}'
        for attr in ('weights', 'mean', 'scale'):
            arr = np.asarray(getattr(self, attr), dtype=np.float64)
            if arr.ndim != 1:
                raise ModelFileError(f'{where}: {attr} must be a flat vector, got shape '
                                     f'{arr.shape}')
            object.__setattr__(self, attr, arr)
            if arr.shape != (N_FEATURES,):
                raise ModelFileError(
                    f'{where}: {attr} must have {N_FEATURES} values, got {arr.size}'
                )
            if not np.all(np.isfinite(arr)):
                raise ModelFileError(f'{where}: {attr} contains NaN or infinity')
        if np.any(self.scale <= 0):
            raise ModelFileError(f'{where}: every scale value must be positive')
        if not math.isfinite(self.bias):
            raise ModelFileError(f'{where}: bias must be finite, got {self.bias}')
        if not 0.0 <= self.threshold <= 1.0:
            raise ModelFileError(f'{where}: threshold must be in [0, 1], got {self.threshold}')

    def decision_function(self, X: np.ndarray) -> np.ndarray:
        """Logits of ``X`` ((N, 23) or (23,) scaled features)."""
        return ((np.asarray(X, dtype=np.float64) - self.mean) / self.scale) @ self.weights + (
            self.bias
        )

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """Probability of 'yes' for each row of ``X`` ((N, 23) -> (N,))."""
        return _sigmoid(self.decision_function(X))

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form for the model file."""
        return {
            'weights': self.weights.tolist(),
            'bias': float(self.bias),
            'threshold': float(self.threshold),
            'mean': self.mean.tolist(),
            'scale': self.scale.tolist(),
            'metrics': self.metrics,
        }

    @classmethod
    def from_dict(cls, name: str, data: Any) -> LogisticModel:
        """Inverse of :meth:`to_dict`; raises ModelFileError on any malformed entry."""
        if not isinstance(data, dict):
            raise ModelFileError(f'model {name!r}: expected a mapping, got {type(data).__name__}')
        missing = [k for k in ('weights', 'bias') if k not in data]
        if missing:
            raise ModelFileError(f'model {name!r}: missing {", ".join(missing)}')
        where = f'model {name!r}'
        metrics = data.get('metrics', {}) or {}
        if not isinstance(metrics, dict):
            raise ModelFileError(f'{where}: "metrics" must be a mapping')
        return cls(
            name=name,
            weights=number_list(data['weights'], f'{where}: weights', N_FEATURES),
            bias=finite_number(data['bias'], f'{where}: bias'),
            threshold=unit_number(data.get('threshold', 0.5), f'{where}: threshold'),
            mean=number_list(data.get('mean', [0.0] * N_FEATURES), f'{where}: mean',
                             N_FEATURES),
            scale=number_list(data.get('scale', [1.0] * N_FEATURES), f'{where}: scale',
                              N_FEATURES),
            metrics=dict(metrics),
        )


def _is_number(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def number_list(value: Any, what: str, length: int) -> np.ndarray:
    """A flat JSON list of ``length`` finite numbers as (length,) float64.

    Raises:
        ModelFileError: nested lists, strings, booleans, NaN/infinity or the wrong length.
    """
    if not isinstance(value, list) or not all(_is_number(v) for v in value):
        raise ModelFileError(f'{what} must be a flat list of {length} numbers')
    if len(value) != length:
        raise ModelFileError(f'{what} must have {length} values, got {len(value)}')
    arr = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(arr)):
        raise ModelFileError(f'{what} contains NaN or infinity')
    return arr


def finite_number(value: Any, what: str) -> float:
    """A finite JSON number as float; raises ModelFileError otherwise."""
    if not _is_number(value) or not math.isfinite(float(value)):
        raise ModelFileError(f'{what} must be a finite number (non-numeric: {value!r:.40})')
    return float(value)


def unit_number(value: Any, what: str) -> float:
    """A JSON number in [0, 1] as float; raises ModelFileError otherwise."""
    if not _is_number(value):
        raise ModelFileError(f'{what} must be a number in [0, 1], got {value!r:.40}')
    v = float(value)
    if not 0.0 <= v <= 1.0:
        raise ModelFileError(f'{what} must be in [0, 1], got {v}')
    return v


@dataclass(frozen=True)
class ModelSet:
    """The F, E, H and R models that score one feature vector together."""

    models: dict[str, LogisticModel]
    scaling: Scaling = Scaling.RESOLUTION_FREE
    feature_names: tuple[str, ...] = FEATURE_NAMES
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, 'scaling', Scaling(self.scaling))
        object.__setattr__(self, 'feature_names', tuple(self.feature_names))
        if self.feature_names != FEATURE_NAMES:
            raise ModelFileError(
                'feature_names do not match the 23 features this version computes '
                f'(first difference at {_first_difference(self.feature_names, FEATURE_NAMES)})'
            )
        missing = [m for m in METHODS if m not in self.models]
        if missing:
            raise ModelFileError(f'missing models: {", ".join(missing)} (need F, E, H and R)')
        names = tuple(self.models)
        W = np.stack([self.models[m].weights / self.models[m].scale for m in names])
        b = np.array([
            (model := self.models[m]).bias - model.weights @ (model.mean / model.scale)
            for m in names
        ])
        # Folding the standardization into one matrix keeps a decision to one mat-vec.
        object.__setattr__(self, '_names', names)
        object.__setattr__(self, '_W', W)
        object.__setattr__(self, '_b', b)

    @property
    def thresholds(self) -> dict[str, float]:
        """Decision threshold of each model, from the file."""
        return {m: self.models[m].threshold for m in self.models}

    def predict_proba(self, x: np.ndarray) -> dict[str, float]:
        """Probabilities of one (23,) feature vector, by model name."""
        z = self._W @ x + self._b  # type: ignore[attr-defined]
        p = 1.0 / (1.0 + np.exp(-np.clip(z, -500.0, 500.0)))
        return dict(zip(self._names, p.tolist(), strict=True))  # type: ignore[attr-defined]

    def predict_proba_batch(self, X: np.ndarray) -> dict[str, np.ndarray]:
        """Probabilities of (N, 23) feature rows, by model name, each (N,)."""
        P = _sigmoid(np.asarray(X, dtype=np.float64) @ self._W.T + self._b)  # type: ignore[attr-defined]
        return {m: P[:, i] for i, m in enumerate(self._names)}  # type: ignore[attr-defined]

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form of the whole file."""
        return {
            'format': FILE_FORMAT,
            'version': FILE_VERSION,
            'scaling': self.scaling.value,
            'feature_names': list(self.feature_names),
            'metadata': self.metadata,
            'models': {name: model.to_dict() for name, model in self.models.items()},
        }

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
        if data.get('version') != FILE_VERSION:
            raise ModelFileError(
                f'unsupported model file version {data.get("version")!r} '
                f'(this build reads {FILE_VERSION})'
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
            models={name: LogisticModel.from_dict(name, m) for name, m in models.items()},
            scaling=scaling,
            feature_names=tuple(names),
            metadata=dict(data.get('metadata', {}) or {}),
        )

    def save(self, path: Path | str) -> None:
        """Write the JSON model file (atomically: temporary file, then rename)."""
        path = Path(path)
        tmp = path.with_name(path.name + '.tmp')
        tmp.write_text(json.dumps(self.to_dict(), indent=2) + '\n')
        os.replace(tmp, path)

    @classmethod
    def load(cls, path: Path | str) -> ModelSet:
        """Read and validate a model file; every problem is a ModelFileError naming it."""
        path = Path(path)
        try:
            data = parse_json_bounded(read_bounded(path))
            return cls.from_dict(data)
        except ModelFileError as exc:
            raise ModelFileError(f'{path}: {exc}') from exc


def read_bounded(path: Path, max_bytes: int = MAX_FILE_BYTES) -> bytes:
    """The bytes of a regular file of at most ``max_bytes``, without ever blocking.

    The file is opened non-blocking (a FIFO then opens at once instead of waiting for a
    writer) and checked with fstat before anything is read.

    Raises:
        ModelFileError: not readable, not a regular file (FIFO, device, directory), too large.
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, 'O_CLOEXEC', 0))
    except OSError as exc:
        raise ModelFileError(f'cannot read model file: {exc.strerror or exc}') from exc
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            kind = ('a directory' if stat.S_ISDIR(info.st_mode) else 'a FIFO'
                    if stat.S_ISFIFO(info.st_mode) else 'a device' if
                    stat.S_ISCHR(info.st_mode) or stat.S_ISBLK(info.st_mode) else 'a socket')
            raise ModelFileError(f'not a regular file ({kind}); a model file is a JSON file')
        if info.st_size > max_bytes:
            raise ModelFileError(
                f'model file is larger than {max_bytes // (1024 * 1024)} MiB '
                f'({info.st_size} bytes); real model files are well under 1 MiB'
            )
        chunks, total = [], 0
        while chunk := os.read(fd, 1 << 20):  # the file may grow after fstat: stay bounded
            chunks.append(chunk)
            total += len(chunk)
            if total > max_bytes:
                raise ModelFileError(f'model file grew larger than {max_bytes} bytes while read')
        return b''.join(chunks)
    except OSError as exc:
        raise ModelFileError(f'cannot read model file: {exc.strerror or exc}') from exc
    finally:
        os.close(fd)


def json_depth(data: bytes) -> int:
    """Deepest nesting of ``[``/``{`` in JSON text, ignoring brackets inside strings.

    Vectorized (no recursion, no per-character Python loop), in 1 MiB chunks so memory stays
    small. Exact for valid JSON; for invalid JSON the parser reports the problem itself.
    """
    # Drop escaped backslashes first, then escaped quotes: what remains of '"' delimits strings.
    text = data.replace(b'\\\\', b'').replace(b'\\"', b'')
    depth, parity, deepest = 0, 0, 0
    step = 1 << 20
    for start in range(0, len(text), step):
        b = np.frombuffer(text, np.uint8, count=min(step, len(text) - start), offset=start)
        in_string = (np.cumsum(b == 34, dtype=np.int64) + parity) & 1
        code = np.zeros(len(b), np.int8)
        code[(b == 91) | (b == 123)] = 1
        code[(b == 93) | (b == 125)] = -1
        code[in_string.astype(bool)] = 0
        level = np.cumsum(code, dtype=np.int64) + depth
        if len(level):
            deepest = max(deepest, int(level.max()))
            depth = int(level[-1])
        parity = int(in_string[-1]) if len(b) else parity
    return deepest


def parse_json_bounded(data: bytes, max_depth: int = MAX_JSON_DEPTH) -> Any:
    """Parse JSON text whose nesting is at most ``max_depth``.

    Raises:
        ModelFileError: binary content, nesting too deep, or invalid JSON.
    """
    try:
        text = data.decode('utf-8')
    except UnicodeDecodeError as exc:
        raise ModelFileError(
            f'not a text model file (binary content at byte {exc.start}); '
            'model files are plain JSON, never pickles'
        ) from exc
    depth = json_depth(data)
    if depth > max_depth:
        raise ModelFileError(f'JSON nested deeper than {max_depth} levels ({depth}); '
                             'not a model file')
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ModelFileError(f'not valid JSON (line {exc.lineno}): {exc.msg}') from exc
    except RecursionError as exc:  # unreachable after the depth check; kept as a guard
        raise ModelFileError('JSON nested too deeply; not a model file') from exc


def _first_difference(a: tuple[str, ...], b: tuple[str, ...]) -> str:
    for i, (x, y) in enumerate(zip(a, b, strict=False)):
        if x != y:
            return f'index {i}: {x!r} vs {y!r}'
    return f'length {len(a)} vs {len(b)}'


def config_dirs() -> list[Path]:
    """Where packaged configuration is looked for, most specific first.

    The ament share directories (``$AMENT_PREFIX_PATH/*/share/initsel_ros/config``), the
    interpreter prefix (``pip install``), then the source tree (editable installs).
    """
    dirs: list[Path] = []
    for prefix in filter(None, os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)):
        dirs.append(Path(prefix) / 'share' / PACKAGE / 'config')
    dirs.append(Path(sys.prefix) / 'share' / PACKAGE / 'config')
    dirs.append(Path(__file__).resolve().parent.parent / 'config')
    return dirs


def find_config_file(name: str) -> Path:
    """The first existing ``config/<name>`` among :func:`config_dirs`.

    Raises:
        ModelFileError: when no directory holds it (the message lists where it looked).
    """
    candidates = [d / name for d in config_dirs()]
    for path in candidates:
        if path.is_file():
            return path
    raise ModelFileError(
        f'{name} not found; looked in: ' + ', '.join(str(p.parent) for p in candidates)
    )


def default_model_path() -> Path:
    """Path of the packaged default model file ``config/models.json``."""
    return find_config_file(DEFAULT_MODEL_NAME)
