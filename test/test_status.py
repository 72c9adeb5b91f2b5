"""The ``~/status`` record: built from a FrameResult, JSON round trip, diagnostics, docs."""

from __future__ import annotations

import json
import re
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pytest

from initsel_ros.errors import StatusError
from initsel_ros.geometry import Method
from initsel_ros.model_selection import CandidateScore, Selection
from initsel_ros.policy import Decision, Reason
from initsel_ros.selector import FrameResult, Initialization
from initsel_ros.status import (
    STATUS_FIELDS,
    WARN_REASONS,
    FrameStatus,
    NodeCounters,
    VerificationStatus,
)
from initsel_ros.verify import VerifyStep

DOCS = Path(__file__).resolve().parent.parent / 'docs' / 'node.md'
#: 1700000000.666666985 s, and its reference 12 frames earlier.
STAMP_NS = 1_700_000_000 * 10**9 + 666_666_985
REFERENCE_NS = STAMP_NS - 12 * 33_333_333

COUNTERS = NodeCounters(
    initialized=True,
    initializations=1,
    received_frames=40,
    dropped_frames=2,
    skipped_frames=1,
    intrinsics_source='camera_info',
    bit_depth=12,
    stamp_issues={'negative': 0, 'zero': 1, 'duplicate': 0, 'backwards': 0},
)


def _selection() -> Selection:
    scores = (
        CandidateScore(Method.E, True, '', 812.4, 231, 2.345, 0.91),
        CandidateScore(Method.H, False, 'too few triangulated points', float('inf'), 12, 0.4, 0.5),
    )
    return Selection(Method.E, scores, float('nan'), 'E: lowest GRIC', 1.0)


def _initializing_result() -> FrameResult:
    probabilities = {'F': 0.2, 'E': 0.8, 'H': 0.4, 'R': 0.1}
    decision = Decision(
        Reason.INITIALIZED,
        probabilities,
        fired=('E',),
        vetoed=(),
        candidates=(Method.E,),
        n_tracks=240,
        mean_disparity=14.5,
        detail='E verified on 3 frames',
        referred=('R',),
    )
    init = Initialization(
        method=Method.E,
        R=np.eye(3),
        t=np.array([0.1, 0.0, 0.0]),
        points=np.ones((60, 3)),
        pixels_ref=np.zeros((60, 2), np.float32),
        pixels_cur=np.zeros((60, 2), np.float32),
        reference_stamp_ns=REFERENCE_NS,
        stamp_ns=STAMP_NS - 3 * 33_333_333,
        frames_since_reference=9,
        probabilities=probabilities,
        parallax_deg=2.3,
        selection=_selection(),
    )
    step = VerifyStep(True, 58, 55, 0.91666, 0.41234, np.eye(3), np.zeros(3), '55/60 inliers')
    return FrameResult(40, STAMP_NS, REFERENCE_NS, decision, init, False, 12, verification=step)


def _status(result: FrameResult | None = None, **kwargs) -> FrameStatus:
    result = _initializing_result() if result is None else result
    sec, nanosec = divmod(STAMP_NS, 10**9)
    return FrameStatus.from_result(
        result, stamp_sec=sec, stamp_nanosec=nanosec, counters=COUNTERS, **kwargs
    )


def test_status_of_an_initializing_frame_carries_the_result_and_the_counters():
    s = _status()
    assert (s.stamp_sec, s.stamp_nanosec) == (1_700_000_000, 666_666_985)
    assert s.stamp_ns == STAMP_NS and s.stamp == pytest.approx(STAMP_NS * 1e-9)
    assert s.reference_stamp_sec * 10**9 + s.reference_stamp_nanosec == REFERENCE_NS
    assert s.initializing_stamp_ns == STAMP_NS - 3 * 33_333_333
    assert s.reason is Reason.INITIALIZED and s.level == 'OK' and s.method == 'E'
    assert s.probabilities == {'F': 0.2, 'E': 0.8, 'H': 0.4, 'R': 0.1}
    assert (
        s.fired == ('E',)
        and s.referred == ('R',)
        and s.tracks == 240
        and s.frames_since_reference == 12
    )
    assert s.selection['winner'] == 'E' and s.selection['orb_ratio'] is None
    assert s.verification == VerificationStatus(True, 58, 55, 0.917, 0.412, '55/60 inliers')
    assert s.initialized and s.received_frames == 40 and s.dropped_frames == 2
    assert s.bit_depth == 12 and s.stamp_issues['zero'] == 1
    assert not s.intrinsics_guessed


def test_status_json_round_trips_and_keeps_the_published_key_order():
    for status in (_status(), _skipped(), _status(reason=Reason.INTERNAL_ERROR, detail='boom')):
        text = status.to_json()
        assert FrameStatus.from_json(text) == status
        assert list(json.loads(text)) == list(STATUS_FIELDS)
    data = json.loads(_status().to_json())
    assert data['reason'] == 'initialized' and data['fired'] == ['E'] and data['referred'] == ['R']
    assert data['verification']['rms_px'] == 0.412
    assert data['selection']['candidates'][1]['gric'] is None  # infinite GRIC: null


def _skipped() -> FrameStatus:
    return FrameStatus.from_result(
        None,
        stamp_sec=-2,
        stamp_nanosec=5,
        counters=NodeCounters(),
        reason=Reason.SKIPPED_IMAGE,
        detail='unsupported encoding',
    )


def test_status_of_a_skipped_image_has_no_result_fields_and_warns():
    s = _skipped()
    assert s.frame_index is None and s.reference_stamp_sec is None and s.method is None
    assert s.probabilities == {'F': None, 'E': None, 'H': None, 'R': None}
    assert s.level == 'WARN' and s.diagnostic_level == 'WARN'
    assert s.stamp_ns == -2 * 10**9 + 5
    assert s.diagnostic_values()['p_E'] == ''
    with pytest.raises(StatusError, match='needs a reason'):
        FrameStatus.from_result(None, stamp_sec=0, stamp_nanosec=0, counters=NodeCounters())


def test_the_node_reasons_are_reasons_and_warn():
    assert Reason('image skipped') is Reason.SKIPPED_IMAGE
    assert Reason('internal error') is Reason.INTERNAL_ERROR
    assert {Reason.SKIPPED_IMAGE, Reason.INTERNAL_ERROR} <= WARN_REASONS
    assert _status(reason=Reason.INTERNAL_ERROR, detail='x').level == 'WARN'
    # the fire path refusing a pair is the ordinary wait, not a fault (it flooded diagnostics)
    assert _status(reason=Reason.POSE_FAILED, detail='H failed').level == 'OK'


def test_diagnostic_values_are_the_published_key_values():
    values = _status().diagnostic_values()
    assert list(values) == [
        'p_F',
        'p_E',
        'p_H',
        'p_R',
        'tracks',
        'mean_disparity_px',
        'frames_since_reference',
        'dropped_frames',
        'reason',
        'intrinsics',
        'selection',
    ]
    assert values['p_E'] == '0.8000' and values['tracks'] == '240'
    assert values['reason'] == 'initialized: E verified on 3 frames'
    assert values['intrinsics'] == 'camera_info' and values['selection'] == 'E: lowest GRIC'
    guessed = replace(_status(), intrinsics_guessed=True, intrinsics_warning='fr3 scaled')
    assert guessed.diagnostic_level == 'WARN' and guessed.level == 'OK'
    assert guessed.diagnostic_values()['intrinsics'] == 'guessed: fr3 scaled'
    scaled = replace(_status(), intrinsics_warning='images are 640x480 but ...')
    assert scaled.diagnostic_level == 'WARN' and not scaled.intrinsics_guessed
    assert scaled.diagnostic_values()['intrinsics'] == 'camera_info: images are 640x480 but ...'


@pytest.mark.parametrize(
    ('text', 'match'),
    [
        ('[1, 2]', 'JSON list, not an object'),
        ('{"stamp": 1', 'invalid JSON'),
        ('{}', 'missing stamp, stamp_sec'),
    ],
)
def test_malformed_status_text_is_a_status_error(text, match):
    with pytest.raises(StatusError, match=match):
        FrameStatus.from_json(text)


def test_unknown_keys_and_reasons_are_status_errors():
    data = json.loads(_status().to_json())
    with pytest.raises(StatusError, match='unknown extra'):
        FrameStatus.from_dict({**data, 'extra': 1})
    with pytest.raises(StatusError, match="unknown reason 'maybe'"):
        FrameStatus.from_dict({**data, 'reason': 'maybe'})


def _documented_status_fields() -> list[str]:
    """The field names of the ``~/status`` table in docs/node.md (first column, in order)."""
    text = DOCS.read_text()
    table = text[text.index('**Status.**') :]
    rows = []
    for line in table.splitlines()[1:]:
        if rows and not line.startswith('|'):
            break
        if line.startswith('|'):
            rows.append(line)
    names = []
    for row in rows[2:]:  # header and separator
        names += re.findall(r'`([a-z_]+)`', row.split('|')[1])
    return names


def test_docs_table_lists_exactly_the_status_fields_in_order():
    assert _documented_status_fields() == [f.name for f in fields(FrameStatus)]


def test_docs_list_every_reason():
    text = DOCS.read_text()
    row = next(
        line
        for line in text[text.index('**Status.**') :].splitlines()
        if line.startswith('| `reason`')
    )
    assert set(re.findall(r'`([^`]+)`', row.split('|', 3)[3])) == {r.value for r in Reason}


def test_a_status_record_of_an_earlier_version_without_referred_still_loads():
    data = _status().to_dict()
    assert data['referred'] == ['R']
    del data['referred']
    assert FrameStatus.from_dict(data).referred == ()


def test_the_next_fire_path_run_is_in_the_status_and_older_records_load():
    held = FrameResult(
        7, STAMP_NS, REFERENCE_NS, Decision(Reason.ROTATION, detail='H fired, but ...'),
        frames_since_reference=4, fire_path_due_in=2,
    )  # fmt: skip
    status = _status(held)
    assert status.fire_path_due_in == 2
    assert json.loads(status.to_json())['fire_path_due_in'] == 2
    assert _status().fire_path_due_in is None  # (an initializing frame: nothing scheduled)
    data = status.to_dict()
    del data['fire_path_due_in']
    assert FrameStatus.from_dict(data).fire_path_due_in is None
