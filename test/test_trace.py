"""Tests for initsel_ros.trace and ``initsel trace``: the node's ~/status records, offline."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from initsel_ros.datasets import open_sequence
from initsel_ros.models import ModelSet, default_model_path
from initsel_ros.policy import Reason
from initsel_ros.selector import Selector, SelectorConfig
from initsel_ros.status import FrameStatus
from initsel_ros.trace import eventful, summary_line, trace_sequence

#: The real fr3/structure_texture_near frames beside the project (../shared/data).
REAL_NEAR = Path(__file__).resolve().parents[2] / 'shared/data/tum_fr3_structure_texture_near'


def initsel(argv: list[str]) -> int:
    from initsel_ros.cli import main

    return main(['trace', *argv])


@pytest.fixture(scope='module')
def models() -> ModelSet:
    return ModelSet.load(default_model_path())


def test_records_are_what_the_selector_decided_frame_by_frame(rotation_sequence, models):
    seq = open_sequence(rotation_sequence)
    records = list(trace_sequence(seq, models, SelectorConfig(), stop=30))
    selector = Selector(models, seq.intrinsics, SelectorConfig())
    expected = [
        selector.process(seq.native_image(i), int(seq.stamps_ns[i])).decision for i in range(30)
    ]
    assert [r.reason for r in records] == [d.reason for d in expected]
    assert [r.detail for r in records] == [d.detail for d in expected]
    assert [r.frame_index for r in records] == list(range(30))
    assert records[-1].received_frames == records[-1].processed_frames == 30
    # the source's own calibration, as the node gets it from `initsel replay`'s camera_info
    assert records[0].intrinsics_source == 'camera_info'
    assert records[0].intrinsics == seq.intrinsics.to_dict()
    # a pan: the fire path ran and measured a rotation, and nothing was published
    assert any(r.rotation_test is not None for r in records)
    assert all(r.method is None for r in records)
    assert not records[-1].initialized
    # the records are the node's: they survive its JSON
    for record in records:
        assert FrameStatus.from_json(record.to_json()).reason is record.reason


def test_an_unreadable_frame_is_a_skipped_record_and_the_trace_goes_on(
    rotation_sequence, models, tmp_path
):
    copy = tmp_path / 'seq'
    shutil.copytree(rotation_sequence, copy)
    broken = sorted((copy / 'rgb').iterdir())[4]
    broken.write_bytes(b'not a png')
    records = list(trace_sequence(open_sequence(copy), models, stop=10))
    assert len(records) == 10
    assert records[4].reason is Reason.SKIPPED_IMAGE
    assert broken.name in records[4].detail and records[4].level == 'WARN'
    assert records[4].skipped_frames == 1 and records[-1].skipped_frames == 1
    assert records[-1].processed_frames == 9
    assert all(r.reason is not Reason.SKIPPED_IMAGE for r in records[5:])


def test_an_error_inside_the_selector_is_an_internal_error_record(
    rotation_sequence, models, monkeypatch
):
    process = Selector.process
    calls = {'n': 0}

    def counted(self, image, stamp_ns):
        calls['n'] += 1
        if calls['n'] == 4:
            raise ValueError('a bug')
        return process(self, image, stamp_ns)

    monkeypatch.setattr(Selector, 'process', counted)
    records = list(trace_sequence(open_sequence(rotation_sequence), models, stop=8))
    assert (
        records[3].reason is Reason.INTERNAL_ERROR and "ValueError('a bug')" in records[3].detail
    )
    assert records[3].level == 'WARN' and records[-1].skipped_frames == 1
    assert [r.reason for r in records[4:]].count(Reason.INTERNAL_ERROR) == 0


def test_wide_frames_are_shrunk_as_the_node_shrinks_them(rotation_sequence, models):
    seq = open_sequence(rotation_sequence)
    full = list(trace_sequence(seq, models, stop=3))
    half = list(trace_sequence(seq, models, stop=3, max_tracking_width=320))
    assert full[0].intrinsics == seq.intrinsics.to_dict()
    assert half[0].intrinsics == seq.intrinsics.binned(2).to_dict()
    assert half[0].intrinsics['width'] == seq.intrinsics.width // 2


def test_summary_line_names_the_reason_probabilities_and_rotation_test(rotation_sequence, models):
    records = list(trace_sequence(open_sequence(rotation_sequence), models, stop=12))
    tested = next(r for r in records if r.rotation_test is not None)
    line = summary_line(tested, 7)
    assert line.lstrip().startswith('7 ')
    assert tested.reason.value in line and tested.detail in line
    r = tested.probabilities['R']
    assert f'R {r:.2f}' in line
    assert f'rotation {tested.rotation_test["statistic"]:.1f}x noise' in line
    assert eventful(tested)
    assert eventful(records[0])  # the first frame is a new reference


def test_command_writes_every_record_and_names_the_initializations(
    near_sequence, tmp_path, capsys
):
    out = tmp_path / 'sub' / 'status.jsonl'
    assert initsel([str(near_sequence), '--jsonl', str(out), '--mode', 'continuous']) == 0
    records = [json.loads(line) for line in out.read_text().splitlines()]
    assert len(records) == len(open_sequence(near_sequence))
    printed = capsys.readouterr().out
    assert f'{len(records)} frames' in printed
    published = [(i, r['method']) for i, r in enumerate(records) if r['method'] is not None]
    assert published, 'the near trajectory gains 0.22 m of baseline in 30 frames'
    assert 'initialized: ' + '; '.join(f'{m} at frame {i}' for i, m in published) in printed
    assert records[-1]['initializations'] == len(published)
    # only the frames where something happened are printed, unless --all
    body = [line for line in printed.splitlines() if line[:5].strip().isdigit()]
    assert len(body) == sum(eventful(FrameStatus.from_dict(r)) for r in records)
    assert [line.split('-> ')[1][0] for line in body if '-> ' in line] == [m for _, m in published]


def test_command_prints_the_frames_where_something_happened_or_all(
    rotation_sequence, tmp_path, capsys
):
    out = tmp_path / 'status.jsonl'
    assert initsel([str(rotation_sequence), '--frames', '30', '--jsonl', str(out)]) == 0
    printed = capsys.readouterr().out
    body = [line for line in printed.splitlines() if line[:5].strip().isdigit()]
    records = [json.loads(line) for line in out.read_text().splitlines()]
    quiet = [
        i
        for i, r in enumerate(records)
        if not (r['new_reference'] or r['fired'] or r['rotation_test'] or r['verification'])
    ]
    assert quiet, "on a pan, model R's yes holds most frames without a fire-path run"
    ran = [i for i, r in enumerate(records) if r['rotation_test'] or r['selection']]
    last = records[ran[-1]]
    assert (
        f'the last fire-path run, frame {ran[-1]}: {last["reason"]}: {last["detail"]}' in printed
    )
    assert [int(line.split()[0]) for line in body] == sorted(set(range(30)) - set(quiet))
    assert initsel([str(rotation_sequence), '--frames', '6', '--start', '2', '--all']) == 0
    body = [line for line in capsys.readouterr().out.splitlines() if line[:5].strip().isdigit()]
    assert [int(line.split()[0]) for line in body] == [2, 3, 4, 5, 6, 7]


def test_command_errors_are_one_line(tmp_path, capsys):
    assert initsel([str(tmp_path / 'missing')]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith('initsel trace: error:') and '\n' not in err
    assert initsel([str(tmp_path), '--frames', '0']) == 2


def test_command_reads_the_source_with_the_replay_options(rotation_sequence, tmp_path, capsys):
    from initsel_ros.camera import Intrinsics

    camera = Intrinsics(500.0, 500.0, 320.0, 240.0, 640, 480)
    camera.save_yaml(tmp_path / 'camera.yaml')
    out = tmp_path / 'status.jsonl'
    argv = [str(rotation_sequence), '--frames', '3', '--jsonl', str(out)]
    assert initsel([*argv, '--intrinsics', str(tmp_path / 'camera.yaml')]) == 0
    record = json.loads(out.read_text().splitlines()[0])
    assert record['intrinsics'] == camera.to_dict()
    capsys.readouterr()
    assert initsel([*argv, '--bag-image-topic', '/camera/image_raw']) == 1
    assert 'applies to bags only' in capsys.readouterr().err


@pytest.mark.skipif(not REAL_NEAR.is_dir(), reason='real TUM sample not available')
def test_command_traces_the_real_tum_frames(tmp_path, capsys):
    out = tmp_path / 'status.jsonl'
    assert initsel([str(REAL_NEAR), '--all', '--jsonl', str(out)]) == 0
    records = [FrameStatus.from_json(line) for line in out.read_text().splitlines()]
    assert len(records) == len(open_sequence(REAL_NEAR))
    assert records[0].reason is Reason.NEW_REFERENCE and records[0].tracks > 0
    assert records[0].intrinsics == open_sequence(REAL_NEAR).intrinsics.to_dict()
    assert f'{len(records)} frames' in capsys.readouterr().out


def test_a_bag_traces_as_its_folder(near_sequence, near_bag_ros2, models):
    """The same frames from a ROS 2 bag: the same records (the reader's stamps are exact)."""
    from_folder = list(trace_sequence(open_sequence(near_sequence), models, stop=20))
    from_bag = list(trace_sequence(open_sequence(near_bag_ros2), models, stop=20))
    assert [r.reason for r in from_bag] == [r.reason for r in from_folder]
    assert [r.detail for r in from_bag] == [r.detail for r in from_folder]
    assert [r.stamp_nanosec for r in from_bag] == [r.stamp_nanosec for r in from_folder]
