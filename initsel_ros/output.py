"""Files written whole or not at all: a temporary file beside the target, then a rename."""

from __future__ import annotations

import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TextIO

from initsel_ros.errors import InitselError


class OutputError(InitselError):
    """An output path that cannot be written (a folder, for one)."""


def check_file_target(path: Path | str) -> Path:
    """``path`` as a Path, when it can name a file to write.

    Raises:
        OutputError: ``path`` is a folder.
    """
    path = Path(path)
    if path.is_dir():
        raise OutputError(f'{path} is a folder: give the name of a file to write')
    return path


@contextmanager
def atomic_text(path: Path | str, newline: str | None = None) -> Iterator[TextIO]:
    """A text handle whose contents replace ``path`` when the block ends without an error.

    The parent folders are made; the file gets the usual permissions (the process umask,
    like any ``open``); its contents are synced to disk before the rename, so a crash leaves
    the old file or the new one, never an empty one; on an error the temporary file is
    removed and ``path`` is untouched.

    Raises:
        OutputError: ``path`` is a folder, or its folder cannot be made or written in.
    """
    path = check_file_target(path)
    tmp = path.with_name(f'.{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp')
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle = open(tmp, 'x', newline=newline)  # noqa: SIM115 (closed below, then renamed)
    except OSError as exc:
        raise OutputError(f'{path}: cannot write: {exc.strerror or exc}') from exc
    try:
        with handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())  # on disk before the rename makes it the file
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


__all__ = ['OutputError', 'atomic_text', 'check_file_target']
