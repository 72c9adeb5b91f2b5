"""One home for finding the packaged configuration files (models, parameters, Fast DDS profile).

Installed with colcon they are in ``share/initsel_ros/config`` under an ament prefix, with pip
under the interpreter prefix, and in an editable install in the source tree.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from initsel_ros.errors import ModelFileError

PACKAGE = 'initsel_ros'


def config_dirs() -> list[Path]:
    """Where packaged configuration is looked for, most specific first.

    The ament share directories (``$AMENT_PREFIX_PATH/*/share/initsel_ros/config``), the
    interpreter prefix (``pip install``), then the source tree (editable installs).
    """
    dirs: list[Path] = []
    for prefix in filter(None, os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)):
        dirs.append(Path(prefix) / 'share' / PACKAGE / 'config')
    dirs.append(Path(sys.prefix) / 'share' / PACKAGE / 'config')
    dirs.append(Path(__file__).resolve().parent.parent / 'config')
    return dirs


def find_config_file(name: str) -> Path:
    """The first existing ``config/<name>`` among :func:`config_dirs`.

    Raises:
        ModelFileError: when no directory holds it (the message lists where it looked).
    """
    candidates = [d / name for d in config_dirs()]
    for path in candidates:
        if path.is_file():
            return path
    raise ModelFileError(
        f'{name} not found; looked in: ' + ', '.join(str(p.parent) for p in candidates)
    )


__all__ = ['PACKAGE', 'config_dirs', 'find_config_file']
