"""Turning four probabilities into a decision that carries its reason."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from initsel_ros.geometry import Method, PoseEstimate

#: Order used to break ties between equally confident models.
PREFERENCE: tuple[str, ...] = ('E', 'H', 'F')


class Reason(str, Enum):
    """Why a frame did or did not initialize the map."""

    INITIALIZED = 'initialized'
    NEW_REFERENCE = 'new reference'  # this frame became the reference frame
    TOO_FEW_TRACKS = 'too few tracks'
    ROTATION = 'rotation'  # model R fired: no usable baseline
    NO_MODEL_FIRED = 'no model fired'
    POSE_FAILED = 'pose estimation failed'
    TOO_FEW_POINTS = 'too few triangulated points'
    LOW_PARALLAX = 'low parallax'
    VERIFYING = 'verifying'  # a candidate is held back until the next frames confirm it
    VERIFICATION_FAILED = 'verification_failed'  # the next frames contradicted the candidate
    DONE = 'already initialized'  # mode 'once', until reset
    # Frames that never got a decision (set by the node, not the selector):
    SKIPPED_IMAGE = 'image skipped'  # the image could not be converted or used
    OUT_OF_ORDER = 'out of order'  # a little older than the latest frame (jitter): skipped
    INTERNAL_ERROR = 'internal error'  # the selector or the publishing failed unexpectedly


@dataclass(frozen=True)
class PolicyConfig:
    """Settings of the decision policy.

    Attributes:
        thresholds: per-model probability thresholds overriding the model file's.
        r_veto: models silenced when model R says pure rotation.
        min_tracks: fewer tracked correspondences than this: no decision (and the
            selector picks a new reference).
        min_points: a pose needs at least this many triangulated points.
        min_parallax_deg: a pose needs at least this median parallax, degrees.
        min_homography_parallax_deg: the same floor for H, whose pose comes from the
            perspective change of a plane rather than from each point's parallax (the
            rotation test and the translation's standard deviation judge that change). It
            applies when the plane is the scene: see ``min_homography_plane_share``.
        min_homography_plane_share: H's own floor holds only when H's triangulated points
            are at least this share of the tracks; on less, the tracks have depth beyond
            the plane, the parallax of that depth will let E or F decide, and H needs
            ``min_parallax_deg`` as well.
        min_rotation_residual_sigma: when a model fires, the flow left after the best pure
            rotation is taken out must reach this many times the tracking noise
            (``geometry.rotation_test``: a least-median rotation fit that independently moving
            objects on under half of the tracks do not sway, under focal lengths up to 20 %
            off, against the tracking noise a homography or F leaves on the same tracks): a
            rotation alone explains any flow with less, whatever the pose estimators make of
            it.
        min_plane_residual_sigma: where the rotation test's statistic is at least this but
            under ``min_rotation_residual_sigma``, H alone is tried: a plane's perspective
            change is parallax enough for H's decomposition (as ``min_homography_parallax_deg``
            says) before it is for E and F, whose translation is then ill-determined; the
            pose check, the direction's standard deviation and the verification still judge
            H, which must triangulate ``min_homography_plane_share`` of the tracks there (on
            less the rest has depth, E's domain). At or above
            ``min_rotation_residual_sigma`` it is off.
        max_translation_sigma_deg: a refined seed map is published only when the direction
            of its translation is known to within this standard deviation, degrees (first
            order, from the bundle adjustment: ``refine.translation_sigma_deg``); a larger one
            waits for more baseline. 0 or less turns the check off.
        max_edge_point_share: a seed map is refused when more than this share of its
            points lie on straight edges of the reference frame, where a track is free to
            slide along the edge (``corners.EDGE_ISOTROPY``): on nearly untextured surfaces
            the map would rest on them. 1 turns the check off.
    """

    thresholds: Mapping[str, float] = field(default_factory=dict)
    r_veto: frozenset[str] = frozenset({'F', 'E'})
    min_tracks: int = 50
    min_points: int = 50
    min_parallax_deg: float = 1.0
    min_homography_parallax_deg: float = 0.5
    min_homography_plane_share: float = 0.8
    min_rotation_residual_sigma: float = 3.0
    min_plane_residual_sigma: float = 2.0
    max_translation_sigma_deg: float = 2.0
    max_edge_point_share: float = 0.33


@dataclass(slots=True)
class Decision:
    """What the models said about one frame, and why it did or did not initialize.

    A record made once per frame: treat it as immutable (``dataclasses.replace`` makes changed
    copies). It is not frozen only because a frozen dataclass costs a microsecond more to
    make, a thirtieth of the whole decision.

    Attributes:
        reason: the outcome (see :class:`Reason`).
        probabilities: model name -> probability of 'yes'.
        fired: of F, E and H, the models at or above their threshold (R's yes is
            reason ROTATION).
        vetoed: models that fired but were silenced by model R.
        candidates: methods to try, most confident first.
        n_tracks: tracked correspondences.
        mean_disparity: mean correspondence disparity, pixels.
        detail: free text, e.g. the pose estimator's complaint.
        referred: models whose probability the model file's referee gave (the file's own
            model was within its band of the threshold; see ``models.Referee``).
    """

    reason: Reason
    probabilities: Mapping[str, float] = field(default_factory=dict)
    fired: tuple[str, ...] = ()
    vetoed: tuple[str, ...] = ()
    candidates: tuple[Method, ...] = ()
    n_tracks: int = 0
    mean_disparity: float = 0.0
    detail: str = ''
    referred: tuple[str, ...] = ()

    @property
    def positive(self) -> bool:
        """True when at least one method is worth trying."""
        return bool(self.candidates)


def effective_thresholds(
    model_thresholds: Mapping[str, float], config: PolicyConfig
) -> dict[str, float]:
    """Model-file thresholds with the configuration's overrides applied."""
    out = dict(model_thresholds)
    out.update({k: float(v) for k, v in config.thresholds.items()})
    return out


@dataclass(frozen=True)
class BatchDecision:
    """:func:`decide_batch` on N pairs at once (the per-frame decision, vectorized).

    Attributes:
        reason: (N,) object array of :class:`Reason` (TOO_FEW_TRACKS, ROTATION,
            NO_MODEL_FIRED, or INITIALIZED pending the pose check).
        fired: (N, 3) bool, models F/E/H at or above their thresholds, in
            :data:`PREFERENCE` order (columns E, H, F).
        vetoed: (N, 3) bool, fired but silenced by model R.
        rotation: (N,) bool, model R fired.
        order: (N, 3) int, candidate columns most confident first (margin above the
            threshold, ties in :data:`PREFERENCE` order); entries past ``n_candidates`` are
            not candidates.
        n_candidates: (N,) int.
    """

    reason: np.ndarray
    fired: np.ndarray
    vetoed: np.ndarray
    rotation: np.ndarray
    order: np.ndarray
    n_candidates: np.ndarray

    def first_method(self) -> np.ndarray:
        """(N,) object array: the most confident candidate ('E', 'H', 'F') or ''."""
        names = np.array(PREFERENCE, dtype=object)[self.order[:, 0]]
        return np.where(self.n_candidates > 0, names, '').astype(object)

    def candidates(self, i: int) -> tuple[Method, ...]:
        """Row i's candidates as methods, most confident first."""
        return tuple(Method(PREFERENCE[j]) for j in self.order[i, : self.n_candidates[i]])


_PREFERENCE_INDEX = np.arange(len(PREFERENCE))


def decide_batch(
    probabilities: Mapping[str, np.ndarray | float],
    thresholds: Mapping[str, float],
    n_tracks: np.ndarray | int,
    config: PolicyConfig,
) -> BatchDecision:
    """The policy, vectorized over pairs: thresholds, R veto and candidate order.

    Args:
        probabilities: model name (F, E, H, R) -> (N,) probabilities (a missing model is 0).
        thresholds: model name -> threshold (already including overrides; default 0.5).
        n_tracks: (N,) correspondences per pair.
        config: the policy settings.
    """
    n_tracks = np.atleast_1d(np.asarray(n_tracks))
    n = n_tracks.shape[0]
    P = np.empty((n, len(PREFERENCE)))
    for j, m in enumerate(PREFERENCE):
        P[:, j] = probabilities.get(m, 0.0)
    T = np.array([thresholds.get(m, 0.5) for m in PREFERENCE])
    enough = n_tracks >= config.min_tracks
    fired = (P >= T) & enough[:, None]
    rotation = (
        np.broadcast_to(np.asarray(probabilities.get('R', 0.0), float), (n,))
        >= thresholds.get('R', 0.5)
    ) & enough
    veto = np.array([m in config.r_veto for m in PREFERENCE])
    vetoed = fired & rotation[:, None] & veto[None, :]
    remaining = fired & ~vetoed
    margin = np.where(remaining, P - T, -np.inf)
    order = np.argsort(-margin, axis=1, kind='stable')  # stable: ties in PREFERENCE order
    count = remaining.sum(axis=1)
    reason = np.empty(n, dtype=object)
    reason.fill(Reason.NO_MODEL_FIRED)  # (np.full would store the enum as a string)
    reason[rotation] = Reason.ROTATION
    reason[count > 0] = Reason.INITIALIZED
    reason[~enough] = Reason.TOO_FEW_TRACKS
    return BatchDecision(reason, fired, vetoed, rotation, order, count)


def decide(
    probabilities: Mapping[str, float],
    thresholds: Mapping[str, float],
    n_tracks: int,
    mean_disparity: float,
    config: PolicyConfig,
    referred: tuple[str, ...] = (),
) -> Decision:
    """Apply thresholds and the R veto, and order the methods worth trying (one pair).

    The scalar twin of :func:`decide_batch` (which the evaluation uses): one row through
    numpy costs about 3x the whole per-frame decision, so this one stays plain Python, and
    a test holds the two equal pair by pair.

    Args:
        probabilities: model name (F, E, H, R) -> probability.
        thresholds: model name -> threshold (already including overrides).
        n_tracks: number of correspondences.
        mean_disparity: mean disparity, pixels.
        config: the policy settings.
        referred: the models whose probability a referee gave (recorded, not used).

    Returns:
        A :class:`Decision`; ``positive`` when candidates remain. Its reason is
        TOO_FEW_TRACKS, ROTATION or NO_MODEL_FIRED when negative, and INITIALIZED
        (pending the pose check) when positive.
    """
    probabilities = dict(probabilities)
    n_tracks = int(n_tracks)
    mean_disparity = float(mean_disparity)
    if n_tracks < config.min_tracks:
        return Decision(
            Reason.TOO_FEW_TRACKS,
            probabilities,
            n_tracks=n_tracks,
            mean_disparity=mean_disparity,
            detail=f'{n_tracks} < {config.min_tracks}',
            referred=referred,
        )
    p, t = probabilities.get, thresholds.get
    fired = [m for m in PREFERENCE if p(m, 0.0) >= t(m, 0.5)]
    rotation = p('R', 0.0) >= t('R', 0.5)
    vetoed: tuple[str, ...] = ()
    remaining = fired
    if rotation and fired:
        vetoed = tuple(m for m in fired if m in config.r_veto)
        remaining = [m for m in fired if m not in config.r_veto]
    if len(remaining) > 1:  # largest margin above the threshold first; sort is stable, so
        remaining.sort(key=lambda m: t(m, 0.5) - p(m, 0.0))  # ties keep PREFERENCE order
    if remaining:
        reason = Reason.INITIALIZED
    elif rotation:
        reason = Reason.ROTATION
    else:
        reason = Reason.NO_MODEL_FIRED
    return Decision(
        reason,
        probabilities,
        tuple(fired),
        vetoed,
        tuple(map(_METHODS.__getitem__, remaining)),
        n_tracks,
        mean_disparity,
        referred=referred,
    )


_METHODS = {m: Method(m) for m in PREFERENCE}


def plane_share(estimate: PoseEstimate) -> float:
    """The share of its tracks an estimate triangulated (for H: how much of the scene its
    plane holds, :func:`min_parallax_of`)."""
    return estimate.n_points / max(int(estimate.inliers.shape[0]), 1)


def min_parallax_of(method: str, config: PolicyConfig, plane_share: float = 1.0) -> float:
    """The median parallax floor of ``method`` ('F', 'E' or 'H'), degrees.

    ``plane_share`` is the share of the tracks the estimate triangulated: H's own floor
    holds alone when it reaches ``config.min_homography_plane_share``, and on less H needs
    ``config.min_parallax_deg`` as well.
    """
    if method != 'H':
        return config.min_parallax_deg
    if plane_share >= config.min_homography_plane_share:
        return config.min_homography_parallax_deg
    return max(config.min_homography_parallax_deg, config.min_parallax_deg)


def check_pose_batch(
    ok: np.ndarray,
    n_points: np.ndarray,
    parallax_deg: np.ndarray,
    config: PolicyConfig,
    method: str = 'E',
    n_tracks: np.ndarray | None = None,
) -> np.ndarray:
    """:func:`check_pose` on N estimates of ``method``: (N,) object array of Reason, or None
    when good. ``n_tracks``: the correspondences each estimate came from (H's floor depends
    on the share it triangulated); without them every H counts as the whole scene."""
    ok = np.asarray(ok, dtype=bool)
    n_points = np.asarray(n_points)
    parallax_deg = np.asarray(parallax_deg, dtype=float)
    share = (
        np.ones(ok.shape[0])
        if n_tracks is None
        else n_points / np.maximum(np.asarray(n_tracks, dtype=float), 1.0)
    )
    floor = np.where(
        share >= config.min_homography_plane_share,
        min_parallax_of(method, config),
        min_parallax_of(method, config, 0.0),
    )
    out = np.full(ok.shape[0], None, dtype=object)
    out[~(parallax_deg >= floor)] = Reason.LOW_PARALLAX
    out[n_points < config.min_points] = Reason.TOO_FEW_POINTS
    out[~ok] = Reason.POSE_FAILED
    return out


def check_pose(
    estimate: PoseEstimate, config: PolicyConfig, share: float | None = None
) -> Reason | None:
    """None when the recovered pose is good enough to initialize, else the reason.

    ``share``: the share of the tracks H's plane holds, for H's parallax floor
    (:func:`min_parallax_of`); by default :func:`plane_share` of the estimate.
    The runner-up decomposition of an ambiguous H is judged with the winner's share: the
    plane is the same, only fewer of its points lie in front of the mirrored cameras.
    The scalar twin of :func:`check_pose_batch` (a test holds them equal).
    """
    if not estimate.ok:
        return Reason.POSE_FAILED
    if estimate.n_points < config.min_points:
        return Reason.TOO_FEW_POINTS
    if share is None:
        share = plane_share(estimate)
    floor = min_parallax_of(estimate.method.value, config, share)
    if not estimate.parallax_deg >= floor:  # NaN parallax fails too
        return Reason.LOW_PARALLAX
    return None
