"""The fire path: once a model fired, which method, which pose and which seed map.

One pure function, :func:`initialize_pair`, runs every step a pair goes through at fire time,
for the live selector and for the offline tools alike (labels, seed-map judging, robustness):

1. the rotation test: a flow that one rotation explains to within the tracking noise has no
   baseline, whatever the estimators make of it (``geometry.rotation_test``: the residual of
   the best rotation against the tracking noise a homography or F leaves on the same
   tracks); between ``min_plane_residual_sigma`` and ``min_rotation_residual_sigma`` only H
   goes on (a plane's perspective change is parallax enough for H before it is for E and F);
2. the estimates of the candidate methods (``geometry.estimate_pose``);
3. the pose check of each (``policy.check_pose``);
4. the choice among those that pass, by GRIC (``model_selection.select_method``);
5. the background test: when the winner leaves many tracks out and one rotation explains
   those to within the noise of all tracks, either the camera only rotated (or stood still)
   and the winner fits an object moving on its own, a board held by a person or a passing
   car, which the first test cannot see once such objects hold most of the tracks; or the
   winner fits one plane of a scene whose other parts show no parallax yet. Either way the
   pair is refused as a rotation and the next frames decide; and the two-motions test: the
   tracks with parallax that contradict the winner's motion (off its epipolar lines, or
   behind the cameras) must not outnumber those that support it (:func:`motion_support`: a
   winner that fits an object moving past a translating camera);
6. the better-model test: an E or F winner is refused when an H that failed the pose check
   scores a lower GRIC (the tracks are a plane, where E and F are degenerate), and an H
   winner when a failed E or F does (the tracks have depth): the pair waits for that model;
7. the seed map of the winner, bundle-adjusted (``refine.refine_two_view``; an H whose
   plane is the scene as one plane, ``refine_plane.refine_as_plane``), refused when it fixes
   the direction of motion worse than ``max_translation_sigma_deg``.

Each step can be switched off (labels need the estimates only). The result carries every
method's estimate and check, not only the winner's. Verification over the next frames is not
part of it: it needs those frames, and stays in the selector.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from initsel_ros.geometry import (
    OFF_PLANE_MIN_PX,
    OFF_PLANE_NOISE_FACTOR,
    ROTATION_RADIAL_TERMS,
    Method,
    PoseEstimate,
    RotationTest,
    estimate_pose,
    fundamental_from_essential,
    homogeneous,
    plane_perspective_test,
    rotation_test,
    sampson_fundamental,
    skew,
    transfer_px,
)
from initsel_ros.model_selection import Selection, select_method
from initsel_ros.policy import (
    Decision,
    PolicyConfig,
    Reason,
    check_pose,
    min_parallax_of,
    plane_share,
)
from initsel_ros.refine import Refinement, refine_two_view
from initsel_ros.refine_plane import refine_as_plane

#: After the bundle adjustment a map point must reproject within this many pixels in both
#: images (the estimators keep points within 2.5 px before it).
MAP_MAX_REPROJECTION_PX = 2.0

#: The background test runs when the winner's outliers are at least this many tracks and this
#: share of all of them: fewer are mismatches and noisy tracks, not a second motion. (12 tracks
#: give the rotation fit's 3 parameters 24 equations; late in a pan the background may keep
#: only 15-20 tracks while a board moving on its own holds the rest. 20 let a pan with moving
#: boards initialize on the board at frame 64; 10 and 14 gave the same tuning results as 12.)
BACKGROUND_MIN_TRACKS = 12
BACKGROUND_MIN_SHARE = 0.2


@dataclass(frozen=True)
class FireConfig:
    """Settings of :func:`initialize_pair`.

    Attributes:
        policy: the pose check (``min_points``, ``min_parallax_deg``,
            ``min_homography_parallax_deg``), the rotation test's threshold
            (``min_rotation_residual_sigma``) and the bound on the refined direction of
            motion (``max_translation_sigma_deg``; it needs ``refine``).
        ransac_threshold_px: RANSAC inlier threshold of the estimators, pixels.
        rotation_test: run the rotation test first (a rotation stops the path).
        background_test: run the background test on the winner (needs ``rotation_test``,
            whose noise it uses; see :func:`background_test`).
        select: choose a winner by GRIC among the estimates that pass the pose check (and
            keep both of an ambiguous H for the verification; without selection it is refused).
        refine: bundle-adjust the winner's seed map.
        map_max_reprojection_px: after refinement, points reprojecting worse than this in
            either image leave the map, pixels.
        radial_terms: radial distortion terms the rotation test also tries
            (:data:`geometry.ROTATION_RADIAL_TERMS`: a pan through a lens whose distortion
            the camera does not state; empty for a camera that states its distortion, whose
            pixels arrive undistorted).
    """

    policy: PolicyConfig = field(default_factory=PolicyConfig)
    ransac_threshold_px: float = 1.0
    rotation_test: bool = True
    background_test: bool = True
    select: bool = True
    refine: bool = True
    map_max_reprojection_px: float = MAP_MAX_REPROJECTION_PX
    radial_terms: tuple[float, ...] = ROTATION_RADIAL_TERMS


def radial_terms_for(states_distortion: bool) -> tuple[float, ...]:
    """The rotation test's radial terms (``FireConfig.radial_terms``) for a camera: none where
    it states its distortion (its pixels arrive undistorted), :data:`ROTATION_RADIAL_TERMS`
    where it states none (a lens whose distortion was left out bends a pan)."""
    return () if states_distortion else ROTATION_RADIAL_TERMS


#: The fire path's estimators alone: no rotation test, selection or refinement (what the
#: offline tools judge each method by).
ESTIMATES_ONLY = FireConfig(rotation_test=False, select=False, refine=False)


@dataclass(frozen=True)
class SeedMap:
    """The pose and first map points of one estimate (refined or not).

    Attributes:
        method: the method of the estimate.
        R: (3, 3) rotation, reference to current camera.
        t: (3,) unit translation, reference to current camera.
        points: (M, 3) float64 points in the reference camera frame, at the scale ``|t| = 1``.
        indices: (M,) int64 indices of the points' correspondences in the input arrays.
        parallax_deg: median parallax of the estimate's points, degrees.
        refinement: the bundle adjustment's result (None when not refined).
    """

    method: Method
    R: np.ndarray
    t: np.ndarray
    points: np.ndarray
    indices: np.ndarray
    parallax_deg: float
    refinement: Refinement | None = None

    @property
    def n_points(self) -> int:
        """Map points kept."""
        return int(self.points.shape[0])

    @property
    def translation_sigma_deg(self) -> float:
        """Standard deviation of the translation direction, degrees (NaN unrefined)."""
        return math.nan if self.refinement is None else self.refinement.translation_sigma_deg


@dataclass(frozen=True)
class FireResult:
    """Everything the fire path found on one pair.

    Attributes:
        reason: INITIALIZED when a seed map came out; ROTATION when the rotation test
            stopped the path; the first failing method's pose-check reason (POSE_FAILED,
            TOO_FEW_POINTS, LOW_PARALLAX) when no candidate passed, or TOO_FEW_POINTS when
            the refined map kept too few points; INITIALIZED with no seed when selection was
            off and at least one estimate passed.
        detail: one line on why, for the status and the log.
        rotation: the rotation test (None when off): the best rotation's residual, the
            noise and their ratio.
        background: the rotation test of the tracks the winner left out, against the noise
            of all tracks (None when it did not run: too few of them, or no winner).
        estimates: every method's estimate, in the order tried (empty after a rotation).
        checks: per estimate, :func:`policy.check_pose`'s reason, or None when it passed.
        selection: the GRIC choice (None when selection was off or never reached).
        seed: the winner's seed map (None when there is none).
        alternatives: seed maps of the winner's rival poses that fit the pair as well (H's
            two-fold planar ambiguity: the runner-up decomposition, when it passes the pose
            check too); the frames after the pair decide between them and ``seed``.
    """

    reason: Reason
    detail: str = ''
    rotation: RotationTest | None = None
    estimates: tuple[PoseEstimate, ...] = ()
    checks: tuple[Reason | None, ...] = ()
    selection: Selection | None = None
    seed: SeedMap | None = None
    alternatives: tuple[SeedMap, ...] = ()
    background: RotationTest | None = None

    @property
    def rotation_residual_px(self) -> float:
        """The rotation test's median residual, pixels (NaN when off)."""
        return math.nan if self.rotation is None else self.rotation.residual_px

    def estimate(self, method: Method | str) -> PoseEstimate | None:
        """The estimate of ``method``, or None when it was not tried."""
        method = Method(method)
        return next((e for e in self.estimates if e.method is method), None)


def fire_methods(
    decision: Decision, thresholds: Mapping[str, float], policy: PolicyConfig
) -> tuple[Method, ...]:
    """The methods a positive decision tries: its candidates, plus H unless R vetoes H.

    H is cheap, and GRIC needs it to see a plane.
    """
    methods = list(decision.candidates)
    rotation = decision.probabilities.get('R', 0.0) >= thresholds.get('R', 0.5)
    h_vetoed = rotation and 'H' in policy.r_veto
    if Method.H not in methods and not h_vetoed:
        methods.append(Method.H)
    return tuple(methods)


def seed_map(
    estimate: PoseEstimate,
    ref: np.ndarray,
    cur: np.ndarray,
    K: np.ndarray,
    *,
    refine: bool = True,
    max_reprojection_px: float = MAP_MAX_REPROJECTION_PX,
    as_plane: bool = False,
) -> SeedMap:
    """The seed map of an estimate, bundle-adjusted when ``refine``.

    Args:
        estimate: a pose estimate with points (``estimate.ok``).
        ref: (N, 2) reference pixels the estimate was made from (undistorted).
        cur: (N, 2) current pixels.
        K: (3, 3) camera matrix.
        refine: run :func:`refine.refine_two_view` and drop the points it rejects.
        max_reprojection_px: the refinement's rejection threshold, pixels.
        as_plane: refine under the homography's own model instead, the points on one plane,
            unless free depths explain the tracks better than the noise allows
            (:func:`refine_plane.refine_as_plane`): for an H whose plane is the scene
            (:func:`plane_is_the_scene`).
    """
    R, t, points, indices = estimate.R, estimate.t, estimate.points, estimate.indices
    refinement = None
    if refine:
        refine_as = refine_as_plane if as_plane else refine_two_view
        refinement = refine_as(
            R, t, points, ref[indices], cur[indices], K, max_reprojection_px=max_reprojection_px
        )
        R, t, points = refinement.R, refinement.t, refinement.points
        indices = indices[refinement.kept]
    return SeedMap(estimate.method, R, t, points, indices, estimate.parallax_deg, refinement)


def _low_essential_parallax(
    estimates: Sequence[PoseEstimate], checks: Sequence[Reason | None]
) -> PoseEstimate | None:
    """The E estimate when it was refused for low parallax, else None.

    With the camera matrix known, E (5 dof) measures the parallax the motion gives; an F
    (7 dof) of the same tracks may reconstruct a projectively distorted scene, and its
    points' parallax then comes out higher than the motion's. F is judged by E's parallax:
    where E is too low, so is F. (On the desk sequence such an F at 1.3 degrees, with E at
    0.9, published a direction 0.15 off; E a few frames later, 0.05.)
    """
    return next(
        (
            e
            for e, c in zip(estimates, checks, strict=True)
            if e.method is Method.E and c is Reason.LOW_PARALLAX
        ),
        None,
    )


def _problem_text(
    estimate: PoseEstimate,
    problem: Reason | None,
    policy: PolicyConfig,
    low_essential: PoseEstimate | None = None,
) -> str:
    """What the selection reports of a candidate: '' when it passed, else why not (for low
    parallax, the floor that applied: H's own, or E's where H's plane is not the scene; for
    an F judged by E's parallax, E's)."""
    if problem is None:
        return ''
    if estimate.reason:
        return estimate.reason
    if (
        problem is Reason.LOW_PARALLAX
        and estimate.method is Method.F
        and low_essential is not None
        and estimate.parallax_deg >= policy.min_parallax_deg
    ):
        return (
            f'{problem.value}: E, with the camera matrix, measures parallax '
            f"{low_essential.parallax_deg:.2f} deg < {policy.min_parallax_deg:g} (F's own "
            f'{estimate.parallax_deg:.2f} deg on {estimate.n_points} points)'
        )
    text = f'{problem.value}: {estimate.n_points} points, parallax {estimate.parallax_deg:.2f} deg'
    if problem is Reason.LOW_PARALLAX:
        share = plane_share(estimate)
        floor = min_parallax_of(estimate.method.value, policy, share)
        text += f' < {floor:g}'
        if estimate.method is Method.H and share < policy.min_homography_plane_share:
            text += (
                f' (H triangulates {share:.0%} of the tracks, under '
                f"{policy.min_homography_plane_share:.0%}: E's floor applies)"
            )
    return text


def _resolve_ambiguity(estimate: PoseEstimate, policy: PolicyConfig) -> PoseEstimate:
    """An H whose close runner-up decomposition fails the pose check is refused, as before.

    Both are kept only when both pass: then the frames after the pair choose. A runner-up
    that fails (too few points with parallax) does not make the winner right: on depth
    variation seen at a small baseline such a winner was the mirrored one as often as not.
    """
    rival = estimate.alternative
    why = None if rival is None else check_pose(rival, policy, plane_share(estimate))
    if why is None:
        return estimate
    return replace(
        estimate,
        ok=False,
        reason=(
            f'homography decomposition ambiguous: {estimate.n_points} vs {rival.n_points} '
            f'points, and the runner-up fails the pose check ({why.value})'
        ),
        alternative=None,
        ambiguous=True,
    )


def _plane_or_relief(
    estimate: PoseEstimate, ref: np.ndarray, cur: np.ndarray, K: np.ndarray, policy: PolicyConfig
) -> PoseEstimate:
    """An H that explains its own tracks no better than a rotation is refused
    (:func:`geometry.plane_perspective_test` under ``min_plane_residual_sigma``): it was fitted
    to the relief of a scene with depth at a short baseline, not to a plane's perspective
    change, and its decompositions are no pose. Other estimates pass unchanged."""
    if estimate.method is not Method.H or not estimate.ok:
        return estimate
    floor = policy.min_plane_residual_sigma
    test = plane_perspective_test(ref, cur, K, estimate.matrix, estimate.inliers, floor)
    if test.statistic >= floor:
        return estimate
    return replace(
        estimate,
        ok=False,
        reason=(
            f'on the {int(np.count_nonzero(estimate.inliers))} tracks H holds, a rotation '
            f'leaves {test.statistic:.1f} x what H leaves (< {floor:g} x): H fits the relief of '
            'a scene with depth at this baseline, not the perspective change of a plane'
        ),
        alternative=None,
    )


def _estimate(
    method: Method | str, ref: np.ndarray, cur: np.ndarray, K: np.ndarray, config: FireConfig
) -> PoseEstimate:
    """One method's estimate as the fire path makes it (an H too close to call is refused
    unless both its decompositions pass the pose check)."""
    estimate = estimate_pose(
        Method(method),
        ref,
        cur,
        K,
        ransac_threshold_px=config.ransac_threshold_px,
        # only a selection goes on to verification, which can choose between the two;
        # without one (labels, the baselines' rules) an ambiguous H is refused as before
        keep_ambiguous=config.select,
        # and where the plane is the scene, a decomposition leaving it behind a camera is
        # none (the labels keep ORB-SLAM's rule)
        plane_visibility_share=config.policy.min_homography_plane_share if config.select else None,
    )
    return _resolve_ambiguity(estimate, config.policy)


def initialize_pair(
    ref: np.ndarray,
    cur: np.ndarray,
    K: np.ndarray,
    methods: Sequence[Method | str],
    config: FireConfig | None = None,
) -> FireResult:
    """Run the fire path on one pair of correspondence sets (see the module docstring).

    Args:
        ref: (N, 2) reference pixels (undistorted).
        cur: (N, 2) current pixels, row i matching row i of ``ref``.
        K: (3, 3) camera matrix.
        methods: the methods to estimate, in order (see :func:`fire_methods`).
        config: which steps run, and their settings.

    Returns:
        A :class:`FireResult`; a rotation, a failed estimate or too few points is a reason,
        not an exception.
    """
    config = config or FireConfig()
    policy = config.policy
    residual = None
    if config.rotation_test:
        threshold = policy.min_rotation_residual_sigma
        wants_h = any(Method(m) is Method.H for m in methods)
        plane_floor = min(policy.min_plane_residual_sigma, threshold) if wants_h else threshold
        residual = rotation_test(
            ref, cur, K, enough_below=plane_floor, radial_terms=config.radial_terms
        )
        if not residual.statistic >= plane_floor:
            return FireResult(
                Reason.ROTATION,
                f'a rotation alone explains the flow (median residual {residual.residual_px:.2f}'
                f' px, {residual.statistic:.1f} x the noise {residual.noise_px:.2f} px < '
                f'{plane_floor:g} x)',
                residual,
            )
        if not residual.statistic >= threshold:
            return _plane_alone(ref, cur, K, config, residual)
    return _estimate_and_choose(ref, cur, K, methods, config, residual)


def _plane_alone(
    ref: np.ndarray, cur: np.ndarray, K: np.ndarray, config: FireConfig, residual: RotationTest
) -> FireResult:
    """The fire path with H alone, for a rotation test between ``min_plane_residual_sigma``
    and ``min_rotation_residual_sigma``: parallax for a plane's perspective change, not yet
    for E and F. An H that triangulates less than ``min_homography_plane_share`` of the
    tracks fits one part of a scene with depth, E's domain: refused as a rotation."""
    policy = config.policy
    threshold = policy.min_rotation_residual_sigma
    measured = f'the rotation test measured {residual.statistic:.1f} x the noise'
    plane = _estimate(Method.H, ref, cur, K, config)
    if plane.ok and plane_share(plane) < policy.min_homography_plane_share:
        return FireResult(
            Reason.ROTATION,
            f'{measured}: parallax for a plane, but H holds {plane_share(plane):.0%} of the '
            f'tracks (< {policy.min_homography_plane_share:.0%}): the rest has depth, and E and '
            f'F need {threshold:g} x',
            residual,
            (plane,),
            (check_pose(plane, policy),),
        )
    fire = _estimate_and_choose(ref, cur, K, (Method.H,), config, residual, (plane,))
    note = f'({measured}: parallax for H, not yet for E and F, which need {threshold:g} x)'
    return replace(fire, detail=f'{fire.detail} {note}'.strip())


def _estimate_and_choose(
    ref: np.ndarray,
    cur: np.ndarray,
    K: np.ndarray,
    methods: Sequence[Method | str],
    config: FireConfig,
    residual: RotationTest | None,
    estimates: tuple[PoseEstimate, ...] | None = None,
) -> FireResult:
    """The fire path after the rotation test: estimates (``estimates`` when already made,
    one per method), pose check, GRIC, background test, the plane and decomposition tests,
    and the seed map (see :func:`initialize_pair`)."""
    policy = config.policy
    if estimates is None:
        estimates = tuple(_estimate(m, ref, cur, K, config) for m in methods)
    if residual is not None:
        estimates = tuple(_plane_or_relief(e, ref, cur, K, policy) for e in estimates)
    checks = tuple(check_pose(e, policy) for e in estimates)
    low_essential = _low_essential_parallax(estimates, checks)
    if low_essential is not None:
        checks = tuple(
            Reason.LOW_PARALLAX if e.method is Method.F and c is None else c
            for e, c in zip(estimates, checks, strict=True)
        )
    passed = [e for e, c in zip(estimates, checks, strict=True) if c is None]
    first_problem = next((c for c in checks if c is not None), Reason.POSE_FAILED)
    if not config.select:
        reason = Reason.INITIALIZED if passed else first_problem
        return FireResult(reason, '', residual, estimates, checks)
    problems = [
        _problem_text(e, c, policy, low_essential) for e, c in zip(estimates, checks, strict=True)
    ]
    selection = select_method(estimates, problems, ref, cur, K)
    if selection.winner is None:
        return FireResult(
            first_problem, selection.summary(), residual, estimates, checks, selection
        )
    winner = next(e for e in estimates if e.method is selection.winner)
    background = None
    if residual is not None and config.background_test:
        threshold = policy.min_rotation_residual_sigma
        background = background_test(winner, ref, cur, K, residual.noise_px, threshold)
        if (
            background is not None
            and background.statistic < threshold
            and not _rest_moves_with_winner(winner, ref, cur, K, background, config)
        ):
            n_out = int(np.count_nonzero(~np.asarray(winner.inliers, dtype=bool)))
            return FireResult(
                Reason.ROTATION,
                f'{selection.winner.value} fits {len(ref) - n_out} tracks, and a rotation alone'
                f' explains the other {n_out} (median residual {background.residual_px:.2f} px,'
                f' {background.statistic:.1f} x the noise {background.noise_px:.2f} px < '
                f'{threshold:g} x): the camera only rotated and {selection.winner.value} fits'
                ' an object moving on its own, or the baseline is too short yet for the rest'
                ' of the scene',
                residual,
                estimates,
                checks,
                selection,
                background=background,
            )
    if residual is not None and config.background_test:
        support = motion_support(
            winner, ref, cur, K, residual.noise_px, config.ransac_threshold_px
        )
        if _second_motion(support, len(ref)):
            name = selection.winner.value
            return FireResult(
                Reason.POSE_FAILED,
                f'{name} failed (two motions: of the {support.measurable} tracks with '
                f'parallax, {support.contradicting} contradict its motion, behind the cameras '
                f'or off its epipolar lines, against {support.supporting} that support it: it '
                'fits an object moving on its own, or the rest of the scene does)',
                residual,
                estimates,
                checks,
                selection,
                background=background,
            )
    noise_px = residual.noise_px if residual is not None else 0.0
    plane = _better_model_not_ready(selection, estimates, checks, ref, cur, policy, noise_px)
    if plane is not None:
        return FireResult(
            plane[0], plane[1], residual, estimates, checks, selection, background=background
        )
    as_plane = plane_is_the_scene(winner, policy)
    winner = _decomposition_by_the_rest(winner, ref, cur, K, config.ransac_threshold_px)
    seed = seed_map(
        winner,
        ref,
        cur,
        K,
        refine=config.refine,
        max_reprojection_px=config.map_max_reprojection_px,
        as_plane=as_plane,
    )
    rival = winner.alternative  # (it passed the pose check, or it would be None)
    other = usable_seed(rival, ref, cur, K, config) if rival is not None else None
    alternatives: tuple[SeedMap, ...] = (other,) if other is not None else ()
    refusal = None
    if seed.n_points < policy.min_points:
        refusal = (
            Reason.TOO_FEW_POINTS,
            f'{seed.n_points} points left after refinement; ' + selection.summary(),
        )
    elif not _direction_known(seed, config):
        sigma = seed.translation_sigma_deg
        known = f'only to +-{sigma:.1f} deg' if math.isfinite(sigma) else 'not at all'
        refusal = (
            Reason.LOW_PARALLAX,
            f'{selection.winner.value} fixes the direction of motion {known}'
            f' (max {policy.max_translation_sigma_deg:g} deg): the baseline is too short yet; '
            + selection.summary(),
        )
    elif rival is not None and other is None:
        # the frames after an ambiguous pair tell its decompositions apart; one that cannot
        # be followed yet leaves the other's verification proving nothing
        refusal = (
            Reason.LOW_PARALLAX,
            f'{selection.winner.value}: its two decompositions are close, and the runner-up '
            'has no usable seed map yet (too few points, or its direction of motion too '
            'uncertain) for the next frames to choose between them; ' + selection.summary(),
        )
    if refusal is not None:
        return FireResult(
            *refusal, residual, estimates, checks, selection, seed, background=background
        )
    why = selection.why
    if alternatives:
        why += '; its two decompositions are close: the next frames choose'
    return FireResult(
        Reason.INITIALIZED,
        why,
        residual,
        estimates,
        checks,
        selection,
        seed,
        alternatives,
        background,
    )


#: An H's two decompositions are told apart by the tracks off its plane when at least this
#: many of them are evidence: clearly off the plane, and on one motion's epipolar lines
#: (squared Sampson error within the estimators' RANSAC threshold squared; a mistrack or an
#: object moving on its own fits neither) ...
OFF_PLANE_MIN_TRACKS = 5
#: ... "clearly off the plane" meaning more than ``geometry.OFF_PLANE_MIN_PX`` from where H
#: puts them (the distance within which the decomposition test counts a point as on its
#: plane, ``geometry.estimate_pose``'s ``max_reprojection_px``); nearer, a tracking error
#: decides which motion's lines a track lies on ...
#: ... when one motion's median Sampson error on them is this many times smaller than the
#: other's ...
OFF_PLANE_MIN_RATIO = 3.0
#: ... and the other misses them clearly: its median at least (this x the RANSAC threshold)
#: squared, not by a tracking error.
OFF_PLANE_MIN_MISS = 2.0


def _rest_moves_with_winner(
    winner: PoseEstimate,
    ref: np.ndarray,
    cur: np.ndarray,
    K: np.ndarray,
    background: RotationTest,
    config: FireConfig,
) -> bool:
    """Do the tracks ``winner`` left out, which a rotation explains to under the bar but at
    least ``min_plane_residual_sigma`` of the noise (parallax, though little), move as its
    motion says: a motion's worth of them with parallax beyond its rotation, on its epipolar
    lines and in front of both cameras, more than contradict it? Then the rest of the scene
    is static and seen with the winner's baseline (a plane's H leaving out a table below it),
    not the background of an object moving on its own, whose flow a camera's rotation is."""
    if background.statistic < config.policy.min_plane_residual_sigma:
        return False
    outside = ~np.asarray(winner.inliers, dtype=bool)
    support = motion_support(
        winner, ref[outside], cur[outside], K, background.noise_px, config.ransac_threshold_px
    )
    return support.supporting > support.contradicting and _a_motions_worth(
        support.supporting, int(np.count_nonzero(outside))
    )


def _second_motion(support: MotionSupport, n_tracks: int) -> bool:
    """Do the tracks that contradict a winner's motion outnumber those that support it, and
    are they a motion's worth (:func:`_a_motions_worth`), not mistracks?"""
    against = support.contradicting
    return against > support.supporting and _a_motions_worth(against, n_tracks)


def _a_motions_worth(count: int, n_tracks: int) -> bool:
    """Are ``count`` of ``n_tracks`` tracks enough to be a motion of their own: at least
    :data:`BACKGROUND_MIN_TRACKS` and :data:`BACKGROUND_MIN_SHARE` of them?"""
    return count >= max(BACKGROUND_MIN_TRACKS, BACKGROUND_MIN_SHARE * n_tracks)


def _decomposition_by_the_rest(
    winner: PoseEstimate,
    ref: np.ndarray,
    cur: np.ndarray,
    K: np.ndarray,
    inlier_px: float = 1.0,
) -> PoseEstimate:
    """Of an H whose two decompositions are close, the one the tracks off its plane confirm.

    Both motions explain the plane's points alike (that is the ambiguity); a static point off
    the plane lies on the epipolar lines of the true motion only. The evidence is the tracks
    H left out that lie more than ``geometry.OFF_PLANE_MIN_PX`` from where H puts them and that
    one of the two motions explains (squared Sampson error within ``inlier_px`` squared, the
    estimators' RANSAC threshold). On a plane alone the tracks H leaves out are mistracks,
    which fit neither motion, and tracks a pixel or two off the plane, whose error decides
    which motion's lines they lie on. When at least :data:`OFF_PLANE_MIN_TRACKS` tracks are
    evidence, they sit clearly nearer one motion's epipolar lines (median Sampson error
    :data:`OFF_PLANE_MIN_RATIO` times smaller), and the other misses them by more than a
    tracking error (:data:`OFF_PLANE_MIN_MISS` x ``inlier_px``, squared), that decomposition
    is kept alone; otherwise both go on to the verification.
    """
    rival = winner.alternative
    if winner.method is not Method.H or rival is None:
        return winner
    off = ~np.asarray(winner.inliers, dtype=bool)
    if off.shape != (len(ref),) or np.count_nonzero(off) < OFF_PLANE_MIN_TRACKS:
        return winner
    a, b = ref[off], cur[off]
    errors = [
        sampson_fundamental(fundamental_from_essential(skew(e.t) @ e.R, K), a, b)
        for e in (winner, rival)
    ]
    off_plane = transfer_px(winner.matrix, a, b) > OFF_PLANE_MIN_PX
    explained = off_plane & (np.minimum(*errors) <= inlier_px * inlier_px)
    if np.count_nonzero(explained) < OFF_PLANE_MIN_TRACKS:
        return winner
    first, second = (float(np.median(e[explained])) for e in errors)
    miss = (OFF_PLANE_MIN_MISS * inlier_px) ** 2
    if first * OFF_PLANE_MIN_RATIO <= second and second >= miss:
        return replace(winner, alternative=None)
    if second * OFF_PLANE_MIN_RATIO <= first and first >= miss:
        return replace(rival, alternative=None)
    return winner


def _better_model_not_ready(
    selection: Selection,
    estimates: Sequence[PoseEstimate],
    checks: Sequence[Reason | None],
    ref: np.ndarray,
    cur: np.ndarray,
    policy: PolicyConfig,
    noise_px: float = 0.0,
) -> tuple[Reason, str] | None:
    """Why the winner is refused because the other kind of model fits better, or None.

    GRIC scores every estimate with a matrix, the ones that failed the pose check too. When
    a failed H scores lower than the E or F that won, the tracks are a plane (or as good as
    one at this baseline), where E and F are degenerate (every ``[e']_x H`` fits a plane's
    points, for any epipole e'); when a failed E or F scores lower than the H that won, the
    tracks have depth that H's plane does not explain. Either way the winner won only
    because the model that fits did not pass yet: the pair waits, with that model's reason.

    GRIC caps what a track off the plane costs H, so a plane holding two thirds of the
    tracks can score lower than E however far off the rest lie. Those tracks, where the
    winner triangulates them with parallax, are the depth that makes E or F well-posed. Where
    at least :data:`BACKGROUND_MIN_TRACKS` of them lie off H's plane
    (:func:`off_plane_support`, ``noise_px`` the tracking noise) and H's plane keeps less
    than ``policy.min_homography_plane_share`` of the tracks (the share the pose check asks
    of H for its plane to be the scene), the winner stands.
    """
    scores = {s.method: s for s in selection.scores}
    won = scores.get(selection.winner) if selection.winner is not None else None
    if won is None:
        return None
    rivals = (Method.E, Method.F) if won.method is Method.H else (Method.H,)
    better = [
        s for m in rivals if (s := scores.get(m)) is not None and not s.ok and s.gric < won.gric
    ]
    if not better:
        return None
    best = min(better, key=lambda s: s.gric)
    kind = 'a plane' if best.method is Method.H else 'not a plane'
    depth = ''
    if best.method is Method.H:
        winner = next(e for e in estimates if e.method is won.method)
        plane = next(e for e in estimates if e.method is Method.H)
        off = off_plane_support(winner, plane, ref, cur, noise_px)
        kept = policy.min_homography_plane_share * len(ref)  # what a scene's plane holds
        if off >= BACKGROUND_MIN_TRACKS and len(ref) - off < kept:
            return None
        depth = (
            f'; {off} of {len(ref)} tracks lie off its plane, triangulated by {won.method.value}'
        )
    reason = next(
        (c for e, c in zip(estimates, checks, strict=True) if e.method is best.method), None
    )
    return (
        reason or Reason.POSE_FAILED,
        f'the tracks are {kind} (GRIC {best.method.value} {best.gric:.0f} < '
        f'{won.method.value} {won.gric:.0f}{depth}), and {best.method.value} is not ready: '
        f'{best.problem}',
    )


def off_plane_support(
    winner: PoseEstimate,
    plane: PoseEstimate,
    ref: np.ndarray,
    cur: np.ndarray,
    noise_px: float = 0.0,
) -> int:
    """How many of the points the E or F ``winner`` triangulated (in front of both cameras,
    with parallax: its ``indices`` into ``ref`` and ``cur``) lie clearly off the plane of the
    homography ``plane``: farther from where it puts them than ``geometry.OFF_PLANE_MIN_PX`` and
    ``geometry.OFF_PLANE_NOISE_FACTOR`` times the tracking noise ``noise_px`` (per coordinate);
    0 when H has no matrix.

    Only triangulated points count: a track that a rotation moves (a background at infinity,
    or the far scene of a pan) fits every epipolar geometry with that rotation, and lies off
    a near plane's homography without showing any depth.
    """
    if not np.any(plane.matrix) or winner.indices.size == 0:
        return 0
    bound = OFF_PLANE_MIN_PX
    if math.isfinite(noise_px):
        bound = max(bound, OFF_PLANE_NOISE_FACTOR * noise_px)
    index = winner.indices
    on = transfer_px(plane.matrix, ref[index], cur[index]) <= bound  # (NaN, inf: off)
    return int(np.count_nonzero(~on))


def plane_is_the_scene(estimate: PoseEstimate, policy: PolicyConfig) -> bool:
    """An H whose plane holds the scene: it triangulates at least
    ``policy.min_homography_plane_share`` of the tracks, and its decomposition is unique (no
    close runner-up kept beside it, nor refused as ambiguous). Its seed map is refined as one
    plane where the tracks show no relief (:func:`seed_map`'s ``as_plane``).

    On part of the scene, the rest has depth the plane's pose ignores (a desk's papers on the
    floor, half its tracks, before a bent poster: E_t 0.041 as a plane, 0.012 with free
    depths). And the planar model's uncertainty is local to one decomposition: where the
    two-fold ambiguity is open, the direction of motion is one of two, which no local standard
    deviation says (on the same desk seen from 4-5 cm, a plane's mirrored decomposition, E_t
    1.1, passed 2 degrees under the planar model). There the bundle adjustment with free
    depths refines, as for E and F, and its wider uncertainty holds the map back.
    """
    return (
        estimate.method is Method.H
        and estimate.alternative is None
        and not estimate.ambiguous
        and plane_share(estimate) >= policy.min_homography_plane_share
    )


def usable_seed(
    estimate: PoseEstimate, ref: np.ndarray, cur: np.ndarray, K: np.ndarray, config: FireConfig
) -> SeedMap | None:
    """The seed map of ``estimate`` (its pose and points, as ``estimate.ok`` would have them)
    when it keeps the policy's ``min_points`` and fixes its direction of motion within
    ``max_translation_sigma_deg``; None otherwise."""
    seed = seed_map(
        replace(estimate, ok=True, reason=''),
        ref,
        cur,
        K,
        refine=config.refine,
        max_reprojection_px=config.map_max_reprojection_px,
    )
    if seed.n_points >= config.policy.min_points and _direction_known(seed, config):
        return seed
    return None


def _direction_known(seed: SeedMap, config: FireConfig) -> bool:
    """The refined seed map fixes its direction of motion to within the policy's bound
    (always true without refinement, which is where the bound is measured, or without a
    bound). A covariance that could not be computed is no knowledge."""
    bound = config.policy.max_translation_sigma_deg
    if not config.refine or not bound > 0.0:
        return True
    return seed.translation_sigma_deg <= bound


@dataclass(frozen=True)
class MotionSupport:
    """How the tracks with parallax side with one estimate's motion (:func:`motion_support`).

    Attributes:
        supporting: tracks with parallax on the motion's epipolar lines and in front of both
            cameras.
        contradicting: tracks with parallax off its lines or behind a camera: a second motion
            when they are many (an object moving on its own, or the background while the
            estimate fits the object), else mistracks.
        measurable: tracks whose flow left after the estimate's rotation is above
            :data:`MOTION_MIN_PARALLAX_SIGMA` times the noise (and 1 px): the others cannot
            say which way the camera moved.
    """

    supporting: int
    contradicting: int
    measurable: int


#: A track takes part in :func:`motion_support` when the flow the estimate's rotation leaves
#: is at least this many times the tracking noise (and at least 1 px): under it, the sign of
#: its depth is the noise's.
MOTION_MIN_PARALLAX_SIGMA = 3.0


def motion_support(
    estimate: PoseEstimate,
    ref: np.ndarray,
    cur: np.ndarray,
    K: np.ndarray,
    noise_px: float,
    inlier_px: float = 1.0,
) -> MotionSupport:
    """Count the tracks with parallax that support ``estimate``'s motion and those that
    contradict it (see :class:`MotionSupport`): on its epipolar lines means a squared Sampson
    error within ``(2 inlier_px)^2`` (twice the estimators' RANSAC threshold).

    The epipolar lines alone cannot tell a camera sliding left past a static scene from one
    sliding right along an object that overtakes it: both flows lie on the same lines. The
    depths can: the tracks of the motion not estimated triangulate behind the cameras.
    """
    R, t = estimate.R, estimate.t
    a, b = np.asarray(ref, dtype=np.float64), np.asarray(cur, dtype=np.float64)
    K_inv = np.linalg.inv(K)
    turned = homogeneous(a) @ K_inv.T @ R.T  # the reference rays, rotated by the estimate
    rays = homogeneous(b) @ K_inv.T
    projected = turned @ K.T
    with np.errstate(divide='ignore', invalid='ignore'):
        left = np.linalg.norm(b - projected[:, :2] / projected[:, 2:3], axis=1)
    floor = max(MOTION_MIN_PARALLAX_SIGMA * noise_px, 1.0) if math.isfinite(noise_px) else 1.0
    measurable = np.nan_to_num(left, nan=0.0) >= floor
    if not np.any(measurable) or not np.linalg.norm(t) > 0:
        return MotionSupport(0, 0, int(np.count_nonzero(measurable)))
    on_lines = (
        sampson_fundamental(
            fundamental_from_essential(skew(t) @ R, K), a[measurable], b[measurable]
        )
        <= (2.0 * inlier_px) ** 2
    )
    agrees = on_lines & _in_front(turned[measurable], rays[measurable], t)
    supporting = int(np.count_nonzero(agrees))
    n = int(np.count_nonzero(measurable))
    return MotionSupport(supporting, n - supporting, n)


def _in_front(turned: np.ndarray, rays: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(N,) bool: the depths ``d0 R x0 - d1 x1 = -t`` of each pair of rays (``turned``: the
    reference rays ``R x0``; ``rays``: ``x1``) are positive (least squares by cross products;
    :func:`geometry.triangulate_pair`'s sign, without its points and errors)."""
    n = np.cross(rays, turned)  # crossed with x1: d0 (R x0 x x1) = -(t x x1); with R x0: alike
    d0 = -np.einsum('ij,ij->i', np.cross(rays, t), n)
    d1 = np.einsum('ij,ij->i', np.cross(t, turned), n)
    return (d0 > 0) & (d1 > 0)


def background_test(
    winner: PoseEstimate,
    ref: np.ndarray,
    cur: np.ndarray,
    K: np.ndarray,
    noise_px: float,
    threshold: float,
) -> RotationTest | None:
    """The rotation test of the tracks ``winner`` leaves out, against ``noise_px`` (the noise
    of all tracks), or None when it did not run: they are fewer than
    :data:`BACKGROUND_MIN_TRACKS` or :data:`BACKGROUND_MIN_SHARE` of all tracks, or the noise
    or the statistic is not finite.

    A static scene seen from a translating camera leaves out mismatches, noisy tracks and
    (for H) the points off its plane, which show parallax; a still or panning camera whose
    winner fits a moving object leaves out the background, which one rotation explains. Points
    whose parallax is still under the noise pass for a rotation too: an H on one plane of a
    scene whose other points show no parallax yet waits for more baseline (on the README's
    desk sequence E then wins a frame later, the better method more often).
    """
    outside = ~np.asarray(winner.inliers, dtype=bool)
    if outside.shape != (len(ref),) or not math.isfinite(noise_px):
        return None  # (an estimate's inlier mask always has one entry per correspondence)
    n_out = int(np.count_nonzero(outside))
    if not _a_motions_worth(n_out, len(ref)):
        return None
    test = rotation_test(ref[outside], cur[outside], K, enough_below=threshold, noise_px=noise_px)
    return test if math.isfinite(test.statistic) else None


__all__ = [
    'BACKGROUND_MIN_SHARE',
    'BACKGROUND_MIN_TRACKS',
    'ESTIMATES_ONLY',
    'MAP_MAX_REPROJECTION_PX',
    'MOTION_MIN_PARALLAX_SIGMA',
    'FireConfig',
    'FireResult',
    'MotionSupport',
    'SeedMap',
    'background_test',
    'fire_methods',
    'initialize_pair',
    'motion_support',
    'plane_is_the_scene',
    'radial_terms_for',
    'seed_map',
    'usable_seed',
]
