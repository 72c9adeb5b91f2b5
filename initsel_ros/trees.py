"""Gradient-boosted decision trees, evaluated in numpy (no scikit-learn at inference).

A :class:`TreeEnsembleModel` scores ``sigmoid(bias + sum over trees of leaf(x))``. Its entry in
the model file (plain JSON)::

    {"kind": "trees", "features": [names], "bias": float, "threshold": float,
     "trees": [{"feature": [int], "split": [float], "left": [int], "right": [int],
                "value": [float]}, ...],
     "metrics": {...}}

Node ``i`` of a tree is a leaf when ``feature[i] == -1`` (then ``left[i] == right[i] == -1``
and ``value[i]`` is its contribution to the logit); otherwise the row goes to ``left[i]`` when
``x[feature[i]] <= split[i]`` and to ``right[i]`` else. Children always have larger indices
than their parent, so every tree is finite and acyclic; node 0 is the root. As in scikit-learn,
features are rounded to float32 before the comparisons; non-finite inputs count as 0 (the value
training imputes).

Evaluation is vectorized over all trees at once: the nodes of every tree live in flat arrays
where a leaf points to itself, so ``depth`` steps of fancy indexing reach every leaf
(:class:`FlatTrees`, any depth, many rows at once). For one input vector and trees at most
:data:`TABLE_DEPTH` deep (the shipped files), :class:`LeafTable` does it in one step: every
comparison of every tree at once, then one table look-up per tree.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from initsel_ros.errors import ModelFileError
from initsel_ros.modelio import (
    finite_number,
    int_list,
    metrics_mapping,
    number_list,
    unit_number,
)

#: Bounds that keep a hostile file from costing much memory or time.
MAX_TREES = 2000
MAX_DEPTH = 16
MAX_NODES_PER_TREE = 4095
TREE_KEYS = ('feature', 'split', 'left', 'right', 'value')


def sigmoid(z: np.ndarray) -> np.ndarray:
    """The logistic function, overflow-free (models.py uses it too)."""
    return 0.5 * (1.0 + np.tanh(0.5 * z))  # overflow-free logistic


class LogitModel:
    """What both model kinds share: a logit per row of features (:meth:`decision_function`),
    whose sigmoid is the probability of 'yes', and a ``bias`` and ``threshold`` to check."""

    name: str
    bias: float
    threshold: float

    def decision_function(self, X: np.ndarray) -> np.ndarray:
        """Logits of ``X`` ((N, D) or (D,) features in the model's order)."""
        raise NotImplementedError

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """Probability of 'yes' for each row of ``X`` ((N, D) -> (N,))."""
        return sigmoid(self.decision_function(X))

    def check_bias_threshold(self) -> None:
        """Raises ModelFileError: a non-finite bias, or a threshold outside [0, 1]."""
        where = f'model {self.name!r}'
        if not math.isfinite(self.bias):
            raise ModelFileError(f'{where}: bias must be finite, got {self.bias}')
        if not 0.0 <= self.threshold <= 1.0:
            raise ModelFileError(f'{where}: threshold must be in [0, 1], got {self.threshold}')


@dataclass(frozen=True)
class Tree:
    """One regression tree in file form (see module docstring)."""

    feature: np.ndarray  # (K,) int64, -1 for leaves
    split: np.ndarray  # (K,) float64
    left: np.ndarray  # (K,) int64, -1 for leaves
    right: np.ndarray  # (K,) int64, -1 for leaves
    value: np.ndarray  # (K,) float64, logit contribution of leaves (0 at inner nodes)

    def to_dict(self) -> dict[str, list[Any]]:
        """Plain data for the model file."""
        return {k: getattr(self, k).tolist() for k in TREE_KEYS}

    @classmethod
    def from_dict(cls, data: Any, n_features: int, where: str) -> Tree:
        """Validate one tree of the file; raises ModelFileError."""
        if not isinstance(data, dict) or sorted(data) != sorted(TREE_KEYS):
            raise ModelFileError(
                f'{where}: a tree must map exactly {", ".join(TREE_KEYS)} to lists'
            )
        raw = data['feature']
        k = len(raw) if isinstance(raw, list) else 0
        if not 1 <= k <= MAX_NODES_PER_TREE:
            raise ModelFileError(f'{where}: a tree needs 1 to {MAX_NODES_PER_TREE} nodes')
        return cls(
            feature=int_list(raw, f'{where}: feature', k, -1, n_features - 1),
            split=number_list(data['split'], f'{where}: split', k),
            left=int_list(data['left'], f'{where}: left', k, -1, k - 1),
            right=int_list(data['right'], f'{where}: right', k, -1, k - 1),
            value=number_list(data['value'], f'{where}: value', k),
        )

    def check(self, where: str) -> None:
        """Structure: leaves have no children, inner nodes two later ones."""
        leaf = self.feature < 0
        nodes = np.arange(len(self.feature))
        if np.any(leaf & ((self.left != -1) | (self.right != -1))):
            raise ModelFileError(f'{where}: a leaf (feature -1) must have left = right = -1')
        inner = ~leaf
        if np.any(inner & ((self.left <= nodes) | (self.right <= nodes))):
            raise ModelFileError(f'{where}: children must come after their parent')

    @property
    def depth(self) -> int:
        """Longest root-to-leaf path from node 0, in edges (MAX_DEPTH + 1 when deeper)."""
        frontier = np.zeros(1, dtype=np.int64)
        for depth in range(MAX_DEPTH + 2):
            inner = frontier[self.feature[frontier] >= 0]
            if not len(inner):
                return depth
            frontier = np.unique(np.concatenate((self.left[inner], self.right[inner])))
        return MAX_DEPTH + 1


@dataclass(frozen=True)
class FlatTrees:
    """Many trees in flat arrays with self-looping leaves, for vectorized evaluation.

    ``feature`` indexes the input vector; a leaf has feature 0 and split +inf, and both of its
    children are itself, so extra steps keep a row on its leaf. ``child[2 i]`` and
    ``child[2 i + 1]`` are node i's left and right child.
    """

    feature: np.ndarray  # (K,) int64
    split: np.ndarray  # (K,) float64
    child: np.ndarray  # (2 K,) int64
    value: np.ndarray  # (K,) float64
    roots: np.ndarray  # (T,) int64
    depth: int

    @classmethod
    def build(cls, trees: Sequence[Tree], columns: Sequence[np.ndarray]) -> FlatTrees:
        """Flatten ``trees``; ``columns[i][j]`` is the input column of tree i's feature j."""
        feats, splits, kids, values, roots = [], [], [], [], []
        offset = 0
        depth = 0
        for tree, cols in zip(trees, columns, strict=True):
            k = len(tree.feature)
            leaf = tree.feature < 0
            own = np.arange(k) + offset
            feats.append(np.where(leaf, 0, cols[np.maximum(tree.feature, 0)]))
            splits.append(np.where(leaf, np.inf, tree.split))
            kids.append(
                np.column_stack(
                    (
                        np.where(leaf, own, tree.left + offset),
                        np.where(leaf, own, tree.right + offset),
                    )
                ).ravel()
            )
            values.append(np.where(leaf, tree.value, 0.0))
            roots.append(offset)
            depth = max(depth, tree.depth)
            offset += k
        return cls(
            np.concatenate(feats).astype(np.int64),
            np.concatenate(splits),
            np.concatenate(kids).astype(np.int64),
            np.concatenate(values),
            np.asarray(roots, dtype=np.int64),
            depth,
        )

    def leaf_values(self, x: np.ndarray) -> np.ndarray:
        """(T,) leaf value of each tree for one prepared input vector (see :func:`prepare`)."""
        node = self.roots
        feature, split, child = self.feature, self.split, self.child
        for _ in range(self.depth):
            node = child[2 * node + (x[feature[node]] > split[node])]
        return self.value[node]

    def leaf_values_batch(self, X: np.ndarray) -> np.ndarray:
        """(N, T) leaf values for prepared input rows ``X`` (N, D)."""
        node = np.broadcast_to(self.roots, (len(X), len(self.roots)))
        rows = np.arange(len(X))[:, None]
        for _ in range(self.depth):
            node = self.child[2 * node + (X[rows, self.feature[node]] > self.split[node])]
        return self.value[node]


#: Trees at most this deep can be scored by :class:`LeafTable`.
TABLE_DEPTH = 3
_SLOTS = 8  # comparisons per tree in a LeafTable: the 7 inner nodes of a full depth-3 tree + 1
_CODES = 128  # leaf-table entries per tree: one per pattern of the 7 comparisons


def float32_splits(split: np.ndarray) -> np.ndarray:
    """The largest float32 at or below each split, so that for float32 x,
    ``x > float32_splits(s)`` (in float32) is exactly ``x > s`` (in float64)."""
    split = np.asarray(split, dtype=np.float64)
    out = split.astype(np.float32)
    above = out.astype(np.float64) > split
    out[above] = np.nextafter(out[above], np.float32(-np.inf))
    return out


@dataclass(frozen=True)
class LeafTable:
    """Trees at most :data:`TABLE_DEPTH` deep, scored on one input vector in one step.

    Each tree becomes a full depth-3 tree in heap order (node k's children are 2k + 1 and
    2k + 2; a leaf above depth 3 is padded with comparisons that always go left, copying its
    value to every leaf below it) with 8 comparison slots: the 7 inner nodes and one that is
    always false. All slots of all trees compare at once, ``np.packbits`` turns each tree's 8
    results into one byte, and that byte, the pattern of the tree's comparisons, looks up its
    leaf value in the tree's 128-entry row of :attr:`by_pattern` (the pattern -> leaf map
    :data:`_PATTERN_LEAF` applied once, when the table is made). A call touches one entry of
    each row. Comparisons are in float32 against :func:`float32_splits`, so the result equals
    scikit-learn's (float32 input, float64 split) and :class:`FlatTrees`'.
    """

    feature: np.ndarray  # (T * 8,) intp input column of each slot
    split: np.ndarray  # (T * 8,) float32, +inf in unused slots
    leaves: np.ndarray  # (T * 8,) float64 leaf values of each tree, left to right
    starts: np.ndarray  # (G,) intp first tree of each group (np.add.reduceat)
    by_pattern: np.ndarray = field(init=False)  # (T * 128,) leaf value of each tree and pattern
    row: np.ndarray = field(init=False)  # (T,) intp, 128 * tree index

    def __post_init__(self) -> None:
        per_tree = self.leaves.reshape(-1, _LEAVES)
        object.__setattr__(self, 'by_pattern', per_tree[:, _PATTERN_LEAF].ravel())
        object.__setattr__(self, 'row', np.arange(per_tree.shape[0], dtype=np.intp) * _CODES)

    @classmethod
    def build(
        cls, trees: Sequence[Tree], columns: Sequence[np.ndarray], starts: Sequence[int]
    ) -> LeafTable:
        """Tables for ``trees`` (each at most TABLE_DEPTH deep); ``columns[i][j]`` is the input
        column of tree i's feature j; ``starts`` the first tree of each group, ascending."""
        n = len(trees)
        feature = np.zeros((n, _SLOTS), dtype=np.intp)
        split = np.full((n, _SLOTS), np.inf)
        leaves = np.zeros((n, _LEAVES))
        for t, (tree, cols) in enumerate(zip(trees, columns, strict=True)):
            if tree.depth > TABLE_DEPTH:
                raise ValueError(f'tree {t} is {tree.depth} deep; a LeafTable takes at most 3')
            stack = [(0, 0, 0)]  # (node, heap slot, depth)
            while stack:
                node, slot, depth = stack.pop()
                if depth == TABLE_DEPTH:
                    leaves[t, slot - _LEAVES + 1] = tree.value[node]
                    continue
                if tree.feature[node] >= 0:
                    feature[t, slot] = cols[tree.feature[node]]
                    split[t, slot] = tree.split[node]
                    kids = (tree.left[node], tree.right[node])
                else:  # a leaf above the last level: both sides lead to it (slot stays +inf)
                    kids = (node, node)
                stack += [(kids[0], 2 * slot + 1, depth + 1), (kids[1], 2 * slot + 2, depth + 1)]
        return cls(
            feature.ravel(),
            float32_splits(split.ravel()),
            leaves.ravel(),
            np.asarray(starts, dtype=np.intp),
        )

    def with_group_offsets(self, offsets: Sequence[float]) -> LeafTable:
        """The same trees with ``offsets[g]`` added to every leaf of group g's first tree, so
        that :meth:`sums` includes it (e.g. each model's bias: no addition per call)."""
        leaves = self.leaves.reshape(-1, _LEAVES).copy()
        leaves[self.starts] += np.asarray(offsets, dtype=np.float64)[:, None]
        return LeafTable(self.feature, self.split, leaves.ravel(), self.starts)

    def sums(self, x32: np.ndarray) -> np.ndarray:
        """(G,) sum of the leaf values of each group's trees for one float32 input vector
        (finite; see :func:`prepare` for what the trees expect)."""
        pattern = _packbits(x32.take(self.feature) > self.split, bitorder='little')
        return np.add.reduceat(self.by_pattern.take(pattern + self.row), self.starts)


#: np.packbits without its dispatch through ``__array_function__`` (its inputs here are
#: always plain arrays).
_packbits = getattr(np.packbits, '_implementation', np.packbits)


def _pattern_leaf() -> np.ndarray:
    """(128,) the leaf (0-7, left to right) that each pattern of the 7 comparisons of a full
    depth-3 tree in heap order leads to (bit k: slot k's comparison says 'go right')."""
    patterns = np.arange(_CODES)
    slot = np.zeros(_CODES, dtype=np.int64)
    for _ in range(TABLE_DEPTH):
        slot = 2 * slot + 1 + ((patterns >> slot) & 1)
    return (slot - (_LEAVES - 1)).astype(np.int64)


_LEAVES = 2**TABLE_DEPTH
_PATTERN_LEAF = _pattern_leaf()


def prepare(X: np.ndarray) -> np.ndarray:
    """Inputs as the trees compare them: non-finite -> 0, then rounded to float32."""
    X = np.asarray(X, dtype=np.float64)
    return np.where(np.isfinite(X), X, 0.0).astype(np.float32).astype(np.float64)


@dataclass(frozen=True)
class TreeEnsembleModel(LogitModel):
    """A boosted tree ensemble over the named features (logit = bias + sum of leaves)."""

    name: str
    features: tuple[str, ...]
    trees: tuple[Tree, ...]
    bias: float
    threshold: float = 0.5
    metrics: dict[str, Any] = field(default_factory=dict)
    kind: str = field(default='trees', init=False)

    def __post_init__(self) -> None:
        where = f'model {self.name!r}'
        object.__setattr__(self, 'features', tuple(self.features))
        object.__setattr__(self, 'trees', tuple(self.trees))
        if not 1 <= len(self.trees) <= MAX_TREES:
            raise ModelFileError(f'{where}: needs 1 to {MAX_TREES} trees, got {len(self.trees)}')
        for i, tree in enumerate(self.trees):
            if np.any(tree.feature >= len(self.features)):
                raise ModelFileError(f'{where}: tree {i} reads a feature beyond its list')
            tree.check(f'{where}: tree {i}')
            if tree.depth > MAX_DEPTH:
                raise ModelFileError(f'{where}: tree {i} is deeper than {MAX_DEPTH}')
        self.check_bias_threshold()
        own = np.arange(len(self.features))
        flat = FlatTrees.build(self.trees, [own] * len(self.trees))
        object.__setattr__(self, '_flat', flat)

    @property
    def depth(self) -> int:
        """Deepest tree, in edges."""
        return self._flat.depth  # type: ignore[attr-defined]

    def decision_function(self, X: np.ndarray) -> np.ndarray:
        """Logits of rows ``X`` ((N, D) or (D,), columns in ``features`` order)."""
        X = np.asarray(X, dtype=np.float64)
        flat: FlatTrees = self._flat  # type: ignore[attr-defined]
        if X.ndim == 1:
            return np.asarray(self.bias + flat.leaf_values(prepare(X)).sum())
        return self.bias + flat.leaf_values_batch(prepare(X)).sum(axis=1)

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form for the model file."""
        return {
            'kind': 'trees',
            'features': list(self.features),
            'bias': float(self.bias),
            'threshold': float(self.threshold),
            'trees': [t.to_dict() for t in self.trees],
            'metrics': self.metrics,
        }

    @classmethod
    def from_dict(
        cls, name: str, data: dict[str, Any], features: tuple[str, ...]
    ) -> TreeEnsembleModel:
        """Validate a ``"kind": "trees"`` entry (``features`` already checked)."""
        where = f'model {name!r}'
        trees = data.get('trees')
        if not isinstance(trees, list) or not 1 <= len(trees) <= MAX_TREES:
            raise ModelFileError(f'{where}: "trees" must be a list of 1 to {MAX_TREES} trees')
        if 'bias' not in data:
            raise ModelFileError(f'{where}: missing bias')
        return cls(
            name=name,
            features=features,
            trees=tuple(
                Tree.from_dict(t, len(features), f'{where}: tree {i}') for i, t in enumerate(trees)
            ),
            bias=finite_number(data['bias'], f'{where}: bias'),
            threshold=unit_number(data.get('threshold', 0.5), f'{where}: threshold'),
            metrics=metrics_mapping(data, where),
        )


__all__ = [
    'MAX_DEPTH',
    'MAX_NODES_PER_TREE',
    'MAX_TREES',
    'TABLE_DEPTH',
    'FlatTrees',
    'LeafTable',
    'LogitModel',
    'Tree',
    'TreeEnsembleModel',
    'float32_splits',
    'prepare',
    'sigmoid',
]
