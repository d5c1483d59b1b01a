"""Markdown tables, the one way every report of the project writes them."""
from typing import Iterable, List, Sequence


def markdown_table(header: Sequence[object],
                   rows: Iterable[Sequence[object]],
                   align: str = '') -> List[str]:
    """The lines of a markdown table.

    Args:
        header (Sequence): Column titles.
        rows (Iterable[Sequence]): Cells, one sequence per row, as many as
            the header; each printed with ``str``.
        align (str): One letter per column, ``'r'`` right-aligned (``---:``)
            or anything else left (``---``); shorter than the header: the
            rest left. Defaults to all left.

    Returns:
        list[str]: The header line, the separator line, one line per row.

    Raises:
        ValueError: a row with another number of cells than the header.
    """
    header = [str(h) for h in header]
    seps = ['---:' if i < len(align) and align[i] == 'r' else '---'
            for i in range(len(header))]
    lines = ['| ' + ' | '.join(header) + ' |', '|' + '|'.join(seps) + '|']
    for row in rows:
        cells = [str(c) for c in row]
        if len(cells) != len(header):
            raise ValueError(f'markdown_table: a row of {len(cells)} cells '
                             f'under {len(header)} columns: {cells}')
        lines.append('| ' + ' | '.join(cells) + ' |')
    return lines
