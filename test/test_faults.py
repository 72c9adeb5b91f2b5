"""Faults: broken bags, TUM folders and model files each give one clear error naming the file.

Also: the dataset builder never leaves a half-written table, the node refuses to start on a
bad model file with one line (no traceback), and a short flood leaves the node responsive with
bounded memory and the newest frame processed.
"""

from __future__ import annotations

import json
import os
import pickle
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from initsel_ros.camera import Intrinsics
from initsel_ros.errors import DatasetError, ModelFileError

ROOT = Path(__file__).resolve().parent.parent
TIMEOUT_S = 120


def _read_everything(path: Path) -> None:
    """Open a sequence and decode every image and depth map (lazy readers fail late)."""
    from initsel_ros.datasets import open_sequence

    seq = open_sequence(path)
    for i in range(len(seq)):
        seq.image(i)
        seq.depth(i)


def _assert_clean_failure_or_success(path: Path, name: str) -> str:
    """Reading either works or raises DatasetError naming ``name``; anything else fails."""
    try:
        _read_everything(path)
    except DatasetError as exc:
        assert name in str(exc), f'the error does not name {name}: {exc}'
        return 'error'
    return 'ok'


# ------------------------------------------------------------------------------------ bags
@pytest.fixture(scope='module')
def small_bags(static_sequence, tmp_path_factory):
    """ROS 1 and ROS 2 (sqlite3 and mcap) bags of the static sequence's first 6 frames."""
    pytest.importorskip('rosbags')
    from initsel_ros.datasets import TumSequence
    from initsel_ros.datasets.bags import write_bag

    seq = TumSequence(static_sequence)
    seq.frames = seq.frames[:6]
    out = tmp_path_factory.mktemp('fault_bags')
    return {
        'ros1': write_bag(seq, out / 'small.bag', 'ros1'),
        'ros2': write_bag(seq, out / 'small_ros2', 'ros2'),
        'mcap': write_bag(seq, out / 'small_mcap', 'ros2', storage='mcap'),
    }


@pytest.mark.parametrize('fraction', [0.0, 0.02, 0.3, 0.6, 0.95, 0.999])
def test_truncated_ros1_bag_fails_with_dataset_error_naming_it(small_bags, tmp_path, fraction):
    data = small_bags['ros1'].read_bytes()
    broken = tmp_path / 'cut.bag'
    broken.write_bytes(data[: int(len(data) * fraction)])
    assert _assert_clean_failure_or_success(broken, 'cut.bag') == 'error'


@pytest.mark.parametrize('kind', ['ros2', 'mcap'])
@pytest.mark.parametrize('fraction', [0.0, 0.1, 0.5, 0.9])
def test_truncated_ros2_storage_fails_with_dataset_error_naming_the_bag(
    small_bags, tmp_path, kind, fraction
):
    copy = tmp_path / 'cut_bag'
    shutil.copytree(small_bags[kind], copy)
    storage = next(p for p in copy.iterdir() if p.suffix in ('.db3', '.mcap'))
    data = storage.read_bytes()
    storage.write_bytes(data[: int(len(data) * fraction)])
    assert _assert_clean_failure_or_success(copy, 'cut_bag') == 'error'


@pytest.mark.parametrize('kind', ['ros1', 'ros2', 'mcap'])
def test_bag_with_garbage_in_the_middle_reads_or_fails_cleanly(small_bags, tmp_path, kind):
    source = small_bags[kind]
    rng = np.random.default_rng(3)
    if source.is_dir():
        copy = tmp_path / 'garbled'
        shutil.copytree(source, copy)
        target = next(p for p in copy.iterdir() if p.suffix in ('.db3', '.mcap'))
    else:
        copy = target = tmp_path / 'garbled.bag'
        shutil.copy(source, copy)
    data = bytearray(target.read_bytes())
    for start in np.linspace(len(data) * 0.2, len(data) * 0.8, 4).astype(int):
        data[start : start + 512] = rng.integers(0, 256, 512, dtype=np.uint8).tobytes()
    target.write_bytes(bytes(data))
    _assert_clean_failure_or_success(copy, 'garbled')


@pytest.mark.parametrize(
    'text',
    [
        '',
        'not: [valid yaml',
        'rosbag2_bagfile_information: 3\n',
        '!!python/object/apply:os.system ["true"]\n',
    ],
)
def test_ros2_bag_with_bad_metadata_fails_naming_the_bag(small_bags, tmp_path, text):
    copy = tmp_path / 'bad_meta'
    shutil.copytree(small_bags['ros2'], copy)
    (copy / 'metadata.yaml').write_text(text)
    assert _assert_clean_failure_or_success(copy, 'bad_meta') == 'error'


_LIMITED_CLI = """
import resource, sys
limit = int(sys.argv[1]) << 20
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
from initsel_ros.cli import main
sys.exit(main(sys.argv[2:]))
"""


@pytest.mark.parametrize('command', ['replay', 'dataset'])
def test_ros1_bag_with_an_overwritten_header_length_fails_with_one_line_and_a_reason(
    small_bags, tmp_path, command
):
    """The bag header record's length field claims 2 GiB: under a 1.5 GiB address-space limit
    (a small machine or container) rosbags raises MemoryError, which has no message."""
    data = bytearray(small_bags['ros1'].read_bytes())
    data[13:17] = b'\xff\xff\xff\x7f'  # header_len of the first record, after '#ROSBAG V2.0\n'
    bag = tmp_path / 'overwritten.bag'
    bag.write_bytes(bytes(data))
    args = (
        [str(bag)]
        if command == 'replay'
        else [str(bag), '--out', str(tmp_path / 't.csv'), '--jobs', '1', '--quiet']
    )
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ('_ROS_WHEELS_BOOTSTRAP_COMPLETE', 'LD_LIBRARY_PATH')
    }
    proc = subprocess.run(
        [sys.executable, '-c', _LIMITED_CLI, '1536', command, *args],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
        env=env,
    )
    err = proc.stderr.strip()
    assert proc.returncode == 1, err
    assert 'Traceback' not in err and 'MemoryError' in err
    assert len(err.splitlines()) == 1, err
    assert err.startswith(f'initsel {command}: error: ') and 'overwritten.bag' in err
    assert 'corrupt length field' in err
    assert not err.rstrip().endswith(':'), 'the reason is empty'
    assert not (tmp_path / 't.csv').exists()


# ----------------------------------------------------------------------------- TUM folders
def _tum_folder(path: Path, n: int = 3) -> Path:
    """A tiny TUM folder: n 64x48 textured PNGs, depth, ground truth."""
    from initsel_ros.datasets.tum import write_listing, write_trajectory

    rng = np.random.default_rng(0)
    (path / 'rgb').mkdir(parents=True)
    (path / 'depth').mkdir()
    stamps = 1.0 + np.arange(n) / 30
    for i in range(n):
        cv2.imwrite(
            str(path / 'rgb' / f'{i}.png'), rng.integers(0, 256, (48, 64, 3), dtype=np.uint8)
        )
        cv2.imwrite(str(path / 'depth' / f'{i}.png'), np.full((48, 64), 5000, np.uint16))
    write_listing(path / 'rgb.txt', stamps, [f'rgb/{i}.png' for i in range(n)], 'color images')
    write_listing(path / 'depth.txt', stamps, [f'depth/{i}.png' for i in range(n)], 'depth')
    write_trajectory(
        path / 'groundtruth.txt', stamps, np.zeros((n, 3)), np.tile([0, 0, 0, 1.0], (n, 1))
    )
    # the intrinsics of these images (the fr3 default is for 640x480: refused, not misread)
    Intrinsics.tum_fr3().scaled(64, 48).save_yaml(path / 'intrinsics.yaml')
    return path


def test_a_healthy_tiny_tum_folder_reads(tmp_path):
    assert _assert_clean_failure_or_success(_tum_folder(tmp_path / 'ok'), 'ok') == 'ok'


def _break_empty_image(p: Path) -> str:
    (p / 'rgb' / '1.png').write_bytes(b'')
    return '1.png'


def _break_truncated_image(p: Path) -> str:
    data = (p / 'rgb' / '2.png').read_bytes()
    (p / 'rgb' / '2.png').write_bytes(data[: len(data) // 2])
    return '2.png'


def _break_missing_image(p: Path) -> str:
    (p / 'rgb' / '0.png').unlink()
    return '0.png'


def _break_image_is_a_folder(p: Path) -> str:
    (p / 'rgb' / '1.png').unlink()
    (p / 'rgb' / '1.png').mkdir()
    return '1.png'


def _break_empty_depth(p: Path) -> str:
    (p / 'depth' / '1.png').write_bytes(b'')
    return '1.png'


def _break_colour_depth(p: Path) -> str:
    cv2.imwrite(str(p / 'depth' / '2.png'), np.zeros((48, 64, 3), np.uint8))
    return '2.png'


def _break_rgb_three_columns(p: Path) -> str:
    with (p / 'rgb.txt').open('a') as f:
        f.write('1.5 rgb/0.png extra\n')
    return 'rgb.txt:'


def _break_rgb_nan_stamp(p: Path) -> str:
    with (p / 'rgb.txt').open('a') as f:
        f.write('nan rgb/0.png\n')
    return 'rgb.txt:'


def _break_depth_listing(p: Path) -> str:
    (p / 'depth.txt').write_text('# depth\n1.0\n')
    return 'depth.txt:'


def _break_groundtruth_short_line(p: Path) -> str:
    with (p / 'groundtruth.txt').open('a') as f:
        f.write('2.0 0 0 0 0 0 0\n')
    return 'groundtruth.txt:'


def _break_groundtruth_binary(p: Path) -> str:
    (p / 'groundtruth.txt').write_bytes(b'\x80\x81\xfe\xff' * 10)
    return 'groundtruth.txt'


def _break_intrinsics_yaml(p: Path) -> str:
    (p / 'intrinsics.yaml').write_text('fx: [1, 2\n')
    return 'intrinsics.yaml'


def _break_intrinsics_values(p: Path) -> str:
    (p / 'intrinsics.yaml').write_text('fx: .nan\nfy: 1\ncx: 1\ncy: 1\nwidth: 64\nheight: 48\n')
    return 'intrinsics'


def _break_rgb_txt_missing(p: Path) -> str:
    (p / 'rgb.txt').unlink()
    return 'rgb.txt'


def _break_rgb_txt_empty(p: Path) -> str:
    (p / 'rgb.txt').write_text('# nothing\n')
    return 'rgb.txt'


TUM_FAULTS = [
    _break_empty_image,
    _break_truncated_image,
    _break_missing_image,
    _break_image_is_a_folder,
    _break_empty_depth,
    _break_colour_depth,
    _break_rgb_three_columns,
    _break_rgb_nan_stamp,
    _break_depth_listing,
    _break_groundtruth_short_line,
    _break_groundtruth_binary,
    _break_intrinsics_yaml,
    _break_intrinsics_values,
    _break_rgb_txt_missing,
    _break_rgb_txt_empty,
]


@pytest.mark.parametrize('fault', TUM_FAULTS, ids=lambda f: f.__name__[len('_break_') :])
def test_broken_tum_folder_gives_one_dataset_error_naming_the_file(tmp_path, fault):
    folder = _tum_folder(tmp_path / 'seq')
    name = fault(folder)
    if fault is _break_rgb_txt_missing:
        from initsel_ros.datasets import TumSequence

        with pytest.raises(DatasetError, match=r'rgb\.txt'):
            TumSequence(folder)
        return
    with pytest.raises(DatasetError) as info:
        _read_everything(folder)
    assert name in str(info.value)


# ------------------------------------------------------------------- the dataset builder
def test_dataset_command_on_a_broken_source_writes_nothing_and_keeps_the_old_table(
    tmp_path, capsys
):
    from initsel_ros.cli import main

    folder = _tum_folder(tmp_path / 'seq', n=4)
    _break_truncated_image(folder)
    out = tmp_path / 'tables' / 'pairs.csv'
    out.parent.mkdir()
    out.write_text('previous table\n')
    status = main(
        [
            'dataset',
            str(folder),
            '--out',
            str(out),
            '--batch',
            '4',
            '--jobs',
            '1',
            '--quiet',
            '--no-orbslam',
        ]
    )
    err = capsys.readouterr().err
    assert status == 1
    assert '2.png' in err and 'Traceback' not in err
    assert len(err.strip().splitlines()) == 1
    assert out.read_text() == 'previous table\n'
    assert sorted(p.name for p in out.parent.iterdir()) == ['pairs.csv']


def test_dataset_on_a_tum_folder_without_depth_labels_from_et_and_rotation(
    static_sequence, tmp_path, capsys
):
    """Before: batches without depth were skipped and a 0-pair table was written, exit 0."""
    from initsel_ros.cli import main
    from initsel_ros.learn.table import read_table

    folder = tmp_path / 'no_depth'
    shutil.copytree(static_sequence, folder)
    (folder / 'depth.txt').unlink()
    out = tmp_path / 'pairs.csv'
    assert (
        main(
            [
                'dataset',
                str(folder),
                '--out',
                str(out),
                '--batch',
                '10',
                '--jobs',
                '1',
                '--quiet',
                '--no-orbslam',
            ]
        )
        == 0
    )
    table = read_table(out)
    assert len(table) == 27  # 30 frames: 3 batches of 10, 9 pairs each
    assert set(table['scale_rule']) == {'no_depth'}
    assert np.all(table['R_label'] == 1)  # the static camera
    assert '27 pairs labelled without depth' in capsys.readouterr().out


def test_dataset_that_can_label_nothing_fails_with_one_line_and_writes_nothing(
    static_sequence, tmp_path, capsys
):
    from initsel_ros.cli import main

    folder = tmp_path / 'no_truth'
    shutil.copytree(static_sequence, folder)
    (folder / 'depth.txt').unlink()
    (folder / 'groundtruth.txt').unlink()
    out = tmp_path / 'pairs.csv'
    status = main(
        [
            'dataset',
            str(folder),
            '--out',
            str(out),
            '--batch',
            '10',
            '--jobs',
            '1',
            '--quiet',
            '--no-orbslam',
        ]
    )
    err = capsys.readouterr().err.strip()
    assert status == 1
    assert len(err.splitlines()) == 1 and 'Traceback' not in err
    assert (
        'no pair could be labelled: no_truth: none of its 30 frames has a ground-truth pose' in err
    )
    assert not out.exists()


def test_table_writer_interrupted_midway_leaves_no_partial_file(tmp_path, monkeypatch):
    from initsel_ros.learn import table as table_module

    rows = table_module.PairTable.from_rows([])
    out = tmp_path / 'pairs.csv'

    def explode(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(table_module.csv, 'writer', explode)
    with pytest.raises(KeyboardInterrupt):
        table_module.write_table(rows, out)
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------------ model files
def _valid_model_dict() -> dict:
    from initsel_ros.benchmarks.common import random_models

    return random_models().to_dict()


def test_model_file_holding_a_pickle_is_rejected_cleanly(tmp_path):
    path = tmp_path / 'models.json'
    path.write_bytes(pickle.dumps(_valid_model_dict(), protocol=pickle.HIGHEST_PROTOCOL))
    with pytest.raises(ModelFileError, match=r'models\.json'):
        from initsel_ros.models import ModelSet

        ModelSet.load(path)


def test_model_file_holding_a_protocol_0_pickle_is_rejected_cleanly(tmp_path):
    path = tmp_path / 'models.json'
    path.write_bytes(pickle.dumps({'format': 'initsel_ros/models'}, protocol=0))
    with pytest.raises(ModelFileError, match=r'models\.json'):
        from initsel_ros.models import ModelSet

        ModelSet.load(path)


@pytest.mark.parametrize(
    'text',
    [
        '!!python/object/apply:os.system ["touch {marker}"]\n',
        '--- !!python/object/new:initsel_ros.models.ModelSet {{}}\n',
        'format: initsel_ros/models\nversion: 1\nmodels: !!python/name:os.system\n',
    ],
)
def test_model_file_with_yaml_tags_is_rejected_and_never_executed(tmp_path, text):
    from initsel_ros.models import ModelSet

    marker = tmp_path / 'executed'
    path = tmp_path / 'models.yaml'
    path.write_text(text.format(marker=marker))
    with pytest.raises(ModelFileError, match=r'models\.yaml'):
        ModelSet.load(path)
    assert not marker.exists()


_SHIPPED_MODELS = Path(__file__).resolve().parent.parent / 'config' / 'models.json'
_BIG = '"@@NUMBER@@"'


def _model_file_with(tmp_path: Path, edit, literal: str = '') -> Path:
    """The shipped model file with ``edit(data)`` applied; ``_BIG`` becomes ``literal``."""
    data = json.loads(_SHIPPED_MODELS.read_text())
    edit(data)
    path = tmp_path / 'odd_models.json'
    path.write_text(json.dumps(data).replace(_BIG, literal))
    return path


def _first_tree(data: dict) -> dict:
    return data['models']['F']['trees'][0]


def _set_value(data: dict) -> None:
    _first_tree(data)['value'][-1] = json.loads(_BIG)


def _set_feature(data: dict) -> None:
    _first_tree(data)['feature'][0] = json.loads(_BIG)


def _set_bias(data: dict) -> None:
    data['models']['E']['bias'] = json.loads(_BIG)


def _set_split(data: dict) -> None:
    _first_tree(data)['split'][0] = json.loads(_BIG)


def _set_threshold(data: dict) -> None:
    data['models']['H']['threshold'] = json.loads(_BIG)


def _add_model_x(data: dict) -> None:
    data['models']['X'] = data['models']['R']


#: Issue 22 case 2: each used to end in a traceback (OverflowError, ValueError) or, for "X",
#: in a model loaded, shown in the ready line and never used.
ODD_MODEL_FILES = [
    pytest.param(
        _set_value,
        '1' + '0' * 400,
        "model 'F': tree 0: value contains NaN or infinity",
        id='10^400-value',
    ),
    pytest.param(
        _set_bias,
        '7' * 5000,
        "model 'E': bias must be a finite number (float64), got infinite, or an integer literal",
        id='5000-digit-bias',
    ),
    pytest.param(
        _set_feature, '1' + '0' * 30, "model 'F': tree 0: feature must lie in", id='10^30-index'
    ),
    pytest.param(
        _set_split,
        '-' + '9' * 320,
        "model 'F': tree 0: split contains NaN or infinity",
        id='-10^320-split',
    ),
    pytest.param(
        _set_threshold,
        '1' + '0' * 400,
        "model 'H': threshold must be in [0, 1]",
        id='10^400-threshold',
    ),
    pytest.param(_add_model_x, '', "unknown models: 'X'", id='model-X'),
]


@pytest.mark.parametrize(('edit', 'literal', 'message'), ODD_MODEL_FILES)
def test_odd_numbers_or_models_in_a_model_file_are_one_line_naming_the_field(
    tmp_path, edit, literal, message
):
    from initsel_ros.models import ModelSet

    path = _model_file_with(tmp_path, edit, literal)
    with pytest.raises(ModelFileError) as info:
        ModelSet.load(path)
    text = str(info.value)
    assert message in text and str(path) in text and '\n' not in text and len(text) < 400


@pytest.mark.parametrize(('edit', 'literal', 'message'), ODD_MODEL_FILES)
def test_initsel_eval_refuses_an_odd_model_file_with_one_line(
    tmp_path, capsys, edit, literal, message
):
    from initsel_ros.cli import main

    path = _model_file_with(tmp_path, edit, literal)
    code = main(['eval', str(tmp_path / 'unused_pairs.csv'), '--models', str(path)])
    err = capsys.readouterr().err.strip()
    assert code == 1
    assert err.startswith('initsel eval: error: ') and message in err and '\n' not in err


@pytest.mark.parametrize(
    ('edit', 'literal', 'message'), [ODD_MODEL_FILES[1], ODD_MODEL_FILES[2], ODD_MODEL_FILES[5]]
)
def test_the_node_refuses_to_start_on_an_odd_model_file_with_one_line(
    tmp_path, edit, literal, message
):
    pytest.importorskip('rclpy')
    path = _model_file_with(tmp_path, edit, literal)
    proc = _start_node_with(path)
    output = (proc.stdout + proc.stderr).strip()
    assert proc.returncode == 1, output
    assert 'Traceback' not in output and message in output
    assert len([line for line in output.splitlines() if 'odd_models.json' in line]) == 1


def _start_node_with(model_file) -> subprocess.CompletedProcess:
    """The node started on ``model_file`` until it exits (it must refuse to start)."""
    return subprocess.run(
        [
            sys.executable,
            '-m',
            'initsel_ros.ros.node',
            '--ros-args',
            '-p',
            f'model_file:={model_file}',
        ],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
        env=_node_env(),
    )


def _node_env() -> dict[str, str]:
    from ros_helpers import ros_environment

    env = ros_environment()
    env['ROS_DOMAIN_ID'] = str(os.getpid() % 50 + 150)
    return env


@pytest.mark.parametrize(
    'content',
    [
        None,
        b'{"format": "initsel_ros/models", "version": 1}',
        pytest.param(b'\x80\x04\x95', id='pickle-header'),
    ],
)
def test_node_refuses_to_start_on_a_missing_or_malformed_model_file(tmp_path, content):
    pytest.importorskip('rclpy')
    path = tmp_path / 'bad_models.json'
    if content is not None:
        path.write_bytes(content)
    proc = _start_node_with(path)
    output = proc.stdout + proc.stderr
    assert proc.returncode == 1, output
    assert 'bad_models.json' in output
    assert 'Traceback' not in output


# ----------------------------------------------------------------------------------- flood
def test_short_flood_keeps_memory_bounded_and_processes_the_newest_frame(tmp_path):
    pytest.importorskip('rclpy')
    from ros_helpers import configure_this_process

    from initsel_ros.benchmarks.common import random_models
    from initsel_ros.ros.bench_live import flood

    configure_this_process()
    os.environ['ROS_DOMAIN_ID'] = str(os.getpid() % 50 + 150)
    model_path = tmp_path / 'models.json'
    random_models().save(model_path)
    run = flood(model_path, seconds=3.0, rate_hz=200.0, width=640, height=480, timeout=60.0)
    assert run.published > 200, run
    assert run.processed > 10, run
    assert run.received <= run.published
    assert run.dropped > 0, 'at 200 Hz the node must drop frames, and say so'
    assert run.processed + run.dropped <= run.received + 1
    assert run.newest_processed, run
    assert run.rss_end_mb - run.rss_mid_mb < 50, run
    assert run.reasons.get('internal error', 0) == 0, run.reasons


@pytest.mark.parametrize('kind', ['fifo', 'dev_zero', 'deep_json', 'nested_weights'])
def test_node_fails_at_once_with_one_line_on_hostile_model_files(tmp_path, kind):
    """Issue 11: a FIFO hung the node in open(); /dev/zero and deep JSON gave tracebacks."""
    pytest.importorskip('rclpy')
    import json

    path = tmp_path / 'models.json'
    if kind == 'fifo':
        os.mkfifo(path)
    elif kind == 'dev_zero':
        path = Path('/dev/zero')
    elif kind == 'deep_json':
        path.write_text('[' * 200_000 + ']' * 200_000)
    else:
        data = _valid_model_dict()
        data['models']['E']['weights'] = [[1.0]] * 23
        path.write_text(json.dumps(data))
    proc = _start_node_with(path)
    output = proc.stdout + proc.stderr
    assert proc.returncode == 1, output
    assert str(path) in output and 'Traceback' not in output
    assert sum(str(path) in line for line in output.splitlines()) == 1
