"""ROS 1 and ROS 2 bags: written from a TUM folder, read back through bags.py."""

from __future__ import annotations

import numpy as np
import pytest

from initsel_ros.camera import Intrinsics
from initsel_ros.datasets import open_sequence
from initsel_ros.datasets.bags import BagSequence, write_bag
from initsel_ros.datasets.tum import TumSequence
from initsel_ros.errors import DatasetError


def _assert_same(folder, bag, indices=(0, 17, 59)):
    assert len(bag) == len(folder)
    assert np.allclose(bag.stamps, folder.stamps, atol=1e-6)
    assert bag.intrinsics == folder.intrinsics
    assert np.allclose(bag.poses(), folder.poses(), atol=1e-9)
    for i in indices:
        assert np.array_equal(bag.image(i), folder.image(i))
        assert np.array_equal(bag.depth(i), folder.depth(i))


def test_ros1_bag_reads_back_to_the_same_frames_depth_and_poses(near_sequence, near_bag_ros1):
    bag = open_sequence(near_bag_ros1)
    assert isinstance(bag, BagSequence) and bag.groundtruth_source == 'pose'
    _assert_same(TumSequence(near_sequence), bag)


def test_ros2_bag_reads_back_to_the_same_frames_depth_and_poses(near_sequence, near_bag_ros2):
    bag = open_sequence(near_bag_ros2)
    assert isinstance(bag, BagSequence)
    _assert_same(TumSequence(near_sequence), bag)


def test_ros2_mcap_storage_round_trips(static_sequence, tmp_path):
    folder = TumSequence(static_sequence)
    path = write_bag(folder, tmp_path / 'mcap_bag', 'ros2', storage='mcap')
    assert list(path.glob('*.mcap'))
    _assert_same(folder, open_sequence(path), indices=(0, 29))


def test_groundtruth_file_overrides_the_pose_topic(near_sequence, near_bag_ros1, tmp_path):
    shifted = tmp_path / 'gt.txt'
    lines = []
    for line in (near_sequence / 'groundtruth.txt').read_text().splitlines():
        if line.startswith('#'):
            continue
        v = line.split()
        v[1] = f'{float(v[1]) + 1.0:.9f}'
        lines.append(' '.join(v))
    shifted.write_text('\n'.join(lines) + '\n')
    bag = BagSequence(near_bag_ros1, groundtruth=shifted)
    folder = TumSequence(near_sequence)
    assert np.allclose(bag.poses()[:, 0, 3], folder.poses()[:, 0, 3] + 1.0, atol=1e-6)


def test_missing_image_topic_names_the_topics_found(near_bag_ros1):
    with pytest.raises(DatasetError, match=r'no messages on image topic .*image_color'):
        BagSequence(near_bag_ros1, image_topic='/nope')


def test_truncated_ros1_bag_raises_dataset_error_naming_the_file(near_bag_ros1, tmp_path):
    data = near_bag_ros1.read_bytes()
    broken = tmp_path / 'broken.bag'
    broken.write_bytes(data[: len(data) // 3])
    with pytest.raises(DatasetError, match=r'broken\.bag'):
        seq = BagSequence(broken)
        for i in range(len(seq)):
            seq.image(i)


def test_corrupt_ros2_bag_raises_dataset_error_naming_the_file(near_bag_ros2, tmp_path):
    import shutil

    copy = tmp_path / 'corrupt'
    shutil.copytree(near_bag_ros2, copy)
    db = next(copy.glob('*.db3'))
    db.write_bytes(b'not a database' * 100)
    with pytest.raises(DatasetError, match='corrupt'):
        BagSequence(copy)


def test_writing_over_an_existing_bag_is_refused(static_sequence, tmp_path):
    target = tmp_path / 'exists.bag'
    target.write_bytes(b'')
    with pytest.raises(DatasetError, match='already exists'):
        write_bag(TumSequence(static_sequence), target, 'ros1')


def test_an_unusable_pose_topic_leaves_the_bag_readable_without_ground_truth(
    near_bag_ros1, monkeypatch, caplog
):
    # e.g. a pose topic whose messages are all unstamped: before, one time with many poses
    # made the whole bag unopenable, for initsel replay too, which needs no poses
    import initsel_ros.datasets.bags as bags

    def refuse(stamps, positions, quaternions, where):
        raise DatasetError(f'{where}: time 0.0 has two different poses')

    monkeypatch.setattr(bags, 'check_trajectory', refuse)
    bag = BagSequence(near_bag_ros1)
    assert len(bag) > 0 and not bag.has_pose.any()
    assert bag.image(0).shape == (480, 640, 3)
    assert 'time 0.0 has two different poses: not used as ground truth' in caplog.text


def _rewrite_ros1(src, dst, receive_time, edit=None):
    """A copy of the ROS 1 bag ``src`` whose messages get ``receive_time(topic, k, t)`` (and
    ``edit(topic, k, msg)`` first, when given)."""
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    with AnyReader([src]) as reader, Writer(dst) as writer:
        out = {
            c.id: writer.add_connection(c.topic, c.msgtype, typestore=store)
            for c in reader.connections
        }
        seen: dict[str, int] = {}
        for conn, t, raw in reader.messages():
            k = seen[conn.topic] = seen.get(conn.topic, -1) + 1
            msg = reader.deserialize(raw, conn.msgtype)
            if edit is not None:
                edit(conn.topic, k, msg)
            writer.write(
                out[conn.id],
                receive_time(conn.topic, k, t),
                store.serialize_ros1(msg, conn.msgtype),
            )
    return dst


def test_two_frames_received_at_one_time_are_read_as_two(near_bag_ros1, tmp_path):
    # before: the second frame came back with the first one's pixels, without a word
    original = BagSequence(near_bag_ros1)
    times = {}

    def same_time(topic, k, t):
        times.setdefault((topic, k), t)
        return times[(topic, k - 1)] if k == 11 and topic.endswith('image_color') else t

    bag = BagSequence(_rewrite_ros1(near_bag_ros1, tmp_path / 'twins.bag', same_time))
    assert np.array_equal(bag.image(11), original.image(11))
    assert not np.array_equal(bag.image(11), bag.image(10))


def test_an_image_topic_that_holds_no_images_is_one_line(near_bag_ros1):
    with pytest.raises(DatasetError, match=r'camera_info is sensor_msgs/msg/CameraInfo, not'):
        BagSequence(near_bag_ros1, image_topic='/camera/rgb/camera_info')


def test_a_bag_without_camera_info_says_the_intrinsics_are_assumed(
    near_bag_ros1, tmp_path, caplog
):
    bag = BagSequence(
        _rewrite_ros1(near_bag_ros1, tmp_path / 'x.bag', lambda topic, k, t: t),
        info_topic='/nowhere',
    )
    assert bag.intrinsics.fx == pytest.approx(535.4)
    assert 'no CameraInfo on /nowhere: the TUM fr3 intrinsics are assumed' in caplog.text


def test_writing_a_bag_into_a_missing_folder_is_one_line(static_sequence, tmp_path):
    with pytest.raises(DatasetError, match='no such folder to write the bag in'):
        write_bag(TumSequence(static_sequence), tmp_path / 'nodir' / 'x.bag', 'ros1')


def test_a_bag_without_camera_info_takes_the_intrinsics_it_is_given(
    near_bag_ros1, tmp_path, caplog
):
    camera = Intrinsics(500.0, 505.0, 321.0, 239.0, 640, 480)
    bag = open_sequence(
        _rewrite_ros1(near_bag_ros1, tmp_path / 'x.bag', lambda topic, k, t: t),
        info_topic='/nowhere',
        intrinsics=camera,
    )
    assert bag.intrinsics == camera
    assert 'assumed' not in caplog.text


def _set_camera_k(value):
    def edit(topic, k, msg):
        if topic.endswith('camera_info'):
            msg.K = np.array([value, 0, 320, 0, 500, 240, 0, 0, 1]) if value else np.zeros(9)

    return edit


def test_an_uncalibrated_or_invalid_camera_info_is_not_called_missing(
    near_bag_ros1, tmp_path, caplog
):
    # before: K all zero and fx NaN were both 'no CameraInfo on ...', and NaN fx went unseen
    keep = lambda topic, k, t: t  # noqa: E731
    zeros = _rewrite_ros1(near_bag_ros1, tmp_path / 'zeros.bag', keep, _set_camera_k(0.0))
    bag = BagSequence(zeros)
    assert bag.intrinsics.fx == pytest.approx(535.4)
    assert 'the CameraInfo is of an uncalibrated camera (K zero) on /camera/rgb/camera_info' in (
        caplog.text
    )
    nan = _rewrite_ros1(near_bag_ros1, tmp_path / 'nan.bag', keep, _set_camera_k(np.nan))
    with pytest.raises(DatasetError, match='bad CameraInfo'):
        BagSequence(nan)
    # the camera's own intrinsics given: the bag's CameraInfo is not read at all
    given = Intrinsics(500.0, 500.0, 320.0, 240.0, 640, 480)
    assert BagSequence(nan, intrinsics=given).intrinsics == given


def _set_image_stamp(stamp_ns):
    def edit(topic, k, msg):
        if topic.endswith('image_color'):
            msg.header.stamp = type(msg.header.stamp)(*divmod(stamp_ns(k), 1_000_000_000))

    return edit


def test_frames_without_header_stamps_take_the_times_the_bag_received_them(
    near_bag_ros1, tmp_path, caplog
):
    # before: every frame was at time 0: replayed in one burst, one ground-truth pose for all
    original = BagSequence(near_bag_ros1)
    bag = BagSequence(
        _rewrite_ros1(
            near_bag_ros1, tmp_path / 'x.bag', lambda topic, k, t: t, _set_image_stamp(lambda k: 0)
        )
    )
    assert 'zero header stamp' in caplog.text
    assert len(bag) == len(original)
    assert np.all(np.diff(bag.stamps) > 0)
    np.testing.assert_allclose(bag.stamps, original.stamps, atol=0.05)  # the recorder's lag
    assert np.array_equal(bag.image(7), original.image(7))


def test_header_stamps_out_of_the_order_of_reception_are_said(near_bag_ros1, tmp_path, caplog):
    original = BagSequence(near_bag_ros1)
    first = int(original.stamps_ns[0])
    swapped = {3: 4, 4: 3}  # frames 3 and 4 carry each other's stamps

    bag = BagSequence(
        _rewrite_ros1(
            near_bag_ros1,
            tmp_path / 'x.bag',
            lambda topic, k, t: t,
            _set_image_stamp(lambda k: int(original.stamps_ns[swapped.get(k, k)])),
        )
    )
    assert (
        f'1 of {len(original)} frames on /camera/rgb/image_color carry an earlier' in caplog.text
    )
    assert int(bag.stamps_ns[0]) == first
    assert 'carry an earlier' not in _warnings_of(near_bag_ros1, caplog)


def test_header_stamps_repeated_are_said(near_bag_ros1, tmp_path, caplog):
    # before: the second frame took the first one's pose and lost its depth, without a word
    original = BagSequence(near_bag_ros1)
    BagSequence(
        _rewrite_ros1(
            near_bag_ros1,
            tmp_path / 'x.bag',
            lambda topic, k, t: t,
            _set_image_stamp(lambda k: int(original.stamps_ns[1 if k == 2 else k])),
        )
    )
    said = f'1 of {len(original)} frames on /camera/rgb/image_color carry the header stamp of'
    assert said in caplog.text
    assert 'header stamp of another' not in _warnings_of(near_bag_ros1, caplog)


def _warnings_of(path, caplog):
    caplog.clear()
    BagSequence(path)
    return caplog.text


def _pose_topic_as(src, dst, msgtype):
    """A copy of the ROS 1 bag ``src`` whose /groundtruth/pose carries ``msgtype`` with the
    same stamps and poses (a PointStamped: the positions alone)."""
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    T = store.types
    with AnyReader([src]) as reader, Writer(dst) as writer:
        out = {
            c.id: writer.add_connection(
                c.topic, msgtype if c.topic == '/groundtruth/pose' else c.msgtype, typestore=store
            )
            for c in reader.connections
        }
        for conn, t, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            kind = conn.msgtype
            if conn.topic == '/groundtruth/pose':
                kind, h, pose = msgtype, msg.header, msg.pose
                covariance = np.zeros(36)
                if msgtype.endswith('PoseWithCovarianceStamped'):
                    msg = T[msgtype](
                        h, T['geometry_msgs/msg/PoseWithCovariance'](pose, covariance)
                    )
                elif msgtype.endswith('Odometry'):
                    twist = T['geometry_msgs/msg/TwistWithCovariance'](
                        T['geometry_msgs/msg/Twist'](
                            T['geometry_msgs/msg/Vector3'](0.0, 0.0, 0.0),
                            T['geometry_msgs/msg/Vector3'](0.0, 0.0, 0.0),
                        ),
                        covariance,
                    )
                    msg = T[msgtype](
                        h,
                        'camera',
                        T['geometry_msgs/msg/PoseWithCovariance'](pose, covariance),
                        twist,
                    )
                elif msgtype.endswith('TransformStamped'):
                    p, o = pose.position, pose.orientation
                    msg = T[msgtype](
                        h,
                        'camera',
                        T['geometry_msgs/msg/Transform'](
                            T['geometry_msgs/msg/Vector3'](p.x, p.y, p.z), o
                        ),
                    )
                else:  # PointStamped
                    msg = T[msgtype](h, pose.position)
            writer.write(out[conn.id], t, store.serialize_ros1(msg, kind))
    return dst


@pytest.mark.parametrize(
    'msgtype',
    [
        'geometry_msgs/msg/PoseWithCovarianceStamped',
        'nav_msgs/msg/Odometry',
        'geometry_msgs/msg/TransformStamped',
    ],
)
def test_pose_topics_of_the_common_ground_truth_types_are_read(near_bag_ros1, tmp_path, msgtype):
    # before: anything but a PoseStamped made the bag unopenable (AttributeError), for replay too
    original = BagSequence(near_bag_ros1)
    bag = BagSequence(_pose_topic_as(near_bag_ros1, tmp_path / 'gt.bag', msgtype))
    assert bag.groundtruth_source == 'pose' and bag.has_pose.all()
    np.testing.assert_allclose(bag.poses(), original.poses(), atol=1e-12)


def test_a_pose_topic_that_holds_no_pose_is_ignored_and_named(near_bag_ros1, tmp_path, caplog):
    caplog.set_level('INFO')
    path = _pose_topic_as(near_bag_ros1, tmp_path / 'points.bag', 'geometry_msgs/msg/PointStamped')
    bag = BagSequence(path)
    assert len(bag) > 0 and not bag.has_pose.any()
    assert '/groundtruth/pose is geometry_msgs/msg/PointStamped, not a pose' in caplog.text
    # (before: 'no ground truth found on /groundtruth/pose ... pose-like topics:
    # /groundtruth/pose', the topic it had just refused)
    assert '/groundtruth/pose holds no usable camera poses (see above)' in caplog.text
    assert 'pose-like topics' not in caplog.text
    assert "write the camera's (body pose times body-to-camera) to groundtruth.txt" in caplog.text
