"""The Fast DDS shared-memory segment: the largest message that crosses processes over SHM.

A message larger than the segment cannot use shared memory; Fast DDS then sends it as
fragmented UDP over loopback (when UDP is enabled, as in ``config/fastdds_shm.xml``), where a
best-effort subscriber such as the node loses many frames. This module reads the segment size
of the active profile file (no ROS import) so that publishers can warn before that happens.
"""

from __future__ import annotations

import logging
import os
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

#: Fast DDS's own shared-memory segment size, bytes (no profile file, or none sets it).
DEFAULT_SEGMENT_BYTES = 512 * 1024
#: Environment variables naming the Fast DDS profile file (new name first).
PROFILE_VARIABLES = ('FASTDDS_DEFAULT_PROFILES_FILE', 'FASTRTPS_DEFAULT_PROFILES_FILE')
#: Room kept for the RTPS headers and the message's other fields, bytes.
HEADER_ALLOWANCE = 4096


@dataclass(frozen=True)
class ShmLimit:
    """The shared-memory segment in use.

    Attributes:
        segment_bytes: segment size, bytes.
        source: the profile file it comes from, or a note that it is Fast DDS's default.
    """

    segment_bytes: int
    source: str

    def fits(self, message_bytes: int) -> bool:
        """True when a message of ``message_bytes`` (payload) fits in the segment."""
        return message_bytes + HEADER_ALLOWANCE <= self.segment_bytes


def shm_limit(environ: Mapping[str, str] | None = None) -> ShmLimit:
    """The SHM segment size of the active Fast DDS profile (or Fast DDS's default).

    An unreadable profile counts as the default (Fast DDS would not use it either).
    """
    env = os.environ if environ is None else environ
    for variable in PROFILE_VARIABLES:
        path = env.get(variable)
        if path:
            size = _segment_size(Path(path))
            if size is not None:
                return ShmLimit(size, path)
            return ShmLimit(DEFAULT_SEGMENT_BYTES, f'Fast DDS default ({path} sets no SHM size)')
    return ShmLimit(DEFAULT_SEGMENT_BYTES, 'Fast DDS default (no profile file)')


def oversize_warning(message_bytes: int, limit: ShmLimit | None = None) -> str | None:
    """A one-line warning when a message cannot cross processes over shared memory, else None."""
    limit = limit or shm_limit()
    if limit.fits(message_bytes):
        return None
    mib, segment_mib = message_bytes / 2**20, limit.segment_bytes / 2**20
    return (
        f'a frame of {mib:.2f} MiB does not fit the {segment_mib:.2f} MiB Fast DDS '
        f'shared-memory segment ({limit.source}): it goes over fragmented UDP, '
        'where a best-effort subscriber (the node) loses many frames; raise segment_size and '
        'maxMessageSize in the profile (see docs/node.md, Transport) or send smaller frames'
    )


class OversizeMonitor:
    """Warns once, through ``logging``, when frames cannot cross over shared memory."""

    def __init__(self, limit: ShmLimit | None = None) -> None:
        self.limit = limit or shm_limit()
        self.warned = False

    def check(self, message_bytes: int, topic: str = '') -> bool:
        """True when the message fits the segment; the first time one does not, log why."""
        text = oversize_warning(message_bytes, self.limit)
        if text is None:
            return True
        if not self.warned:
            self.warned = True
            logging.getLogger(__name__).warning('%s%s', f'{topic}: ' if topic else '', text)
        return False


def _segment_size(path: Path) -> int | None:
    """The largest ``segment_size`` of an SHM transport descriptor in a profile file."""
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError):
        return None
    sizes = []
    for descriptor in root.findall('.//{*}transport_descriptor'):
        kind = descriptor.findtext('{*}type', default='').strip().upper()
        text = descriptor.findtext('{*}segment_size', default='').strip()
        if kind == 'SHM' and text.isdigit():
            sizes.append(int(text))
    return max(sizes) if sizes else None


__all__ = ['DEFAULT_SEGMENT_BYTES', 'OversizeMonitor', 'ShmLimit', 'oversize_warning', 'shm_limit']
