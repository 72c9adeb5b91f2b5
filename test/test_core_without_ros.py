"""The core must import and run where rclpy and the message packages are missing."""

from __future__ import annotations

import os
import subprocess
import sys

CORE = [
    'initsel_ros', 'initsel_ros.camera', 'initsel_ros.errors', 'initsel_ros.features',
    'initsel_ros.models', 'initsel_ros.tracking', 'initsel_ros.geometry',
    'initsel_ros.policy', 'initsel_ros.selector', 'initsel_ros.cli',
]

BLOCKER = """
import importlib.abc, sys
class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in {blocked!r}:
            raise ImportError('blocked for this test: ' + name)
sys.meta_path.insert(0, Block())
"""


def test_core_modules_import_with_ros_packages_blocked():
    blocked = {'rclpy', 'sensor_msgs', 'std_msgs', 'geometry_msgs', 'rosidl_runtime_py'}
    modules = list(CORE)
    for extra in ('initsel_ros.datasets', 'initsel_ros.synth', 'initsel_ros.learn'):
        try:
            __import__(extra)
            modules.append(extra)
        except ImportError:
            pass
    code = BLOCKER.format(blocked=blocked) + ''.join(f'import {m}\n' for m in modules)
    code += 'print("ok")\n'
    env = {k: v for k, v in os.environ.items() if k != 'PYTHONPATH'}
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120, env=env)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == 'ok'
