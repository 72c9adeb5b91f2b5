"""Markdown tables: the one layout every report of the package prints (``| a | b |``)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any


def markdown_table(columns: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    """``columns`` and ``rows`` (cells formatted with ``str``) as a Markdown table, no final
    newline."""
    lines = ['| ' + ' | '.join(columns) + ' |', '|' + '---|' * len(columns)]
    lines += ['| ' + ' | '.join(str(c) for c in row) + ' |' for row in rows]
    return '\n'.join(lines)


def number(value: float | None, digits: int = 3) -> str:
    """A table cell for a figure: ``digits`` decimals, ``-`` for None, NaN or infinity."""
    if value is None or not math.isfinite(value):
        return '-'
    return f'{value:.{digits}f}'


class Table:
    """A Markdown table built row by row."""

    def __init__(self, *columns: str) -> None:
        self.columns = columns
        self.rows: list[tuple[str, ...]] = []

    def add(self, *cells: Any) -> None:
        """Append a row (missing trailing cells are empty)."""
        cells = tuple(str(c) for c in cells) + ('',) * (len(self.columns) - len(cells))
        self.rows.append(cells)

    def render(self) -> str:
        """The table as Markdown."""
        return markdown_table(self.columns, self.rows)


__all__ = ['Table', 'markdown_table', 'number']
