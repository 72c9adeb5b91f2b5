"""A small DBoW2 vocabulary of ORB words, in the text format ORB-SLAM3 loads.

ORB-SLAM3 will not start without a vocabulary, and its original ``ORBvoc.txt`` is not
available from the package registries. Its monocular initializer matches features by image
grid, not through the vocabulary (the vocabulary serves relocalization, loop closing and
keyframe matching after initialization), so a small vocabulary trained here from ORB
descriptors of the project's own rendered frames serves the seed-map comparison. It is a
substitute: tracking after initialization is not judged with it.

The tree is built as DBoW2 builds one: hierarchical k-medians on 256-bit descriptors
(k-means++ seeding with Hamming distances, bitwise-majority centres), ``k`` branches and
``levels`` levels; each leaf is a word weighted by its inverse document frequency
``log(N / n_i)`` over the training images.

The text format: the first line is ``k L scoring weighting`` with DBoW2's enum values (here
``0 0``: L1-norm scoring, TF-IDF weighting); then one line per node except the
root, in node-id order: ``parent is_leaf d_0 ... d_31 weight``, with the 32 descriptor bytes
as decimal integers and weight 0 for inner nodes.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

#: DBoW2's enum values written in the header: ScoringType L1_NORM, WeightingType TF_IDF.
L1_NORM = 0
TF_IDF = 0
#: ORB descriptor length, bytes.
DESCRIPTOR_BYTES = 32


@dataclass
class Vocabulary:
    """A vocabulary tree: node arrays indexed by node id (0 is the root).

    Attributes:
        k: branching factor.
        levels: depth.
        parent: (N,) parent id of each node (-1 for the root).
        descriptor: (N, 32) uint8 node centres (zeros for the root).
        leaf: (N,) bool, the node is a word.
        weight: (N,) float64 IDF weight of words (0 elsewhere).
    """

    k: int
    levels: int
    parent: np.ndarray
    descriptor: np.ndarray
    leaf: np.ndarray
    weight: np.ndarray

    @property
    def n_words(self) -> int:
        """Number of words (leaves)."""
        return int(self.leaf.sum())

    def to_text(self) -> str:
        """The DBoW2 text format (no trailing newline: ORB-SLAM3's reader turns one into a
        node)."""
        lines = [f'{self.k} {self.levels} {L1_NORM} {TF_IDF}']
        for i in range(1, len(self.parent)):
            desc = ' '.join(str(int(b)) for b in self.descriptor[i])
            lines.append(f'{self.parent[i]} {int(self.leaf[i])} {desc} {self.weight[i]:.6f}')
        return '\n'.join(lines)

    def save(self, path: Path | str) -> None:
        """Write :meth:`to_text` to ``path``."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(self.to_text())

    @classmethod
    def load(cls, path: Path | str) -> Vocabulary:
        """Read a DBoW2 text vocabulary.

        Raises:
            ValueError: the header or a node line is malformed.
        """
        lines = Path(path).read_text().splitlines()
        head = lines[0].split() if lines else []
        if len(head) != 4:
            raise ValueError(f'{path}: not a DBoW2 text vocabulary (header {lines[:1]})')
        k, levels = int(head[0]), int(head[1])
        rows = [line.split() for line in lines[1:] if line.strip()]
        if any(len(r) != DESCRIPTOR_BYTES + 3 for r in rows):
            raise ValueError(f'{path}: a node line does not have {DESCRIPTOR_BYTES + 3} fields')
        n = len(rows) + 1
        parent = np.full(n, -1, dtype=np.int64)
        descriptor = np.zeros((n, DESCRIPTOR_BYTES), dtype=np.uint8)
        leaf = np.zeros(n, dtype=bool)
        weight = np.zeros(n)
        for i, r in enumerate(rows, start=1):
            parent[i], leaf[i] = int(r[0]), r[1] == '1'
            descriptor[i] = np.array([int(v) for v in r[2 : 2 + DESCRIPTOR_BYTES]], np.uint8)
            weight[i] = float(r[-1])
        return cls(k, levels, parent, descriptor, leaf, weight)

    def word_of(self, descriptors: np.ndarray) -> np.ndarray:
        """(M, 32) uint8 descriptors -> (M,) node id of the word each descends to."""
        children: dict[int, np.ndarray] = {}
        for node in np.unique(self.parent[1:]):
            children[int(node)] = np.flatnonzero(self.parent == node)
        bits = _bits(descriptors)
        node = np.zeros(len(descriptors), dtype=np.int64)
        for _ in range(self.levels):
            for parent in np.unique(node):
                kids = children.get(int(parent))
                if kids is None:
                    continue
                sel = node == parent
                d = _hamming(bits[sel], _bits(self.descriptor[kids]))
                node[sel] = kids[np.argmin(d, axis=1)]
        return node


def _bits(descriptors: np.ndarray) -> np.ndarray:
    """(M, 32) uint8 -> (M, 256) float32 bits."""
    return np.unpackbits(np.asarray(descriptors, dtype=np.uint8), axis=1).astype(np.float32)


def _hamming(a_bits: np.ndarray, b_bits: np.ndarray) -> np.ndarray:
    """Hamming distances between (M, 256) and (C, 256) bit arrays: (M, C) float32."""
    return a_bits.sum(1)[:, None] + b_bits.sum(1)[None, :] - 2.0 * (a_bits @ b_bits.T)


def _kmedians(bits: np.ndarray, k: int, rng: np.random.Generator, iters: int = 10) -> np.ndarray:
    """Cluster labels (M,) of bit vectors: k-means++ seeds, majority-bit centres."""
    m = len(bits)
    centres = [int(rng.integers(m))]
    d = _hamming(bits, bits[centres])[:, 0]
    for _ in range(1, k):
        p = d**2
        if p.sum() <= 0:
            break
        centres.append(int(rng.choice(m, p=p / p.sum())))
        d = np.minimum(d, _hamming(bits, bits[centres[-1:]])[:, 0])
    c_bits = bits[centres]
    labels = np.argmin(_hamming(bits, c_bits), axis=1)
    for _ in range(iters):
        c_bits = np.stack(
            [
                (bits[labels == j].mean(0) > 0.5).astype(np.float32)
                if np.any(labels == j)
                else c_bits[j]
                for j in range(len(c_bits))
            ]
        )
        new = np.argmin(_hamming(bits, c_bits), axis=1)
        if np.array_equal(new, labels):
            break
        labels = new
    return labels


def orb_descriptors(gray: np.ndarray, n_features: int = 1000) -> np.ndarray:
    """ORB descriptors of one grey image ((M, 32) uint8, ORB-SLAM's pyramid: 8 levels x1.2)."""
    orb = cv2.ORB_create(nfeatures=n_features, scaleFactor=1.2, nlevels=8, fastThreshold=7)
    _, desc = orb.detectAndCompute(gray, None)
    return np.zeros((0, DESCRIPTOR_BYTES), np.uint8) if desc is None else desc


def train_vocabulary(
    images: Iterable[np.ndarray], k: int = 10, levels: int = 3, seed: int = 0
) -> Vocabulary:
    """Train a ``k``-ary, ``levels``-deep vocabulary from grey images (one document each).

    Raises:
        ValueError: bad ``k``/``levels`` (DBoW2 reads 2..20 and 1..10) or no descriptors.
    """
    if not (2 <= k <= 20 and 1 <= levels <= 10):
        raise ValueError(f'k={k}, levels={levels}: DBoW2 reads k in 2..20, L in 1..10')
    per_image = [orb_descriptors(g) for g in images]
    per_image = [d for d in per_image if len(d)]
    if not per_image:
        raise ValueError('no ORB descriptors in the training images')
    desc = np.concatenate(per_image)
    doc = np.concatenate([np.full(len(d), i) for i, d in enumerate(per_image)])
    bits = _bits(desc)
    rng = np.random.default_rng(seed)
    parent, centre, leaf = [-1], [np.zeros(DESCRIPTOR_BYTES, np.uint8)], [False]
    members: list[np.ndarray] = [np.arange(len(desc))]  # descriptors under each node
    frontier = [(0, 0)]  # (node id, level)
    while frontier:
        node, level = frontier.pop(0)
        idx = members[node]
        if len(idx) > k:
            labels = _kmedians(bits[idx], k, rng)
            groups = [idx[labels == j] for j in range(labels.max() + 1)]
        else:
            groups = [idx[j : j + 1] for j in range(len(idx))]
        groups = [g for g in groups if len(g)]
        for g in groups:
            parent.append(node)
            centre.append(np.packbits(bits[g].mean(0) > 0.5))
            is_leaf = level + 1 == levels or len(g) == 1
            leaf.append(is_leaf)
            members.append(g)
            if not is_leaf:
                frontier.append((len(parent) - 1, level + 1))
    leaf_arr = np.array(leaf)
    weight = np.zeros(len(parent))
    n_docs = len(per_image)
    for node in np.flatnonzero(leaf_arr):
        n_i = len(np.unique(doc[members[node]]))
        weight[node] = math.log(n_docs / n_i)
    return Vocabulary(
        k, levels, np.array(parent), np.stack(centre).astype(np.uint8), leaf_arr, weight
    )


def training_frames(
    sequences: Sequence[Path | str], every: int = 10, limit: int = 300
) -> list[np.ndarray]:
    """Grey frames of sequences (every ``every``-th, at most ``limit`` in all)."""
    from initsel_ros.datasets import open_sequence
    from initsel_ros.image import to_gray

    frames: list[np.ndarray] = []
    for path in sequences:
        sequence = open_sequence(path)
        frames += [to_gray(sequence.image(i)) for i in range(0, len(sequence), every)]
    if len(frames) > limit:
        frames = [frames[i] for i in np.linspace(0, len(frames) - 1, limit).astype(int)]
    return frames


__all__ = ['Vocabulary', 'orb_descriptors', 'train_vocabulary', 'training_frames']
