"""Reading model files safely: bounded, non-blocking reads, bounded JSON nesting, and the
schema's primitive checks (flat lists of finite numbers, numbers in range).

Numbers are checked as the values they must become: every float a finite float64 (an integer
literal such as 10^400 is not), every index an integer within its bounds (checked as a Python
int, before any conversion to int64). Integer literals too long for Python to convert (over
4300 digits) are read as infinite floats, so they too are refused naming their field.
Everything here raises :class:`~initsel_ros.errors.ModelFileError` with a one-line message,
whatever the JSON holds.
"""

from __future__ import annotations

import json
import math
import numbers
import os
import stat
from pathlib import Path
from typing import Any

import numpy as np

from initsel_ros.errors import ModelFileError

#: A model file larger than this is refused before reading (real ones are well under 1 MiB).
MAX_FILE_BYTES = 16 * 1024 * 1024
#: Deepest JSON nesting a model file may have (real ones nest about 5 levels).
MAX_JSON_DEPTH = 64
#: Longest integer literal read as an int; longer ones cannot be a finite float64 (the
#: largest has 309 digits) nor a usable index, and become infinite floats.
MAX_INT_DIGITS = 400


def _parse_int(text: str) -> int | float:
    """JSON integer literal -> int, or +-inf beyond :data:`MAX_INT_DIGITS` digits."""
    if len(text) > MAX_INT_DIGITS:
        return -math.inf if text.startswith('-') else math.inf
    return int(text)


def read_bounded(path: Path, max_bytes: int = MAX_FILE_BYTES) -> bytes:
    """The bytes of a regular file of at most ``max_bytes``, without ever blocking.

    The file is opened non-blocking (a FIFO then opens at once instead of waiting for a
    writer) and checked with fstat before anything is read.

    Raises:
        ModelFileError: not readable, not a regular file (FIFO, device, directory), too large.
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, 'O_CLOEXEC', 0))
    except OSError as exc:
        raise ModelFileError(f'cannot read model file: {exc.strerror or exc}') from exc
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            kind = (
                'a directory'
                if stat.S_ISDIR(info.st_mode)
                else 'a FIFO'
                if stat.S_ISFIFO(info.st_mode)
                else 'a device'
                if stat.S_ISCHR(info.st_mode) or stat.S_ISBLK(info.st_mode)
                else 'a socket'
            )
            raise ModelFileError(f'not a regular file ({kind}); a model file is a JSON file')
        if info.st_size > max_bytes:
            raise ModelFileError(
                f'model file is larger than {max_bytes // (1024 * 1024)} MiB '
                f'({info.st_size} bytes); real model files are well under 1 MiB'
            )
        chunks, total = [], 0
        while chunk := os.read(fd, 1 << 20):  # the file may grow after fstat: stay bounded
            chunks.append(chunk)
            total += len(chunk)
            if total > max_bytes:
                raise ModelFileError(f'model file grew larger than {max_bytes} bytes while read')
        return b''.join(chunks)
    except OSError as exc:
        raise ModelFileError(f'cannot read model file: {exc.strerror or exc}') from exc
    finally:
        os.close(fd)


def json_depth(data: bytes) -> int:
    """Deepest nesting of ``[``/``{`` in JSON text, ignoring brackets inside strings.

    Vectorized (no recursion, no per-character Python loop), in 1 MiB chunks so memory stays
    small. Exact for valid JSON; for invalid JSON the parser reports the problem itself.
    """
    # Drop escaped backslashes first, then escaped quotes: what remains of '"' delimits strings.
    text = data.replace(b'\\\\', b'').replace(b'\\"', b'')
    depth, parity, deepest = 0, 0, 0
    step = 1 << 20
    for start in range(0, len(text), step):
        b = np.frombuffer(text, np.uint8, count=min(step, len(text) - start), offset=start)
        in_string = (np.cumsum(b == 34, dtype=np.int64) + parity) & 1
        code = np.zeros(len(b), np.int8)
        code[(b == 91) | (b == 123)] = 1
        code[(b == 93) | (b == 125)] = -1
        code[in_string.astype(bool)] = 0
        level = np.cumsum(code, dtype=np.int64) + depth
        if len(level):
            deepest = max(deepest, int(level.max()))
            depth = int(level[-1])
        parity = int(in_string[-1]) if len(b) else parity
    return deepest


def parse_json_bounded(data: bytes, max_depth: int = MAX_JSON_DEPTH) -> Any:
    """Parse JSON text whose nesting is at most ``max_depth``.

    Raises:
        ModelFileError: binary content, nesting too deep, or invalid JSON.
    """
    try:
        text = data.decode('utf-8')
    except UnicodeDecodeError as exc:
        raise ModelFileError(
            f'not a text model file (binary content at byte {exc.start}); '
            'model files are plain JSON, never pickles'
        ) from exc
    depth = json_depth(data)
    if depth > max_depth:
        raise ModelFileError(
            f'JSON nested deeper than {max_depth} levels ({depth}); not a model file'
        )
    try:
        return json.loads(text, parse_int=_parse_int)
    except json.JSONDecodeError as exc:
        raise ModelFileError(f'not valid JSON (line {exc.lineno}): {exc.msg}') from exc
    except (ValueError, OverflowError) as exc:  # e.g. a number the float parser rejects
        raise ModelFileError(f'not a readable JSON number: {str(exc)[:80]}') from exc
    except RecursionError as exc:  # unreachable after the depth check; kept as a guard
        raise ModelFileError('JSON nested too deeply; not a model file') from exc


def _is_number(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _as_float(value: Any) -> float:
    """A JSON number as float64; +-inf when it lies beyond float64's range (10^400)."""
    try:
        return float(value)
    except OverflowError:
        return math.inf if value > 0 else -math.inf


def number_list(value: Any, what: str, length: int) -> np.ndarray:
    """A flat JSON list of ``length`` finite numbers as (length,) float64.

    Raises:
        ModelFileError: nested lists, strings, booleans, NaN/infinity or the wrong length.
    """
    if not isinstance(value, list) or not all(_is_number(v) for v in value):
        raise ModelFileError(f'{what} must be a flat list of {length} numbers')
    if len(value) != length:
        raise ModelFileError(f'{what} must have {length} values, got {len(value)}')
    arr = np.array([_as_float(v) for v in value], dtype=np.float64)
    if not np.all(np.isfinite(arr)):
        bad = int(np.flatnonzero(~np.isfinite(arr))[0])
        raise ModelFileError(
            f'{what} contains NaN or infinity, or a number beyond float64 (value {bad}: '
            f'{_brief(value[bad])})'
        )
    return arr


def _brief(value: Any) -> str:
    """A JSON value for a one-line message (huge integers by their size only)."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**20:
        return f'an integer of {len(str(abs(value)))} digits'
    if isinstance(value, float) and math.isinf(value):
        return 'infinite, or an integer literal of more than 400 digits'
    return f'{value!r:.40}'


def finite_number(value: Any, what: str) -> float:
    """A JSON number that is a finite float64, as float; raises ModelFileError otherwise."""
    if not _is_number(value):
        raise ModelFileError(f'{what} must be a finite number (non-numeric: {value!r:.40})')
    if not math.isfinite(_as_float(value)):
        raise ModelFileError(f'{what} must be a finite number (float64), got {_brief(value)}')
    return _as_float(value)


def unit_number(value: Any, what: str) -> float:
    """A JSON number in [0, 1] as float; raises ModelFileError otherwise."""
    if not _is_number(value):
        raise ModelFileError(f'{what} must be a number in [0, 1], got {_brief(value)}')
    v = _as_float(value)
    if not 0.0 <= v <= 1.0:
        raise ModelFileError(f'{what} must be in [0, 1], got {v}')
    return v


def metrics_mapping(data: dict[str, Any], where: str) -> dict[str, Any]:
    """A model entry's optional ``"metrics"`` mapping (absent or null: empty), copied;
    raises ModelFileError when it is something else."""
    metrics = data.get('metrics', {}) or {}
    if not isinstance(metrics, dict):
        raise ModelFileError(f'{where}: "metrics" must be a mapping')
    return dict(metrics)


def int_list(value: Any, what: str, length: int, low: int, high: int) -> np.ndarray:
    """A flat JSON list of ``length`` integers in [low, high] as (length,) int64.

    Raises:
        ModelFileError: nested lists, non-integers, booleans, out-of-range values, bad length.
    """
    if not isinstance(value, list) or not all(
        isinstance(v, int) and not isinstance(v, bool) for v in value
    ):
        raise ModelFileError(f'{what} must be a flat list of {length} integers')
    if len(value) != length:
        raise ModelFileError(f'{what} must have {length} values, got {len(value)}')
    for i, v in enumerate(value):  # Python ints: no overflow, whatever their size
        if not low <= v <= high:
            raise ModelFileError(f'{what} must lie in [{low}, {high}]; value {i} is {_brief(v)}')
    return np.asarray(value, dtype=np.int64)


def name_list(value: Any, what: str, allowed: tuple[str, ...]) -> tuple[str, ...]:
    """A non-empty flat list of distinct names, each one of ``allowed``."""
    if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
        raise ModelFileError(f'{what} must be a non-empty list of feature names')
    unknown = [v for v in value if v not in allowed]
    if unknown:
        raise ModelFileError(
            f'{what}: unknown features {unknown[:3]} (this version computes {", ".join(allowed)})'
        )
    if len(set(value)) != len(value):
        raise ModelFileError(f'{what} lists a feature twice')
    return tuple(value)
