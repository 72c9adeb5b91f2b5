"""The dropped share of received frames, judged over windows (initsel_ros.backlog)."""

from __future__ import annotations

import math

import pytest

from initsel_ros.backlog import Backlog, BacklogWatch


def test_a_window_with_a_steady_share_dropped_is_reported_with_its_figures():
    watch = BacklogWatch(window=10, warn_share=0.2)
    assert watch.processed(1, 0, 0.04, now=0.0) is None  # the first processed frame: start
    reports, received = [], 1
    for k in range(8):  # 30 Hz, 40-50 ms a frame: a frame in three is dropped
        received += 3 if k % 2 else 2
        now = (received - 1) / 30.0
        reports.append(watch.processed(received, k + 1, 0.050 if k % 2 else 0.040, now))
    closed = [r for r in reports if r is not None]
    assert reports[:3] == [None] * 3 and reports[3] is not None  # 10 received by the 4th
    first = closed[0]
    assert (first.received, first.dropped) == (10, 4)
    assert first.interval_ms == pytest.approx(1000 / 30) and first.mean_ms == pytest.approx(45)
    assert first.p90_ms == pytest.approx(50, abs=1e-6)
    assert len(closed) == 2 and closed[1].received == 10  # the next window starts afresh


def test_drops_before_the_first_processed_frame_do_not_count():
    watch = BacklogWatch(window=10, warn_share=0.1)
    assert watch.processed(6, 5, 0.2, now=0.2) is None  # a camera_info wait dropped five
    assert all(watch.processed(6 + k, 5, 0.01, now=0.2 + k / 30) is None for k in range(1, 30))


def test_an_occasional_drop_is_no_backlog():
    watch = BacklogWatch(window=30, warn_share=0.1)
    assert all(watch.processed(k + 1, (k + 1) // 15, 0.01, k / 30) is None for k in range(90))


def test_the_message_says_which_cause_the_figures_point_to():
    slow = Backlog(received=90, dropped=20, interval_ms=33.3, mean_ms=41.6, p90_ms=55.0)
    off = slow.message(0)
    assert off.startswith('dropped 20 of the last 90 frames (they arrived every 33 ms')
    assert 'processing is slower than the camera' in off and '42 ms on average' in off
    assert 'set max_tracking_width (e.g. 640)' in off
    assert 'lower max_tracking_width (now 1280 px)' in slow.message(1280)
    bursts = Backlog(received=90, dropped=20, interval_ms=33.3, mean_ms=17.0, p90_ms=30.0)
    assert 'the frames arrive in bursts' in bursts.message(0)
    assert 'max_tracking_width' not in bursts.message(0)
    unknown = Backlog(received=90, dropped=20, interval_ms=math.nan, mean_ms=17.0, p90_ms=30.0)
    assert 'processing is slower' in unknown.message(0)


@pytest.mark.parametrize('window, share', [(0, 0.1), (10, 0.0), (10, 1.5)])
def test_a_watch_that_could_never_report_is_refused(window, share):
    with pytest.raises(ValueError):
        BacklogWatch(window, share)
