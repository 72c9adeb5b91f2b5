"""The dropped share of received frames, judged over windows (initsel_ros.backlog)."""

from __future__ import annotations

import pytest

from initsel_ros.backlog import Backlog, BacklogWatch


def test_a_window_with_a_steady_share_dropped_is_reported_once_with_its_processing_time():
    watch = BacklogWatch(window=10, warn_share=0.2)
    reports = []
    received = 0
    for k in range(8):  # a node taking 40-50 ms a frame at 30 Hz: a frame in three dropped
        received += 3 if k % 2 else 2
        reports.append(watch.processed(received, k + 1, 0.050 if k % 2 else 0.040))
    closed = [r for r in reports if r is not None]
    assert reports[:3] == [None] * 3 and reports[3] is not None  # 10 received by the 4th
    assert closed[0] == Backlog(received=10, dropped=4, median_ms=pytest.approx(45.0))
    assert len(closed) == 2 and closed[1].received == 10  # the next window starts afresh


def test_an_occasional_drop_is_no_backlog():
    watch = BacklogWatch(window=30, warn_share=0.1)
    assert all(watch.processed(k + 1, (k + 1) // 15, 0.01) is None for k in range(90))


def test_the_message_names_the_setting_that_helps():
    backlog = Backlog(received=90, dropped=20, median_ms=41.6)
    off = backlog.message(0)
    assert off.startswith('dropped 20 of the last 90 frames') and '42 ms' in off
    assert 'set max_tracking_width (e.g. 640)' in off
    assert 'lower max_tracking_width (now 1280 px)' in backlog.message(1280)


@pytest.mark.parametrize('window, share', [(0, 0.1), (10, 0.0), (10, 1.5)])
def test_a_watch_that_could_never_report_is_refused(window, share):
    with pytest.raises(ValueError):
        BacklogWatch(window, share)
