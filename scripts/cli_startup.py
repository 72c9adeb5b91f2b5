"""Start-up time of ``initsel [SUB] --help``: median wall time of 10 runs, and what it imports.

Usage (inside the environment): ``python scripts/cli_startup.py [SUB]``.
"""

import os
import statistics
import subprocess
import sys
import time

RUNS = 10
PROBE = (
    'import sys\nfrom initsel_ros.cli import main\ntry:\n    main(sys.argv[1:])\n'
    'except SystemExit:\n    pass\nprint(len(sys.modules), sorted(m for m in sys.modules '
    "if m.split('.')[0] in ('cv2', 'sklearn', 'rclpy', 'numpy')))"
)


def main() -> None:
    """Print the median, min and max of RUNS runs and the count of modules imported."""
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ('_ROS_WHEELS_BOOTSTRAP_COMPLETE', 'LD_LIBRARY_PATH')
    }
    script = os.path.join(os.path.dirname(sys.executable), 'initsel')
    argv = [script, *sys.argv[1:], '--help']
    times = []
    for _ in range(RUNS):
        start = time.perf_counter()
        subprocess.run(argv, env=env, stdout=subprocess.DEVNULL, timeout=60, check=True)
        times.append(time.perf_counter() - start)
    probe = subprocess.run(
        [sys.executable, '-c', PROBE, *sys.argv[1:], '--help'],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    print(
        f'initsel {" ".join(sys.argv[1:])} --help: median '
        f'{statistics.median(times) * 1000:.0f} ms over {RUNS} runs (min '
        f'{min(times) * 1000:.0f}, max {max(times) * 1000:.0f}); modules, heavy ones: '
        f'{probe.stdout.strip().splitlines()[-1]}'
    )


if __name__ == '__main__':
    main()
