"""Trajectory interpolation of ground-truth poses.

Conventions: quaternions are ``(x, y, z, w)`` as in TUM's ``groundtruth.txt``; poses are
camera-to-world (4, 4) matrices ``T_w_c`` with positions in metres and times in seconds. The
conversions themselves are in :mod:`initsel_ros.transforms`.
"""

from __future__ import annotations

import logging

import numpy as np

from initsel_ros.errors import DatasetError, GeometryError
from initsel_ros.transforms import normalize_quaternions, pose_matrix, slerp

LOG = logging.getLogger(__name__)

#: Default largest gap (seconds) between the two ground-truth samples bracketing a query time.
DEFAULT_MAX_GAP = 0.1

#: A quaternion this far from unit norm is normalized with a warning (a column order mixed
#: up reads as one far from 1; rounding in a file is far below it).
QUATERNION_NORM_TOLERANCE = 0.01


def check_trajectory(
    stamps: np.ndarray,
    positions: np.ndarray,
    quaternions: np.ndarray,
    where: str,
    file_order: str = 'x y z w',
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A ground-truth trajectory as the readers hand it on: sorted by time, exact repeats
    of a sample dropped.

    Args:
        stamps: (N,) times (any unit).
        positions: (N, 3).
        quaternions: (N, 4) xyzw.
        file_order: the quaternion's column order in the file (named in the warning about
            quaternions off unit norm: EuRoC writes w x y z).
        where: the file (and topic) they came from, for the messages.

    Raises:
        DatasetError: a non-finite value, a zero quaternion, or one stamp with two different
            poses (interpolation would blend them), naming ``where`` and the sample.
    """
    stamps = np.asarray(stamps)
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    quaternions = np.asarray(quaternions, dtype=np.float64).reshape(-1, 4)
    values = np.column_stack([stamps.astype(np.float64), positions, quaternions])
    bad = np.flatnonzero(~np.all(np.isfinite(values), axis=1))
    if len(bad):
        raise DatasetError(
            f'{where}: sample {bad[0]} (time {stamps[bad[0]]}) has a non-finite value '
            f'{values[bad[0], 1:].tolist()} ({len(bad)} samples)'
        )
    norms = np.linalg.norm(quaternions, axis=1)
    zero = np.flatnonzero(norms < 1e-9)
    if len(zero):
        raise DatasetError(f'{where}: sample {zero[0]} (time {stamps[zero[0]]}): zero quaternion')
    off = np.abs(norms - 1.0) > QUATERNION_NORM_TOLERANCE
    if np.any(off):
        LOG.warning(
            '%s: %d of %d quaternions are not of unit norm (%.3g to %.3g): normalized; check '
            'the column order (%s)',
            where,
            int(off.sum()),
            len(norms),
            float(norms[off].min()),
            float(norms[off].max()),
            file_order,
        )
    order = np.argsort(stamps, kind='stable')
    stamps, positions, quaternions = stamps[order], positions[order], quaternions[order]
    repeat = np.flatnonzero(stamps[1:] == stamps[:-1]) + 1
    if len(repeat):
        unit = quaternions / np.linalg.norm(quaternions, axis=1, keepdims=True)
        same_q = np.minimum(
            np.abs(unit[repeat] - unit[repeat - 1]).max(axis=1),
            np.abs(unit[repeat] + unit[repeat - 1]).max(axis=1),
        )
        same_t = np.abs(positions[repeat] - positions[repeat - 1]).max(axis=1)
        conflict = repeat[(same_t > 1e-9) | (same_q > 1e-9)]
        if len(conflict):
            k = conflict[0]
            raise DatasetError(
                f'{where}: time {stamps[k]} has two different poses '
                f'({positions[k - 1].tolist()} and {positions[k].tolist()}; {len(conflict)} '
                'such times): which one is the ground truth?'
            )
        keep = np.ones(len(stamps), dtype=bool)
        keep[repeat] = False
        stamps, positions, quaternions = stamps[keep], positions[keep], quaternions[keep]
    return stamps, positions, quaternions


def interpolate_poses(
    query_times: np.ndarray,
    stamps: np.ndarray,
    positions: np.ndarray,
    quaternions: np.ndarray,
    max_gap: float = DEFAULT_MAX_GAP,
    nearest_tolerance: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Interpolate a trajectory at query times (linear position, slerp rotation).

    Args:
        query_times: (M,) seconds.
        stamps: (N,) seconds, strictly increasing after sorting (sorted here).
        positions: (N, 3) metres.
        quaternions: (N, 4) xyzw.
        max_gap: a query is interpolated only if the two bracketing samples are at most this
            far apart (seconds).
        nearest_tolerance: a query outside the trajectory (or in a too-large gap) takes the
            nearest sample if that is within this many seconds; 0 disables it.

    Returns:
        ``(positions (M, 3), quaternions (M, 4))``; rows are NaN where no pose is available.
    """
    query = np.atleast_1d(np.asarray(query_times, dtype=np.float64))
    stamps = np.asarray(stamps, dtype=np.float64)
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    quaternions = normalize_quaternions(np.asarray(quaternions).reshape(-1, 4))
    if not (len(stamps) == len(positions) == len(quaternions)):
        raise GeometryError(
            f'trajectory arrays disagree: {len(stamps)} stamps, {len(positions)} positions, '
            f'{len(quaternions)} quaternions'
        )
    out_t = np.full((len(query), 3), np.nan)
    out_q = np.full((len(query), 4), np.nan)
    if len(stamps) == 0 or len(query) == 0:
        return out_t, out_q
    order = np.argsort(stamps, kind='stable')
    stamps, positions, quaternions = stamps[order], positions[order], quaternions[order]

    hi = np.searchsorted(stamps, query, side='left')
    exact = (hi < len(stamps)) & (stamps[np.minimum(hi, len(stamps) - 1)] == query)
    lo = hi - 1
    inside = (lo >= 0) & (hi < len(stamps))
    lo_c = np.clip(lo, 0, len(stamps) - 1)
    hi_c = np.clip(hi, 0, len(stamps) - 1)
    gap = stamps[hi_c] - stamps[lo_c]
    ok = inside & (gap <= max_gap) & (gap > 0)
    if np.any(ok):
        a = (query[ok] - stamps[lo_c[ok]]) / gap[ok]
        out_t[ok] = (1 - a)[:, None] * positions[lo_c[ok]] + a[:, None] * positions[hi_c[ok]]
        out_q[ok] = slerp(quaternions[lo_c[ok]], quaternions[hi_c[ok]], a)
    out_t[exact] = positions[hi_c[exact]]
    out_q[exact] = quaternions[hi_c[exact]]
    if nearest_tolerance > 0:
        missing = np.isnan(out_t[:, 0])
        if np.any(missing):
            d_lo = np.where(lo >= 0, np.abs(query - stamps[lo_c]), np.inf)
            d_hi = np.where(hi < len(stamps), np.abs(stamps[hi_c] - query), np.inf)
            nearest = np.where(d_lo <= d_hi, lo_c, hi_c)
            close = missing & (np.minimum(d_lo, d_hi) <= nearest_tolerance)
            out_t[close] = positions[nearest[close]]
            out_q[close] = quaternions[nearest[close]]
    return out_t, out_q


def pose_matrices(t: np.ndarray, q: np.ndarray) -> list[np.ndarray | None]:
    """The (4, 4) camera-to-world of each row of :func:`interpolate_poses`' output, None
    where the row is NaN."""
    valid = ~np.isnan(t[:, 0])
    out: list[np.ndarray | None] = [None] * len(t)
    if np.any(valid):
        mats = pose_matrix(t[valid], q[valid])
        for k, i in enumerate(np.flatnonzero(valid)):
            out[i] = mats[k]
    return out


__all__ = [
    'DEFAULT_MAX_GAP',
    'QUATERNION_NORM_TOLERANCE',
    'check_trajectory',
    'interpolate_poses',
    'pose_matrices',
]
