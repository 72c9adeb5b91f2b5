"""``python -m initsel_ros.cli.flood_publisher``: the publisher child of ``initsel bench --flood``.

:func:`initsel_ros.ros.bench_live.flood` runs the node in its own process and this publisher in
a child, so that publishing does not compete with the node for the interpreter lock. It prints
the summary of :func:`initsel_ros.ros.bench_live.flood_publisher` as one JSON line. Not a
subcommand of ``initsel``.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence


def main(argv: Sequence[str] | None = None) -> int:
    """Publish textured frames on image_raw, then print the summary; 0 when done."""
    parser = argparse.ArgumentParser(
        prog='initsel_ros.cli.flood_publisher', description='publish textured frames on image_raw'
    )
    parser.add_argument('--rate', type=float, default=200.0)
    parser.add_argument('--seconds', type=float, default=30.0)
    parser.add_argument('--width', type=int, default=1920)
    parser.add_argument('--height', type=int, default=1080)
    parser.add_argument('--encoding', choices=('bgr8', 'mono8'), default='bgr8')
    args = parser.parse_args(argv)
    from initsel_ros.ros.bench_live import flood_publisher

    summary = flood_publisher(args.rate, args.seconds, args.width, args.height, args.encoding)
    print(json.dumps(summary), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
