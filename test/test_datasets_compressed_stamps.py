"""Exact integer-nanosecond stamps and CompressedImage bags (issue 11)."""

from __future__ import annotations

import numpy as np
import pytest

from initsel_ros.datasets import Frame, open_sequence
from initsel_ros.datasets.tum import TumSequence
from initsel_ros.errors import DatasetError
from initsel_ros.timestamps import parse_seconds_ns, split_ns

#: Realistic Unix stamps with odd nanoseconds, 30 Hz.
FIRST_NS = 1_700_000_000_666_666_985
STEP_NS = 33_333_333


@pytest.mark.parametrize(
    ('text', 'ns'),
    [
        ('1341839327.392692', 1_341_839_327_392_692_000),
        ('1700000000.666666985', 1_700_000_000_666_666_985),
        ('1.036205e-01', 103_620_500),
        ('0.000000e+00', 0),
        ('-1.5', -1_500_000_000),
        ('42', 42_000_000_000),
    ],
)
def test_decimal_second_text_parses_to_exact_nanoseconds(text, ns):
    assert parse_seconds_ns(text) == ns


def test_split_ns_gives_ros_time_fields_also_for_negative_stamps():
    assert split_ns(1_341_839_327_392_692_000) == (1_341_839_327, 392_692_000)
    assert split_ns(-1_500_000_000) == (-2, 500_000_000)


@pytest.mark.parametrize('text', ['nan', 'inf', 'abc', ''])
def test_non_numeric_or_non_finite_stamps_are_dataset_errors(text):
    with pytest.raises(DatasetError):
        parse_seconds_ns(text)


def test_tum_listing_stamps_reach_the_frames_exactly(static_sequence, tmp_path):
    import shutil

    folder = tmp_path / 'tum'
    shutil.copytree(static_sequence, folder)
    lines = ['# color images', '# timestamp filename']
    names = [
        line.split()[1]
        for line in (folder / 'rgb.txt').read_text().splitlines()
        if not line.startswith('#')
    ]
    lines += [f'1341839327.{392692 + k:06d} {n}' for k, n in enumerate(names)]
    (folder / 'rgb.txt').write_text('\n'.join(lines) + '\n')
    (folder / 'groundtruth.txt').unlink()
    (folder / 'depth.txt').unlink()
    seq = TumSequence(folder)
    assert seq.frames[0].stamp_ns == 1_341_839_327_392_692_000
    assert seq.stamps_ns[5] == 1_341_839_327_392_697_000
    assert seq.stamps_ns.dtype == np.int64


def _odd_stamped(static_sequence, n=5):
    """The first n frames of the static sequence restamped with odd Unix nanoseconds."""
    seq = TumSequence(static_sequence)
    frames = []
    for f in seq.frames[:n]:
        ns = FIRST_NS + f.index * STEP_NS
        frames.append(Frame(f.index, ns * 1e-9, f.pose, ns * 1e-9, stamp_ns=ns))
    seq.frames = frames
    return seq


@pytest.mark.parametrize('fmt', ['ros1', 'ros2'])
def test_bag_round_trip_keeps_odd_nanosecond_stamps_exactly(static_sequence, tmp_path, fmt):
    from initsel_ros.datasets.bags import write_bag

    seq = _odd_stamped(static_sequence)
    path = write_bag(seq, tmp_path / ('b.bag' if fmt == 'ros1' else 'b'), fmt)
    back = open_sequence(path)
    expected = FIRST_NS + STEP_NS * np.arange(5, dtype=np.int64)
    np.testing.assert_array_equal(back.stamps_ns, expected)


@pytest.mark.parametrize('fmt', ['ros1', 'ros2'])
@pytest.mark.parametrize('codec', ['png', 'jpeg'])
def test_compressed_image_bags_read_back_like_the_folder(static_sequence, tmp_path, fmt, codec):
    from initsel_ros.datasets.bags import BagSequence, write_bag

    seq = _odd_stamped(static_sequence)
    path = write_bag(
        seq, tmp_path / ('c.bag' if fmt == 'ros1' else 'c'), fmt, compressed=codec, jpeg_quality=95
    )
    back = open_sequence(path)  # default topic absent: <topic>/compressed is found
    assert isinstance(back, BagSequence)
    assert back.image_topic == '/camera/rgb/image_color/compressed'
    np.testing.assert_array_equal(back.stamps_ns, seq.stamps_ns)
    assert back.intrinsics == seq.intrinsics
    for i in (0, 4):
        got, want = back.image(i), seq.image(i)
        assert got.shape == want.shape and got.dtype == np.uint8
        diff = np.abs(got.astype(int) - want.astype(int))
        if codec == 'png':
            assert diff.max() == 0
        else:
            assert diff.mean() < 3.0
        assert np.array_equal(back.depth(i), seq.depth(i))
    np.testing.assert_allclose(back.poses(), seq.poses(), atol=1e-9)
    explicit = BagSequence(path, image_topic='/camera/rgb/image_color/compressed')
    assert len(explicit) == 5


def test_16bit_grey_images_go_through_png_unchanged(tmp_path):
    from initsel_ros.datasets.bags import image_from_compressed
    from initsel_ros.image import encode_compressed

    img = (np.arange(48 * 64, dtype=np.uint16).reshape(48, 64) * 13) % 4096  # 12-bit data
    data, fmt = encode_compressed(img, 'jpeg')  # jpeg cannot hold 16 bits: png is used
    assert fmt == 'mono16; png compressed mono16'

    class Msg:
        format = fmt

    Msg.data = np.frombuffer(data, np.uint8)
    out = image_from_compressed(Msg)
    assert out.dtype == np.uint16 and np.array_equal(out, img)


def test_undecodable_compressed_frame_names_the_bag_topic_and_frame(static_sequence, tmp_path):
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    T = store.types
    msgtype = 'sensor_msgs/msg/CompressedImage'
    path = tmp_path / 'garbage_jpeg'
    with Writer(path, version=9) as writer:
        conn = writer.add_connection('/cam/compressed', msgtype, typestore=store)
        header = T['std_msgs/msg/Header'](
            stamp=T['builtin_interfaces/msg/Time'](sec=1, nanosec=5), frame_id='cam'
        )
        msg = T[msgtype](
            header=header, format='jpeg', data=np.frombuffer(b'not a jpeg at all', np.uint8)
        )
        writer.write(conn, 1_000_000_005, store.serialize_cdr(msg, msgtype))
    seq = open_sequence(path, image_topic='/cam/compressed')
    assert seq.frames[0].stamp_ns == 1_000_000_005
    with pytest.raises(DatasetError, match=r'garbage_jpeg.*/cam/compressed frame 0.*decode'):
        seq.image(0)


def test_dataset_on_a_png_compressed_bag_gives_the_folder_s_table(
    static_sequence, near_sequence, tmp_path
):
    """png is lossless: the compressed ROS 2 bag labels exactly like the TUM folder (with depth),
    and a TUM folder next to a KITTI root takes --sequence without complaint."""
    from initsel_ros.cli import main
    from initsel_ros.datasets.bags import write_bag
    from initsel_ros.learn.table import read_table

    folder = TumSequence(near_sequence)
    folder.frames = folder.frames[:20]
    bag = write_bag(folder, tmp_path / 'near_png', 'ros2', compressed='png')
    tables = {}
    for name, source in (('bag', bag), ('folder', near_sequence)):
        out = tmp_path / f'{name}.csv'
        assert (
            main(
                [
                    'dataset',
                    str(source),
                    '--out',
                    str(out),
                    '--batch',
                    '20',
                    '--stride',
                    '1',
                    '--jobs',
                    '1',
                    '--quiet',
                    '--no-orbslam',
                    '--sequence',
                    '00',
                ]
            )
            == 0
        )
        tables[name] = read_table(out)
    bag_table = tables['bag']
    folder_table = tables['folder'].select(tables['folder']['cur_index'] < 20)
    assert len(bag_table) == 19 == len(folder_table)
    assert set(bag_table['scale_rule']) == {'median'}
    for column in ('n_tracks', 'E_label', 'H_label', 'F_label', 'R_label'):
        np.testing.assert_array_equal(bag_table[column], folder_table[column])
    np.testing.assert_allclose(bag_table['E_et'], folder_table['E_et'])


def test_a_bag_frame_claiming_a_huge_size_is_refused_before_decoding():
    """The bag reader decodes through image.py, with its decompression-bomb check."""
    import cv2

    from initsel_ros.datasets.bags import image_from_compressed

    data = bytearray(cv2.imencode('.png', np.zeros((4, 4), np.uint8))[1].tobytes())
    data[16:24] = (1 << 14).to_bytes(4, 'big') * 2

    class Msg:
        format = 'png'

    Msg.data = bytes(data)
    with pytest.raises(DatasetError, match=r'16384x16384 .* is larger than'):
        image_from_compressed(Msg)
