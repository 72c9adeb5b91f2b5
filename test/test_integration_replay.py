"""``initsel replay`` as a separate process: TUM, EuRoC and KITTI layouts, raw and compressed.

A subscriber in this process receives every frame and CameraInfo and checks the stamps are the
source's integer nanoseconds, field by field. Processes always stop in ``finally`` (SIGINT,
then SIGTERM, then SIGKILL).
"""

from __future__ import annotations

import itertools
import shutil
import subprocess
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

pytest.importorskip('rclpy')

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from ros_helpers import DOMAIN_ID, ros_environment, stop_process
from sensor_msgs.msg import CameraInfo, CompressedImage, Image

from initsel_ros.camera import Intrinsics
from initsel_ros.datasets import open_sequence
from initsel_ros.datasets.bags import write_bag
from initsel_ros.datasets.euroc import write_euroc
from initsel_ros.datasets.kitti import write_kitti
from initsel_ros.datasets.tum import TumSequence

TIMEOUT_S = 60.0
N_FRAMES = 20
DISTORTION = (-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05)  # EuRoC MH_01 cam0
_namespaces = itertools.count()


def _environment() -> dict[str, str]:
    env = ros_environment()
    for name in ('_ROS_WHEELS_BOOTSTRAP_COMPLETE', 'LD_LIBRARY_PATH'):
        env.pop(name, None)
    return env


def _initsel() -> str:
    path = shutil.which('initsel')
    if path is None:
        pytest.skip('initsel is not installed (pip install -e .)')
    return path


@pytest.fixture(scope='module')
def sources(near_sequence, tmp_path_factory) -> dict[str, Path]:
    """20 rendered frames as a TUM folder with odd Unix stamps, as a ROS 1 bag of jpeg
    CompressedImages, as EuRoC (with a distortion vector in sensor.yaml) and as a KITTI root."""
    out = tmp_path_factory.mktemp('replay_sources')
    tum = out / 'tum_odd'
    (tum / 'rgb').mkdir(parents=True)
    lines = ['# color images', '# timestamp filename']
    seq = TumSequence(near_sequence)
    for f in seq.frames[:N_FRAMES]:
        name = f'rgb/{f.index}.png'
        shutil.copy(seq.rgb_files[f.index], tum / name)
        ns = 1_700_000_000_666_666_985 + f.index * 33_333_333
        lines.append(f'{ns // 10**9}.{ns % 10**9:09d} {name}')
    (tum / 'rgb.txt').write_text('\n'.join(lines) + '\n')
    seq.frames = seq.frames[:N_FRAMES]
    write_bag(open_sequence(tum), out / 'jpeg.bag', 'ros1', compressed='jpeg', jpeg_quality=95)
    write_kitti(seq, out / 'kitti', '03')
    cam = seq.intrinsics
    seq.intrinsics = Intrinsics(cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height, DISTORTION)
    write_euroc(seq, out / 'euroc')
    return {'tum': tum, 'bag': out / 'jpeg.bag', 'euroc': out / 'euroc', 'kitti': out / 'kitti'}


@pytest.fixture(scope='module')
def listener_context():
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=DOMAIN_ID)
    yield ctx
    rclpy.try_shutdown(context=ctx)


CASES = {
    'tum-raw': ('tum', []),
    'tum-jpeg': ('tum', ['--compressed', '--jpeg-quality', '95']),
    'compressed-ros1-bag-raw': ('bag', []),
    'euroc-native-mono8': ('euroc', ['--encoding', 'native']),
    'euroc-png': ('euroc', ['--encoding', 'native', '--compressed', '--compressed-format', 'png']),
    'kitti-root': ('kitti', ['--sequence', '03']),
}


@pytest.mark.parametrize('case', list(CASES))
def test_replay_publishes_every_frame_with_exact_stamps_and_the_calibration(
    sources, listener_context, tmp_path, case
):
    layout, options = CASES[case]
    sequence = open_sequence(sources[layout], sequence='03' if layout == 'kitti' else None)
    compressed = '--compressed' in options
    ns = f'/replay{next(_namespaces)}'
    node = rclpy.create_node('initsel_replay_listener', namespace=ns, context=listener_context)
    executor = SingleThreadedExecutor(context=listener_context)
    executor.add_node(node)
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    images: list = []
    infos: list = []
    if compressed:
        node.create_subscription(CompressedImage, 'image_raw/compressed', images.append, qos)
    else:
        node.create_subscription(Image, 'image_raw', images.append, qos)
    node.create_subscription(CameraInfo, 'camera_info', infos.append, qos)
    log = tmp_path / 'replay.log'
    replay = None
    try:
        with log.open('w') as out:
            replay = subprocess.Popen(
                [
                    _initsel(),
                    'replay',
                    str(sources[layout]),
                    *options,
                    '--image-topic',
                    f'{ns}/image_raw',
                    '--camera-info-topic',
                    f'{ns}/camera_info',
                    '--wait-for-subscriber',
                    '20',
                    '--rate',
                    '2',
                ],
                env=_environment(),
                stdout=out,
                stderr=subprocess.STDOUT,
            )
        deadline = time.monotonic() + TIMEOUT_S
        while len(images) < N_FRAMES or len(infos) < N_FRAMES:
            if replay.poll() is not None:  # done: what is in flight has 3 s to arrive
                deadline = min(deadline, time.monotonic() + 3)
            assert time.monotonic() < deadline, (
                f'{len(images)} images, {len(infos)} infos\n{log.read_text()}'
            )
            executor.spin_once(timeout_sec=0.05)
        code = replay.wait(timeout=TIMEOUT_S)
    finally:
        if replay is not None:
            stop_process(replay)
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()

    assert code == 0, log.read_text()
    assert f'published {N_FRAMES} frames' in log.read_text()
    expected = [(int(t) // 10**9, int(t) % 10**9) for t in sequence.stamps_ns]
    assert [(m.header.stamp.sec, m.header.stamp.nanosec) for m in images] == expected
    assert [(m.header.stamp.sec, m.header.stamp.nanosec) for m in infos] == expected
    if layout in ('tum', 'bag'):
        assert expected[1] == (1_700_000_000, 700_000_318)
    if layout == 'kitti':
        assert expected[0] == (0, 0)

    info = infos[0]
    cam = sequence.intrinsics
    np.testing.assert_allclose(np.reshape(info.k, (3, 3)), cam.K)
    assert (info.width, info.height) == (cam.width, cam.height)
    if layout == 'euroc':
        np.testing.assert_allclose(info.d[:4], DISTORTION)
        assert info.distortion_model == 'plumb_bob'
    else:
        assert not np.any(info.d)

    for k in (0, N_FRAMES - 1):
        msg = images[k]
        if compressed:
            pixels = cv2.imdecode(np.frombuffer(bytes(msg.data), np.uint8), cv2.IMREAD_UNCHANGED)
        else:
            channels = 1 if msg.encoding.startswith('mono') else 3
            pixels = (
                np.frombuffer(bytes(msg.data), np.uint8)
                .reshape(msg.height, msg.width, channels)
                .squeeze()
            )
        if layout == 'euroc':  # grey source: mono8 published as stored
            assert pixels.ndim == 2
            want = sequence.gray(k)
            if compressed:
                assert msg.format == 'mono8; png compressed mono8'
            else:
                assert msg.encoding == 'mono8'
            assert np.array_equal(pixels, want)
        elif compressed:
            assert msg.format == 'bgr8; jpeg compressed bgr8'
            diff = np.abs(pixels.astype(int) - sequence.image(k).astype(int))
            assert diff.mean() < 3.0
        else:
            assert msg.encoding == 'rgb8'
            assert np.array_equal(pixels, sequence.image(k)[..., ::-1])  # bag: decoded jpeg


def test_replay_warns_once_when_frames_exceed_the_shared_memory_segment(sources, tmp_path):
    profile = tmp_path / 'small_shm.xml'
    profile.write_text(
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"><profiles>'
        '<transport_descriptors><transport_descriptor><transport_id>shm</transport_id>'
        '<type>SHM</type><segment_size>262144</segment_size></transport_descriptor>'
        '<transport_descriptor><transport_id>udp</transport_id><type>UDPv4</type>'
        '</transport_descriptor></transport_descriptors>'
        '<participant profile_name="p" is_default_profile="true"><rtps><userTransports>'
        '<transport_id>shm</transport_id><transport_id>udp</transport_id></userTransports>'
        '<useBuiltinTransports>false</useBuiltinTransports></rtps></participant>'
        '</profiles></dds>\n'
    )
    env = _environment()
    env['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(profile)
    env.pop('FASTDDS_DEFAULT_PROFILES_FILE', None)
    code, output = _replay_output(
        sources['tum'], '--image-topic', '/shm_probe/image_raw', env=env, rate='4'
    )
    assert code == 0, output
    warnings = [ln for ln in output.splitlines() if 'shared-memory segment' in ln]
    assert len(warnings) == 1, output  # 20 oversized frames, one warning
    assert '0.88 MiB' in warnings[0] and '0.25 MiB' in warnings[0]
    assert str(profile) in warnings[0]


def _replay_output(
    source: Path, *options: str, env: dict[str, str] | None = None, rate: str = '8'
) -> tuple[int, str]:
    """Exit code and output of ``initsel replay SOURCE --rate RATE OPTIONS``."""
    proc = subprocess.Popen(
        [_initsel(), 'replay', str(source), '--rate', rate, *options],
        env=_environment() if env is None else env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        output, _ = proc.communicate(timeout=TIMEOUT_S)
    finally:
        stop_process(proc)
    return proc.returncode, output


def test_an_unreadable_frame_is_skipped_with_a_warning_and_the_replay_goes_on(sources, tmp_path):
    # before: the first unreadable frame ended the replay with a traceback
    tum = tmp_path / 'tum'
    shutil.copytree(sources['tum'], tum)
    (tum / 'rgb' / '3.png').write_bytes(b'\x89PNG\r\n\x1a\n not an image')
    code, output = _replay_output(tum, '--image-topic', '/skip_probe/image_raw')
    assert code == 0, output
    assert 'frame 3 not published' in output
    assert f'published {N_FRAMES - 1} frames' in output
    assert '1 unreadable frames skipped' in output
    assert 'Traceback' not in output

    for png in (tum / 'rgb').glob('*.png'):
        png.write_bytes(b'')
    code, output = _replay_output(tum, '--loop', '--image-topic', '/skip_probe/image_raw')
    assert code == 1, output  # nothing readable: a failure, and --loop does not spin on it
    assert 'published 0 frames' in output
    assert output.count('not published') == 5  # the rest are counted, not named
