"""Camera effects of the renderer, each checked against its physics."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest
import yaml

from initsel_ros.camera import Intrinsics
from initsel_ros.datasets import open_sequence
from initsel_ros.errors import ConfigError
from initsel_ros.synth import Effects, render
from initsel_ros.synth.effects import ramp_gains
from initsel_ros.synth.realism import EFFECT_LEVELS, REALISM_RANGES, draw_realism, effect_level
from initsel_ros.synth.render import Distorter
from initsel_ros.synth.scene import Scene, make_plane
from initsel_ros.synth.sensor import PoseTrack, SensorRenderer
from initsel_ros.synth.textures import repeated_texture

CAM = Intrinsics.tum_fr3()
F = CAM.fx
DEPTH = 1.0  # metres from the camera to the test plane


def _plane_scene(texture: np.ndarray, ppm: float = 1000.0, z: float = DEPTH) -> Scene:
    """One plane facing the camera at world z = ``z``, texture centred on the optical axis."""
    h, w = texture.shape[:2]
    origin = [-w / 2 / ppm, -h / 2 / ppm, z]
    plane = make_plane('test', origin, [1, 0, 0], [0, 1, 0], texture, ppm)
    return Scene('test', (plane,), np.array([0.0, 0.0, z]))


def _edge_texture(size: int = 3000, ramp: int = 0) -> np.ndarray:
    """Dark left half, bright right half: a vertical edge at world x = 0 (a step, or a linear
    ramp over ``ramp`` texture pixels, for sub-pixel edge positions)."""
    x = np.arange(size) - size / 2  # texture pixel size / 2 is at world x = 0
    level = 40 + 160 * np.clip(x / max(ramp, 1e-9) + 0.5, 0, 1)
    tex = np.repeat(np.round(level).astype(np.uint8)[None, :], size, axis=0)
    return np.repeat(tex[..., None], 3, axis=2)


def _track(n: int, position=None, rotation=None, rate: float = 30.0) -> PoseTrack:
    """Poses at ``rate`` Hz; ``position(t)`` (3,) and ``rotation(t)`` (3, 3) camera-to-world."""
    stamps = np.arange(n) / rate
    poses = np.tile(np.eye(4), (n, 1, 1))
    for i, t in enumerate(stamps):
        if position is not None:
            poses[i, :3, 3] = position(t)
        if rotation is not None:
            poses[i, :3, :3] = rotation(t)
    return PoseTrack(stamps, poses)


def _sensor(
    scene: Scene, effects: Effects, track: PoseTrack, camera: Intrinsics = CAM, seed: int = 0
) -> SensorRenderer:
    return SensorRenderer(scene, camera, effects, track, np.random.default_rng(seed))


def _edge_spread(gray: np.ndarray, rows: slice) -> tuple[float, float]:
    """(centre, standard deviation) in pixels of the derivative of the mean row profile."""
    profile = gray[rows].astype(np.float64).mean(axis=0)
    d = np.abs(np.diff(profile))
    x = np.arange(len(d)) + 0.5
    w = d / d.sum()
    centre = float((w * x).sum())
    return centre, float(np.sqrt((w * (x - centre) ** 2).sum()))


@pytest.mark.parametrize('exposure_time', [0.01, 0.02])
def test_motion_blur_length_is_velocity_times_exposure_over_depth_times_focal(exposure_time):
    velocity = 0.6  # m/s along the camera x axis, in front of a plane 1 m away
    scene = _plane_scene(_edge_texture())
    track = _track(4, position=lambda t: np.array([velocity * t, 0.0, 0.0]))
    sharp = _sensor(scene, Effects(noise=0.0), track).frame(2)[0]
    blurred = _sensor(scene, Effects(noise=0.0, exposure_time=exposure_time), track).frame(2)[0]
    rows = slice(200, 280)
    c0, s0 = _edge_spread(cv2.cvtColor(sharp, cv2.COLOR_BGR2GRAY), rows)
    c1, s1 = _edge_spread(cv2.cvtColor(blurred, cv2.COLOR_BGR2GRAY), rows)
    expected = velocity * exposure_time / DEPTH * F  # 3.2 and 6.4 px
    # a box of length L has variance L^2 / 12, added to the sharp edge's own spread
    length = np.sqrt(12 * (s1**2 - s0**2))
    assert length == pytest.approx(expected, rel=0.08)
    # the frame time is the middle of the exposure: the blurred edge is centred on the sharp one
    assert c1 == pytest.approx(c0, abs=0.15)
    assert c0 == pytest.approx(CAM.cx - F * velocity * track.stamps[2] / DEPTH, abs=0.3)


def _rotation_y(omega: float):
    def rot(t: float) -> np.ndarray:
        c, s = np.cos(omega * t), np.sin(omega * t)
        return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])

    return rot


def _edge_columns(gray: np.ndarray, level: float = 120.0) -> np.ndarray:
    """Sub-pixel column of the dark-to-bright crossing of ``level`` in every row."""
    g = gray.astype(np.float64)
    out = np.full(g.shape[0], np.nan)
    for r, row in enumerate(g):
        above = np.flatnonzero((row[:-1] < level) & (row[1:] >= level))
        if len(above):
            i = above[np.argmin(np.abs(above - len(row) / 2))]
            out[r] = i + (level - row[i]) / (row[i + 1] - row[i])
    return out


@pytest.mark.parametrize('exposure_time', [0.0, 0.01])
def test_rolling_shutter_leans_a_vertical_edge_by_focal_times_pan_rate_times_readout(
    exposure_time,
):
    omega, line_delay = 0.5, 40e-6  # rad/s pan about the camera y axis; s per row
    scene = _plane_scene(_edge_texture(ramp=8))
    track = _track(4, rotation=_rotation_y(omega))
    effects = Effects(noise=0.0, line_delay=line_delay, exposure_time=exposure_time)
    image = _sensor(scene, effects, track).frame(2)[0]
    cols = _edge_columns(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY))
    H = CAM.height
    rows = np.arange(20, H - 20)
    # row r is exposed at t_r = t + (r - (H - 1) / 2) * line_delay; the edge (world x = 0)
    # then projects to u = cx - f tan(omega t_r)
    t_rows = track.stamps[2] + (rows - (H - 1) / 2) * line_delay
    expected = CAM.cx - F * np.tan(omega * t_rows)
    lean = np.polyfit(rows, cols[rows], 1)[0] * (H - 1)
    assert lean == pytest.approx(-F * omega * (H - 1) * line_delay, rel=0.05)  # -5.1 px
    assert np.max(np.abs(cols[rows] - expected)) < 0.4
    global_shutter = _sensor(scene, Effects(noise=0.0), track).frame(2)[0]
    still = _edge_columns(cv2.cvtColor(global_shutter, cv2.COLOR_BGR2GRAY))
    assert abs(np.polyfit(rows, still[rows], 1)[0] * (H - 1)) < 0.1


def _stripes(levels: np.ndarray, width: int = 200, height: int = 2000) -> np.ndarray:
    tex = np.repeat(levels.astype(np.uint8), width)[None, :].repeat(height, axis=0)
    return np.repeat(tex[..., None], 3, axis=2)


@pytest.mark.parametrize('gain', [1.0, 2.0])
def test_shot_noise_variance_grows_linearly_with_intensity_as_gain_over_full_well(gain):
    levels = np.linspace(15, 120, 8)  # grey levels of the stripes (times the gain, unsaturated)
    stripe_px = 200 * F / 1000.0 / 1.5  # stripe width in pixels at 1.5 m
    scene = _plane_scene(_stripes(levels), z=1.5)
    read, full_well = 2.0, 5000.0
    effects = Effects(noise=read, full_well=full_well, gain_ramp=(gain, gain, 0.0))
    image = _sensor(scene, effects, _track(2)).frame(0)[0].astype(np.float64)
    means, variances = [], []
    first = CAM.cx - len(levels) / 2 * stripe_px
    for k in range(len(levels)):
        x0 = int(first + (k + 0.25) * stripe_px)
        x1 = int(first + (k + 0.75) * stripe_px)
        patch = image[60:420, x0:x1]
        means.append(patch.mean())
        variances.append(patch.var())
    slope, intercept = np.polyfit(means, variances, 1)
    assert np.allclose(means, levels * gain, atol=0.3)
    # variance = gain * 255 / full_well * I + read^2 (grey levels squared)
    assert slope == pytest.approx(gain * 255 / full_well, rel=0.1)
    assert intercept == pytest.approx(read**2 + 1 / 12, abs=0.6)  # + 8-bit quantization


def test_read_noise_alone_is_flat_in_intensity():
    levels = np.linspace(20, 220, 6)
    scene = _plane_scene(_stripes(levels), z=1.5)
    image = _sensor(scene, Effects(noise=3.0, vignetting=0.0), _track(2)).frame(0)[0]
    stripe_px = 200 * F / 1000.0 / 1.5
    first = CAM.cx - len(levels) / 2 * stripe_px
    var = [
        image[60:420, int(first + (k + 0.25) * stripe_px) : int(first + (k + 0.75) * stripe_px)]
        .astype(float)
        .var()
        for k in range(len(levels))
    ]
    assert np.allclose(var, 9.0, rtol=0.12)


def test_vignetting_follows_cos4_of_the_ray_angle():
    flat = np.full((4000, 4000, 3), 200, np.uint8)
    scene = _plane_scene(flat, ppm=1000.0)
    strength = 0.6
    image = _sensor(scene, Effects(noise=0.0, vignetting=strength), _track(2)).frame(0)[0]
    ys, xs = np.mgrid[0 : CAM.height, 0 : CAM.width]
    tan2 = ((xs - CAM.cx) / CAM.fx) ** 2 + ((ys - CAM.cy) / CAM.fy) ** 2
    expected = 200 * (1 - strength * (1 - 1 / (1 + tan2) ** 2))
    assert np.max(np.abs(image[..., 1] - expected)) <= 0.51
    assert image[0, 0, 1] < 0.75 * image[240, 320, 1]  # corners clearly darker


def test_gain_ramp_scales_the_frames_as_auto_exposure_does(tmp_path):
    g = ramp_gains(np.array([0.0, 0.5, 1.0, 2.0, 3.0]), (0.6, 1.4, 2.0))
    assert np.allclose(g, [0.6, 0.8, 1.0, 1.4, 1.4])
    assert np.allclose(ramp_gains(np.array([0.0, 1.0, 1.5]), (1.0, 2.0, 1.0, 0.5)), [1, 1.5, 2])
    path = render(
        tmp_path / 'ramp',
        scene='wall',
        trajectory='static',
        frames=61,
        effects=Effects(noise=0.0, gain_ramp=(0.6, 1.4, 2.0)),
    ).path
    seq = open_sequence(path)
    dark = seq.gray(0).astype(float)
    unsaturated = (dark > 5) & (dark < 150)  # below 255 at the gain 1.4 as well
    for i in (15, 30, 60):
        gain = 0.6 + 0.8 * min(i / 30 / 2.0, 1.0)
        ratio = np.median(seq.gray(i)[unsaturated] / dark[unsaturated])
        assert ratio == pytest.approx(gain / 0.6, rel=0.02)


def test_jpeg_frames_are_written_as_jpeg_and_lose_more_at_lower_quality(tmp_path):
    png = open_sequence(
        render(tmp_path / 'png', trajectory='static', frames=1, effects=Effects(noise=0.0)).path
    )
    clean = png.image(0)
    errors = {}
    for q in (90, 40):
        path = render(
            tmp_path / f'q{q}',
            trajectory='static',
            frames=1,
            effects=Effects(noise=0.0, jpeg_quality=q),
        ).path
        files = list((path / 'rgb').iterdir())
        assert files[0].suffix == '.jpg' and files[0].read_bytes()[:2] == b'\xff\xd8'
        assert '.jpg' in (path / 'rgb.txt').read_text()
        frame = open_sequence(path).image(0)
        # the last step of the camera: the final 8-bit frame compressed at quality q
        _, data = cv2.imencode('.jpg', clean, [cv2.IMWRITE_JPEG_QUALITY, q])
        assert np.array_equal(frame, cv2.imdecode(data, cv2.IMREAD_COLOR))
        errors[q] = np.sqrt(np.mean((frame.astype(float) - clean) ** 2))
    assert 0.5 < errors[90] < errors[40]


def test_barrel_distortion_renders_without_empty_borders_and_writes_d(tmp_path):
    dist = (-0.28, 0.08, 1e-3, -1e-3)
    path = render(
        tmp_path / 'barrel',
        scene='wall',
        trajectory='arc',
        frames=2,
        distortion=dist,
        effects=Effects(noise=0.0),
        bags=('ros2',),
    ).path
    seq = open_sequence(path)
    assert seq.intrinsics.distortion == dist
    assert yaml.safe_load((path / 'intrinsics.yaml').read_text())['distortion'] == list(dist)
    assert (seq.depth(0) > 0).all()  # the wall fills the distorted view, corners included
    bag = open_sequence(path / 'sequence_ros2')
    assert bag.intrinsics.distortion == pytest.approx(dist)
    # a sensor pixel shows the ideal ray that the OpenCV model maps onto it
    d = Distorter(dataclasses.replace(CAM, distortion=dist))
    rays = np.column_stack(
        [
            (d.map_x.ravel() - d.canvas.cx) / CAM.fx,
            (d.map_y.ravel() - d.canvas.cy) / CAM.fy,
            np.ones(d.map_x.size),
        ]
    )
    proj, _ = cv2.projectPoints(
        rays[::97].reshape(-1, 1, 3), np.zeros(3), np.zeros(3), CAM.K, np.array(dist)
    )
    grid = np.mgrid[0 : CAM.height, 0 : CAM.width][::-1].reshape(2, -1).T[::97]
    assert np.max(np.abs(proj.reshape(-1, 2) - grid)) < 0.01


def test_distortion_that_folds_the_image_is_rejected():
    with pytest.raises(ConfigError, match='one-to-one'):
        Distorter(dataclasses.replace(CAM, distortion=(-0.4, 0.0, 0.0, 0.0)))


def test_movers_change_only_their_own_pixels_and_move_on_their_own(tmp_path):
    base = render(
        tmp_path / 'still', trajectory='static', frames=30, effects=Effects(noise=0.0)
    ).path
    moving = render(
        tmp_path / 'movers', trajectory='static', frames=30, effects=Effects(noise=0.0, movers=3)
    ).path
    a, b = open_sequence(base), open_sequence(moving)
    masks = []
    for i in (0, 29):
        mover = a.depth(i) != b.depth(i)
        assert 0.02 < mover.mean() < 0.6
        assert np.all(b.depth(i)[mover] < a.depth(i)[mover] + 1e-3)  # in front of the scene
        same = ~cv2.dilate(mover.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        assert np.array_equal(a.image(i)[same], b.image(i)[same])
        masks.append(mover)
    assert (masks[0] != masks[1]).mean() > 0.01  # the camera is still, the boards moved
    assert yaml.safe_load((moving / 'effects.yaml').read_text())['movers'] == 3


def test_repeated_texture_is_periodic_and_the_scene_has_many_corners(tmp_path):
    tex = repeated_texture(np.random.default_rng(3), 400, 300, 40)
    assert np.array_equal(tex[:, 40:], tex[:, :-40]) and np.array_equal(tex[40:], tex[:-40])
    assert not np.array_equal(tex[:, 20:], tex[:, :-20])
    seq = open_sequence(
        render(tmp_path / 'rep', scene='repeated', trajectory='near', frames=1, start=80).path
    )
    corners = cv2.goodFeaturesToTrack(seq.gray(0), 300, 0.01, 8)
    assert len(corners) >= 200


def test_realism_draws_are_seeded_in_range_and_varied():
    draws = [draw_realism(s) for s in range(40)]
    assert draw_realism(7) == draws[7]
    for d in draws:
        e = d.effects
        lo, hi = REALISM_RANGES['exposure_time'][1]
        assert e.exposure_time == 0 or lo <= e.exposure_time <= hi
        assert e.jpeg_quality == 0 or 60 <= e.jpeg_quality <= 95
        assert 0.5 <= e.noise <= 3.0 and 0 <= e.vignetting <= 0.8
        if d.distortion:
            Distorter(dataclasses.replace(CAM, distortion=d.distortion))  # one-to-one
    for name in ('exposure_time', 'line_delay', 'full_well', 'jpeg_quality', 'movers'):
        on = np.mean([getattr(d.effects, name) > 0 for d in draws])
        assert 0.1 < on < 1.0, name
    assert 0.2 < np.mean([bool(d.distortion) for d in draws]) < 0.8
    assert 0.2 < np.mean([bool(d.effects.gain_ramp) for d in draws]) < 0.8


def test_effect_levels_name_every_effect_and_combine_into_all():
    for name in EFFECT_LEVELS:
        effects, distortion, scene = effect_level(name, 'default')
        assert effects != Effects() or distortion or scene != 'structure_texture', name
    effects, distortion, scene = effect_level('all', 'default')
    assert effects.exposure_time > 0 and effects.line_delay > 0 and effects.full_well > 0
    assert effects.jpeg_quality > 0 and effects.movers > 0 and distortion
    assert scene == 'structure_texture'
    with pytest.raises(ConfigError, match='unknown effect'):
        effect_level('fog', 'default')


def test_cli_realism_renders_and_records_the_drawn_effects(tmp_path, capsys):
    from initsel_ros.cli import main

    out = tmp_path / 'real'
    assert (
        main(
            [
                'synth',
                '--out',
                str(out),
                '--frames',
                '2',
                '--realism',
                '--seed',
                '4',
                '--jpeg-quality',
                '70',
                '--width',
                '320',
                '--height',
                '240',
                '--no-progress',
            ]
        )
        == 0
    )
    assert 'effects: ' in capsys.readouterr().out
    data = yaml.safe_load((out / 'effects.yaml').read_text())
    drawn = draw_realism(4)
    assert data['realism'] and data['effects']['jpeg_quality'] == 70  # the option wins
    assert data['effects']['noise'] == pytest.approx(drawn.effects.noise)
    assert len(open_sequence(out)) == 2


def test_cli_named_effects_render_the_levels_of_the_table(tmp_path, capsys):
    from initsel_ros.cli import main
    from initsel_ros.cli.synth import EFFECT_NAMES

    assert tuple(EFFECT_LEVELS) == EFFECT_NAMES  # the CLI's list is the table's
    small = ['--frames', '2', '--width', '320', '--height', '240', '--no-progress']
    out = tmp_path / 'strong'
    argv = ['synth', '--out', str(out), '--effect', 'noise', '--effect', 'distortion']
    assert main([*argv, '--strength', 'strong', '--jpeg-quality', '90', *small]) == 0
    data = yaml.safe_load((out / 'effects.yaml').read_text())
    want = effect_level('noise', 'strong')[0]
    assert data['effects']['noise'] == want.noise == 4.0
    assert data['effects']['full_well'] == want.full_well
    assert data['effects']['jpeg_quality'] == 90  # an explicit option wins
    assert tuple(data['distortion']) == effect_level('distortion', 'strong')[1]
    # A scene variant picks the scene unless --scene says otherwise.
    assert main(['synth', '--out', str(tmp_path / 'lt'), '--effect', 'low_texture', *small]) == 0
    assert 'scene low_texture' in (tmp_path / 'lt' / 'rgb.txt').read_text()
    argv = ['synth', '--out', str(tmp_path / 'w'), '--effect', 'low_texture', '--scene', 'wall']
    assert main([*argv, *small]) == 0
    assert 'scene wall' in (tmp_path / 'w' / 'rgb.txt').read_text()
    capsys.readouterr()


def test_cli_renders_through_a_fisheye_lens_and_says_so(tmp_path, capsys):
    from initsel_ros.cli import main

    small = ['--frames', '2', '--width', '320', '--height', '240', '--no-progress', '--hfov', '90']
    out = tmp_path / 'fisheye'
    argv = ['synth', '--out', str(out), '--fisheye', '--distortion', '0.05,-0.01,0.004,-0.001']
    assert main([*argv, '--realism', *small]) == 0
    assert '(fisheye)' in capsys.readouterr().out
    camera = open_sequence(out).intrinsics
    assert camera.fisheye and camera.distortion == (0.05, -0.01, 0.004, -0.001)
    assert yaml.safe_load((out / 'effects.yaml').read_text())['fisheye'] is True
    # with --realism and no --distortion, the drawn (standard-model) lens is not reused
    assert (
        main(['synth', '--out', str(tmp_path / 'ftheta'), '--fisheye', '--realism', *small]) == 0
    )
    assert open_sequence(tmp_path / 'ftheta').intrinsics.distortion == ()
    five = ['--distortion', '0.05,-0.01,0.004,-0.001,0.0']
    assert main(['synth', '--out', str(tmp_path / 'bad'), '--fisheye', *five, *small]) == 1
    assert 'fisheye (equidistant) model takes 4' in capsys.readouterr().err


def test_bad_effect_values_are_rejected():
    with pytest.raises(ConfigError, match='line_delay'):
        Effects(line_delay=-1e-5)
    with pytest.raises(ConfigError, match='gain_ramp'):
        Effects(gain_ramp=(0.6, 1.4))
    with pytest.raises(ConfigError, match='jpeg_quality'):
        Effects(jpeg_quality=101)


def test_low_texture_scene_leaves_few_trackable_corners(tmp_path):
    # The same view of the default scene and of the low-texture one, the same corner detector
    # as the tracker's quality bar: a bare scene must starve KLT of corners.
    rich, bare = (
        open_sequence(render(tmp_path / s, scene=s, trajectory='near', frames=1, start=80).path)
        for s in ('structure_texture', 'low_texture')
    )
    n_rich, n_bare = (
        len(cv2.goodFeaturesToTrack(seq.gray(0), 5000, 0.01, 8)) for seq in (rich, bare)
    )
    assert n_rich >= 400 and n_bare < n_rich / 3  # here 609 and 131
