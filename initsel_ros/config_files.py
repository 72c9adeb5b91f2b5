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
    prefixes = [Path(p) for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    prefixes += [*_install_prefixes(Path(__file__).absolute()), Path(sys.prefix)]
    dirs = [prefix / 'share' / PACKAGE / 'config' for prefix in prefixes]
    dirs.append(Path(__file__).resolve().parent.parent / 'config')
    return list(dict.fromkeys(dirs))  # each once, in order


def _install_prefixes(module: Path) -> list[Path]:
    """The prefix this package is installed under, from the module's own path: ``PREFIX`` of
    ``PREFIX/lib/pythonX.Y/site-packages/initsel_ros/...`` (and of Debian's
    ``PREFIX/local/lib/pythonX.Y/dist-packages``); none in a source tree. A colcon install
    then finds its own ``share/`` without its setup script sourced."""
    for parent in module.parents:
        if parent.name in ('site-packages', 'dist-packages') and len(parent.parents) >= 3:
            prefix = parent.parents[2]  # .../lib/pythonX.Y/site-packages -> ...
            return [prefix, prefix.parent] if prefix.name == 'local' else [prefix]
    return []


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
