"""Sequences opened once per process, for batch workers that read one sequence many times.

Opening a bag scans all of its messages, and a TUM folder reads its listings and trajectory,
so the offline tools' workers keep each sequence they open: one entry per path and reader
options, until :func:`forget_sequences`.
"""

from __future__ import annotations

import logging
from contextlib import nullcontext
from pathlib import Path
from typing import Any

from initsel_ros.datasets.sequence import Sequence

_OPEN: dict[tuple[str, tuple[tuple[str, str], ...]], Sequence] = {}
#: The readers' logger: its warnings are silenced for a worker whose caller said them already.
READERS_LOG = 'initsel_ros.datasets'


def _key(path: Path | str, options: dict[str, Any]) -> tuple[str, tuple[tuple[str, str], ...]]:
    return str(path), tuple(sorted((name, repr(value)) for name, value in options.items()))


class _ReadersQuiet:
    """Only the readers' errors are logged inside this context."""

    def __enter__(self) -> None:
        readers = logging.getLogger(READERS_LOG)
        self._level = readers.level
        readers.setLevel(logging.ERROR)

    def __exit__(self, *exc: object) -> None:
        logging.getLogger(READERS_LOG).setLevel(self._level)


def open_cached(path: Path | str, *, quiet: bool = False, **options: Any) -> Sequence:
    """``open_sequence(path, **options)``, once per process for each path and options.

    ``quiet``: the readers' warnings and notes are not logged when it opens (a worker whose
    caller opened the sequence, and said them, before).
    """
    key = _key(path, options)
    sequence = _OPEN.get(key)
    if sequence is None:
        from initsel_ros.datasets import open_sequence

        with _ReadersQuiet() if quiet else nullcontext():
            sequence = _OPEN[key] = open_sequence(path, **options)
    return sequence


def keep_sequence(sequence: Sequence, path: Path | str, /, **options: Any) -> None:
    """Keep ``sequence``, opened by the caller, as :func:`open_cached` would with ``path`` and
    ``options`` (batches run in the caller's process then read that very sequence)."""
    _OPEN[_key(path, options)] = sequence


def forget_sequences() -> None:
    """Drop every kept sequence: the next :func:`open_cached` reads afresh."""
    _OPEN.clear()


__all__ = ['READERS_LOG', 'forget_sequences', 'keep_sequence', 'open_cached']
