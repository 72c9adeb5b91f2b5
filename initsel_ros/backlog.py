"""Noticing a node that falls behind its camera (ROS-free).

The node keeps only the newest frame: one that arrives while another waits overwrites it and
counts as dropped. A few drops are the price of a busy moment; a steady share of them means
processing a frame takes longer than the camera's frame interval (or the frames arrive in
bursts, or processing has slow spikes), and the decision sees a camera at a lower rate than
it runs. :class:`BacklogWatch` judges the dropped share over windows of received frames and
says when one is worth a warning, with the figures that tell those causes apart.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: The dropped share is judged over windows of this many received frames (3 s at 30 Hz).
BACKLOG_WINDOW_FRAMES = 90
#: A window with at least this share of its received frames dropped is worth a warning.
BACKLOG_WARN_SHARE = 0.1


@dataclass(frozen=True)
class Backlog:
    """One window that dropped too many frames.

    Attributes:
        received: frames received in the window.
        dropped: of those, frames overwritten before they were processed.
        interval_ms: mean time between the window's received frames, milliseconds (NaN
            when the window took no measurable time).
        mean_ms: mean time the node spent on each of the window's processed frames.
        p90_ms: its 90th percentile.
    """

    received: int
    dropped: int
    interval_ms: float
    mean_ms: float
    p90_ms: float

    def message(self, max_tracking_width: int) -> str:
        """The warning a node logs, with what a user can change."""
        head = (
            f'dropped {self.dropped} of the last {self.received} frames (they arrived every '
            f'{self.interval_ms:.0f} ms; a frame took {self.mean_ms:.0f} ms on average, '
            f'{self.p90_ms:.0f} ms at the 90th percentile): the decision sees a slower camera'
        )
        if not self.mean_ms < 0.9 * self.interval_ms:  # (NaN interval: slower, as far as known)
            shrink = (
                f'lower max_tracking_width (now {max_tracking_width} px)'
                if max_tracking_width > 0
                else 'set max_tracking_width (e.g. 640) to track a downscaled image'
            )
            return (
                f'{head}; processing is slower than the camera: {shrink}, or lower the '
                "camera's rate or resolution"
            )
        return (
            f'{head}; processing keeps up on average, so the frames arrive in bursts (the '
            'transport, a bag player) or slow frames pile up (the 90th percentile)'
        )


class BacklogWatch:
    """Windows of received frames and their dropped share (see the module docstring).

    The first window starts at the first processed frame, after the start-up (the wait for a
    camera_info, the first frame's set-up) has dropped what it dropped.
    """

    def __init__(
        self, window: int = BACKLOG_WINDOW_FRAMES, warn_share: float = BACKLOG_WARN_SHARE
    ):
        if window < 1 or not 0.0 < warn_share <= 1.0:
            raise ValueError(f'window {window} must be >= 1 and warn_share {warn_share} in (0, 1]')
        self.window, self.warn_share = window, warn_share
        self._start: tuple[int, int, float] | None = None  # received, dropped, time
        self._seconds: list[float] = []

    def processed(self, received: int, dropped: int, seconds: float, now: float) -> Backlog | None:
        """Count one processed frame.

        Args:
            received: frames received so far (a running count).
            dropped: frames dropped so far (a running count).
            seconds: how long this frame took the node.
            now: a monotonic clock's time, seconds.

        Returns:
            The window's figures when this frame closes a window of at least ``window``
            received frames with ``warn_share`` of them or more dropped; None otherwise (a
            window closes either way, and the next one starts).
        """
        if self._start is None:
            self._start = (received, dropped, now)
            return None
        self._seconds.append(seconds)
        got, lost = received - self._start[0], dropped - self._start[1]
        if got < self.window:
            return None
        elapsed, times = now - self._start[2], np.array(self._seconds) * 1e3
        self._start, self._seconds = (received, dropped, now), []
        if lost < self.warn_share * got:
            return None
        interval = 1e3 * elapsed / got if elapsed > 0.0 else math.nan
        return Backlog(got, lost, interval, float(times.mean()), float(np.percentile(times, 90)))
