"""When to run the fire path again after it found the baseline too short.

While model R's yes holds every other model back, the selector re-checks the pair with the
fire path's rotation test (``selector.SelectorConfig.rotation_recheck_frames``). A fixed
cadence wastes frames where the evidence was just short of its bar: a poster seen from an
arc whose H had 0.49 degrees of median parallax against a floor of 0.5 waited three more
frames, then five of verification.

Each gate that stopped the fire path for want of baseline measures something that grows
with it, so the frame at which the nearest one is predicted to pass follows from the
measure, its bar and the frames since the reference (motion at a steady pace):

- parallax (``policy.min_parallax_of``) grows in proportion to the baseline;
- the rotation test's statistic is the flow a rotation leaves over the noise, about 1 at no
  baseline, with the perspective change adding in quadrature: ``s^2 - 1`` grows with the
  square of the baseline (its bars are ``min_plane_residual_sigma`` for H and
  ``min_rotation_residual_sigma`` for E and F: between the two only H was tried);
- the standard deviation of the refined direction of motion shrinks in inverse proportion.

The next run comes on the last whole frame at or before that one, never later than the
fixed cadence's next frame (a multiple of ``rotation_recheck_frames`` after the reference):
the early runs come on top of the cadence, and a pan, whose statistic stays near 1, is
re-checked as before. Where the rotation test stopped the run, the selector holds a model's
yes on the frames before the scheduled one without running the fire path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from initsel_ros.initialize import FireResult
from initsel_ros.policy import PolicyConfig, Reason, min_parallax_of, plane_share


@dataclass(frozen=True)
class EvidenceGap:
    """How far the nearest baseline-limited gate of one fire-path run is from its bar.

    Attributes:
        growth: the factor by which the baseline must grow for that gate to pass (inf when
            no gate that stopped the run is baseline-limited; under 1 counts as 1).
        gate: what that gate measured against its bar, for the log ('' when none).
    """

    growth: float = math.inf
    gate: str = ''


def evidence_gap(fire: FireResult, policy: PolicyConfig, h_tried: bool = True) -> EvidenceGap:
    """The baseline growth the nearest gate that stopped ``fire`` needs (see the module).

    ``h_tried``: H was among the methods of the run (H's own bar of the rotation test,
    ``min_plane_residual_sigma``, is a gate only then, and only under E's bar).
    """
    gaps = [EvidenceGap()]
    rotation, background = fire.rotation, fire.background
    if fire.reason is Reason.ROTATION and background is not None:
        gaps.append(
            _statistic_gap(background.statistic, policy.min_rotation_residual_sigma, 'left-out')
        )
    elif rotation is not None:
        # under E's bar only H was tried (or nothing): the next bar is a gate of its own
        bars = [policy.min_rotation_residual_sigma]
        if h_tried and policy.min_plane_residual_sigma < bars[0]:
            bars.insert(0, policy.min_plane_residual_sigma)
        bar = next((b for b in bars if not rotation.statistic >= b), math.nan)
        gaps.append(_statistic_gap(rotation.statistic, bar, 'rotation test'))
    for estimate, check in zip(fire.estimates, fire.checks, strict=True):
        if check is Reason.LOW_PARALLAX and estimate.parallax_deg > 0.0:
            floor = min_parallax_of(estimate.method.value, policy, plane_share(estimate))
            if estimate.parallax_deg < floor:
                gaps.append(
                    EvidenceGap(
                        floor / estimate.parallax_deg,
                        f'{estimate.method.value} parallax {estimate.parallax_deg:.2f} of '
                        f'{floor:g} deg',
                    )
                )
    seed = fire.seed
    if fire.reason is Reason.LOW_PARALLAX and seed is not None:
        sigma, bound = seed.translation_sigma_deg, policy.max_translation_sigma_deg
        if math.isfinite(sigma) and sigma > bound > 0.0:
            gaps.append(EvidenceGap(sigma / bound, f'direction +-{sigma:.1f} of {bound:g} deg'))
    return min(gaps, key=lambda g: g.growth)


def _statistic_gap(statistic: float, bar: float, name: str) -> EvidenceGap:
    """The growth a noise-relative statistic needs to reach ``bar`` (quadrature with the
    noise: ``s^2 - 1`` grows with the square of the baseline)."""
    if not (math.isfinite(statistic) and math.isfinite(bar)) or statistic <= 1.0 or bar <= 1.0:
        return EvidenceGap()
    growth = math.sqrt(max(bar * bar - 1.0, 0.0) / (statistic * statistic - 1.0))
    return EvidenceGap(growth, f'{name} {statistic:.1f} of {bar:g} x the noise')


def frames_to_recheck(since: int, every: int, gap: EvidenceGap) -> int:
    """Frames from now (``since`` frames after the reference) to the next run: the last whole
    frame at or before the one where the baseline has grown by ``gap.growth`` at the pace it
    had so far, at least 1 frame on, and never later than the fixed cadence's next multiple
    of ``every`` frames after the reference (the statistic's noise estimate moves from frame
    to frame: an early run that comes out short does not push the cadence back)."""
    cadence = cadence_frames(since, every)
    target = since * max(gap.growth, 1.0)
    if since < 1 or not math.isfinite(target):
        return cadence
    # rounded down: the statistics move from frame to frame with their noise estimate, and a
    # frame too early costs one run, a frame too late a frame of delay
    due = math.floor(target) - since
    return int(min(max(due, 1), cadence))


def cadence_frames(since: int, every: int) -> int:
    """Frames from now (``since`` frames after the reference) to the cadence's next frame, a
    multiple of ``every`` after the reference."""
    if every < 1:
        raise ValueError(f'every must be at least 1, got {every}')
    return every - since % every if since >= 1 else every
