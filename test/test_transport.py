"""The Fast DDS shared-memory limit: read from the profile file, and the oversize warning."""

from __future__ import annotations

from pathlib import Path

from initsel_ros.ros.transport import (
    DEFAULT_SEGMENT_BYTES,
    ShmLimit,
    oversize_warning,
    shm_limit,
)

PROFILE = Path(__file__).resolve().parent.parent / 'config' / 'fastdds_shm.xml'
VGA_RGB8 = 640 * 480 * 3


def test_the_shipped_profile_gives_a_16_mib_segment():
    limit = shm_limit({'FASTRTPS_DEFAULT_PROFILES_FILE': str(PROFILE)})
    assert limit == ShmLimit(16 * 2**20, str(PROFILE))
    assert limit.fits(VGA_RGB8) and limit.fits(4096 * 1024 * 3)
    assert not limit.fits(16 * 2**20)


def test_without_a_profile_the_fast_dds_default_applies_and_a_vga_frame_does_not_fit():
    limit = shm_limit({})
    assert limit.segment_bytes == DEFAULT_SEGMENT_BYTES == 512 * 1024
    assert not limit.fits(VGA_RGB8)
    assert 'no profile file' in limit.source


def test_a_profile_without_shm_or_unreadable_counts_as_the_default(tmp_path):
    udp_only = tmp_path / 'udp.xml'
    udp_only.write_text(
        '<dds><profiles><transport_descriptors><transport_descriptor>'
        '<transport_id>u</transport_id><type>UDPv4</type>'
        '</transport_descriptor></transport_descriptors></profiles></dds>'
    )
    for path in (udp_only, tmp_path / 'missing.xml'):
        limit = shm_limit({'FASTRTPS_DEFAULT_PROFILES_FILE': str(path)})
        assert limit.segment_bytes == DEFAULT_SEGMENT_BYTES and 'sets no SHM size' in limit.source


def test_the_warning_names_the_sizes_the_profile_and_the_fix():
    limit = ShmLimit(16 * 2**20, 'config/fastdds_shm.xml')
    assert oversize_warning(VGA_RGB8, limit) is None
    warning = oversize_warning(4096 * 2160 * 3, limit)
    assert warning is not None and '\n' not in warning
    assert '25.31 MiB' in warning and '16.00 MiB' in warning
    assert 'config/fastdds_shm.xml' in warning
    assert 'segment_size' in warning and 'docs/node.md' in warning
