"""Noticing a node that falls behind its camera (ROS-free).

The node keeps only the newest frame: one that arrives while another waits overwrites it and
counts as dropped. A few drops are the price of a busy moment; a steady share of them means
processing a frame takes longer than the camera's frame interval, and the decision sees a
camera at a lower rate than it runs. :class:`BacklogWatch` judges the dropped share over
windows of received frames and says when one is worth a warning, with the processing time
that explains it.
"""

from __future__ import annotations

import statistics
from dataclasses import dataclass

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
        median_ms: median processing time of the window's processed frames, milliseconds.
    """

    received: int
    dropped: int
    median_ms: float

    def message(self, max_tracking_width: int) -> str:
        """The warning a node logs, with what a user can change."""
        shrink = (
            f'lower max_tracking_width (now {max_tracking_width} px)'
            if max_tracking_width > 0
            else 'set max_tracking_width (e.g. 640) to track a downscaled image'
        )
        return (
            f'dropped {self.dropped} of the last {self.received} frames: processing one takes '
            f"a median of {self.median_ms:.0f} ms, longer than the camera's frames arrive "
            f"apart, so the decision sees a slower camera; {shrink}, or lower the camera's "
            'rate or resolution'
        )


class BacklogWatch:
    """Windows of received frames and their dropped share (see the module docstring)."""

    def __init__(
        self, window: int = BACKLOG_WINDOW_FRAMES, warn_share: float = BACKLOG_WARN_SHARE
    ):
        if window < 1 or not 0.0 < warn_share <= 1.0:
            raise ValueError(f'window {window} must be >= 1 and warn_share {warn_share} in (0, 1]')
        self.window, self.warn_share = window, warn_share
        self._start = (0, 0)  # received, dropped at the window's start
        self._seconds: list[float] = []

    def processed(self, received: int, dropped: int, seconds: float) -> Backlog | None:
        """Count one processed frame.

        Args:
            received: frames received so far (a running count).
            dropped: frames dropped so far (a running count).
            seconds: how long this frame's processing took.

        Returns:
            The window's figures when this frame closes a window of at least ``window``
            received frames with ``warn_share`` of them or more dropped; None otherwise (a
            window closes either way, and the next one starts).
        """
        self._seconds.append(seconds)
        got, lost = received - self._start[0], dropped - self._start[1]
        if got < self.window:
            return None
        median_ms = 1e3 * statistics.median(self._seconds)
        self._start, self._seconds = (received, dropped), []
        if lost < self.warn_share * got:
            return None
        return Backlog(got, lost, median_ms)
