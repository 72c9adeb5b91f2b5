"""The package builds with colcon (ament_python) into the layout `ros2 run` expects.

colcon and ament_package come from PyPI into a separate virtual environment (colcon wants
setuptools < 80): ``pip install colcon-common-extensions ros-jazzy-ament-package 'setuptools<80'``.
Set INITSEL_COLCON_VENV to a prepared one to skip that step; without network the test skips.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest
from ros_helpers import ROOT, ros_environment, stop_process

COLCON_PACKAGES = ('colcon-common-extensions', 'ros-jazzy-ament-package', 'setuptools<80')
#: Variables of this (ROS wheels) environment that must not leak into another venv.
FOREIGN_VARS = (
    '_ROS_WHEELS_BOOTSTRAP_COMPLETE',
    'LD_LIBRARY_PATH',
    'VIRTUAL_ENV',
    'PYTHONPATH',
    'AMENT_PREFIX_PATH',
    'PYTHONHOME',
)


def _clean_env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in FOREIGN_VARS}
    env['PATH'] = os.pathsep.join(
        p
        for p in env.get('PATH', '').split(os.pathsep)
        if not os.environ.get('VIRTUAL_ENV') or not p.startswith(os.environ['VIRTUAL_ENV'])
    )
    return env


@pytest.fixture(scope='module')
def colcon(tmp_path_factory) -> Path:
    """Path of a colcon executable in a venv of its own."""
    prepared = os.environ.get('INITSEL_COLCON_VENV')
    if prepared:
        exe = Path(prepared) / 'bin' / 'colcon'
        if not exe.is_file():
            pytest.fail(f'INITSEL_COLCON_VENV={prepared} has no bin/colcon')
        return exe
    venv = tmp_path_factory.mktemp('colcon-venv')
    base_python = getattr(sys, '_base_executable', None) or sys.executable
    env = _clean_env()
    try:
        subprocess.run(
            [base_python, '-m', 'venv', str(venv)],
            env=env,
            check=True,
            capture_output=True,
            timeout=120,
        )
        subprocess.run(
            [
                str(venv / 'bin' / 'python'),
                '-m',
                'pip',
                'install',
                '--quiet',
                '--disable-pip-version-check',
                *COLCON_PACKAGES,
            ],
            env=env,
            check=True,
            capture_output=True,
            text=True,
            timeout=400,
        )
    except subprocess.CalledProcessError as exc:
        pytest.skip(f'cannot install {" ".join(COLCON_PACKAGES)}: {exc.stderr or exc}'[-500:])
    except subprocess.TimeoutExpired:
        pytest.skip(f'installing {" ".join(COLCON_PACKAGES)} timed out')
    return venv / 'bin' / 'colcon'


@pytest.fixture(scope='module')
def install_prefix(colcon, tmp_path_factory) -> Path:
    """colcon build of a copy of this source tree; the workspace's install/ directory."""
    ws = tmp_path_factory.mktemp('colcon-ws')
    shutil.copytree(
        ROOT,
        ws / 'src' / 'initsel_ros',
        ignore=shutil.ignore_patterns(
            '.git',
            '.venv*',
            '*.egg-info',
            '__pycache__',
            'build',
            'install',
            'log',
            '.pytest_cache',
            '.ruff_cache',
            'out',
        ),
    )
    env = _clean_env()
    env['PATH'] = os.pathsep.join([str(colcon.parent), env['PATH']])
    result = subprocess.run(
        [
            str(colcon),
            'build',
            '--base-paths',
            'src',
            '--build-base',
            'build',
            '--install-base',
            'install',
            '--event-handlers',
            'console_direct-',
        ],
        cwd=ws,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    return ws / 'install'


def _installed_env(install: Path) -> dict[str, str]:
    """This test venv's Python (it has rclpy) running the colcon-installed package."""
    env = ros_environment()
    prefix = install / 'initsel_ros'
    site = next((prefix / 'lib').glob('python3*/site-packages'))
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(site), env.get('PYTHONPATH')]))
    env['AMENT_PREFIX_PATH'] = os.pathsep.join(
        filter(None, [str(prefix), os.environ.get('AMENT_PREFIX_PATH')])
    )
    return env


def test_colcon_installs_scripts_config_launch_file_and_the_ament_marker(install_prefix):
    prefix = install_prefix / 'initsel_ros'
    for script in ('selector', 'initsel-selector', 'initsel'):
        assert (prefix / 'lib' / 'initsel_ros' / script).is_file(), script
    config = prefix / 'share' / 'initsel_ros' / 'config'
    source_params = (ROOT / 'config' / 'selector.yaml').read_text()
    assert (config / 'selector.yaml').read_text() == source_params
    assert (
        prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / 'initsel_ros'
    ).is_file()
    assert (prefix / 'share' / 'initsel_ros' / 'package.xml').is_file()
    launch = prefix / 'share' / 'initsel_ros' / 'launch' / 'selector.launch.py'
    assert launch.read_text() == (ROOT / 'launch' / 'selector.launch.py').read_text()
    if (ROOT / 'config' / 'models.json').is_file():
        assert (config / 'models.json').is_file()


def test_installed_selector_prints_help(install_prefix):
    script = install_prefix / 'initsel_ros' / 'lib' / 'initsel_ros' / 'selector'
    result = subprocess.run(
        [sys.executable, str(script), '--help'],
        env=_installed_env(install_prefix),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0, result.stderr
    assert 'init/method' in result.stdout and 'reference_frame_id' in result.stdout


def test_installed_selector_starts_with_its_share_config_and_stops_on_sigint(
    install_prefix, tmp_path
):
    if not (ROOT / 'config' / 'models.json').is_file():
        pytest.skip('config/models.json (trained model) is not in the source tree')
    prefix = install_prefix / 'initsel_ros'
    script = prefix / 'lib' / 'initsel_ros' / 'selector'
    params = prefix / 'share' / 'initsel_ros' / 'config' / 'selector.yaml'
    log = tmp_path / 'selector.log'
    with log.open('w') as out:
        proc = subprocess.Popen(
            [
                sys.executable,
                str(script),
                '--ros-args',
                '--params-file',
                str(params),
                '-r',
                '__ns:=/colcon_test',
            ],
            env=_installed_env(install_prefix),
            stdout=out,
            stderr=subprocess.STDOUT,
        )
        try:
            deadline = time.monotonic() + 60
            while 'ready:' not in log.read_text() and proc.poll() is None:
                assert time.monotonic() < deadline, log.read_text()
                time.sleep(0.1)
            assert proc.poll() is None, log.read_text()
        finally:
            code = stop_process(proc)
    text = log.read_text()
    assert f'model file {prefix / "share" / "initsel_ros" / "config" / "models.json"}' in text
    assert code == 0, text
