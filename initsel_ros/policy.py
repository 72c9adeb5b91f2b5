"""Turning four probabilities into a decision that carries its reason."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum

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
    """

    thresholds: Mapping[str, float] = field(default_factory=dict)
    r_veto: frozenset[str] = frozenset({'F', 'E'})
    min_tracks: int = 50
    min_points: int = 50
    min_parallax_deg: float = 1.0


@dataclass(frozen=True)
class Decision:
    """What the models said about one frame, and why it did or did not initialize.

    Attributes:
        reason: the outcome (see :class:`Reason`).
        probabilities: model name -> probability of 'yes'.
        fired: models at or above their threshold.
        vetoed: models that fired but were silenced by model R.
        candidates: methods to try, most confident first.
        n_tracks: tracked correspondences.
        mean_disparity: mean correspondence disparity, pixels.
        detail: free text, e.g. the pose estimator's complaint.
    """

    reason: Reason
    probabilities: Mapping[str, float] = field(default_factory=dict)
    fired: tuple[str, ...] = ()
    vetoed: tuple[str, ...] = ()
    candidates: tuple[Method, ...] = ()
    n_tracks: int = 0
    mean_disparity: float = 0.0
    detail: str = ''

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


def decide(
    probabilities: Mapping[str, float],
    thresholds: Mapping[str, float],
    n_tracks: int,
    mean_disparity: float,
    config: PolicyConfig,
) -> Decision:
    """Apply thresholds and the R veto, and order the methods worth trying.

    Args:
        probabilities: model name (F, E, H, R) -> probability.
        thresholds: model name -> threshold (already including overrides).
        n_tracks: number of correspondences.
        mean_disparity: mean disparity, pixels.
        config: the policy settings.

    Returns:
        A :class:`Decision`; ``positive`` when candidates remain. Its reason is
        TOO_FEW_TRACKS, ROTATION or NO_MODEL_FIRED when negative, and INITIALIZED
        (pending the pose check) when positive.
    """
    common = {
        'probabilities': dict(probabilities), 'n_tracks': int(n_tracks),
        'mean_disparity': float(mean_disparity),
    }
    if n_tracks < config.min_tracks:
        detail = f'{n_tracks} < {config.min_tracks}'
        return Decision(Reason.TOO_FEW_TRACKS, detail=detail, **common)
    fired = tuple(
        m for m in PREFERENCE if probabilities.get(m, 0.0) >= thresholds.get(m, 0.5)
    )
    rotation = probabilities.get('R', 0.0) >= thresholds.get('R', 0.5)
    vetoed = tuple(m for m in fired if rotation and m in config.r_veto)
    remaining = [m for m in fired if m not in vetoed]
    margin = {m: probabilities[m] - thresholds.get(m, 0.5) for m in remaining}
    candidates = tuple(
        Method(m) for m in sorted(remaining, key=lambda m: (-margin[m], PREFERENCE.index(m)))
    )
    if candidates:
        reason = Reason.INITIALIZED
    elif rotation:
        reason = Reason.ROTATION
    else:
        reason = Reason.NO_MODEL_FIRED
    return Decision(reason, fired=fired, vetoed=vetoed, candidates=candidates, **common)


def check_pose(estimate: PoseEstimate, config: PolicyConfig) -> Reason | None:
    """None when the recovered pose is good enough to initialize, else the reason."""
    if not estimate.ok:
        return Reason.POSE_FAILED
    if estimate.n_points < config.min_points:
        return Reason.TOO_FEW_POINTS
    if estimate.parallax_deg < config.min_parallax_deg:
        return Reason.LOW_PARALLAX
    return None
