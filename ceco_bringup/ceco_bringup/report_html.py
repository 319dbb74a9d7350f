"""Render a report (a list of blocks) as Markdown and as self-contained HTML.

A report is a list of blocks, each one of

* ``Heading(level, text)``
* ``Paragraph(text)``           (plain text; ``**bold**`` is kept in Markdown)
* ``Warning(text)``             (a mismatch or other problem, shown loudly)
* ``Table(header, rows, caption)``  (cells already formatted as strings; ``**bold**`` and
  ``code`` spans render in the HTML as in paragraphs)
* ``Figure(path, caption)``     (a PNG; embedded as base64 in the HTML)

The HTML has no external reference (no CDN, no linked file): figures are
``data:image/png;base64`` URIs and the stylesheet is inline, so the one file
can be mailed or archived. Numbers are formatted here for every output: :func:`fmt_value` with a fixed format
(the console tables, the verdict's words, ``ceco_bringup.outputs`` and ``ceco_bringup.verdict``), :func:`fmt_num`
and :func:`fmt_pct` for the report's table cells; :func:`slug` makes file names. Pure Python (stdlib only).
"""

from __future__ import annotations

import base64
import dataclasses
import html
import math
import os
from collections.abc import Sequence
from pathlib import Path

__all__ = [
    'Heading',
    'Paragraph',
    'Warning',
    'Table',
    'Figure',
    'Block',
    'render_markdown',
    'render_html',
    'fmt_value',
    'fmt_num',
    'fmt_pct',
    'slug',
]


@dataclasses.dataclass(frozen=True)
class Heading:
    """A section title."""

    level: int
    """1..4."""
    text: str
    """Title text."""


@dataclasses.dataclass(frozen=True)
class Paragraph:
    """A paragraph of plain text."""

    text: str
    """The text."""


@dataclasses.dataclass(frozen=True)
class Warning:  # a report block, not the builtin exception
    """A problem the reader must see (metrics mismatch, missing data)."""

    text: str
    """The message."""


@dataclasses.dataclass(frozen=True)
class Table:
    """A table of pre-formatted cells."""

    header: tuple
    """Column titles."""
    rows: tuple
    """Rows, each a tuple of strings as long as the header."""
    caption: str = ''
    """Shown above the table."""

    def __post_init__(self):
        object.__setattr__(self, 'header', tuple(str(h) for h in self.header))
        object.__setattr__(self, 'rows', tuple(tuple(str(c) for c in r) for r in self.rows))
        for i, r in enumerate(self.rows):
            if len(r) != len(self.header):
                raise ValueError(f'rows[{i}]: {len(r)} cells for {len(self.header)} columns')


@dataclasses.dataclass(frozen=True)
class Figure:
    """A PNG figure."""

    path: Path
    """The PNG file."""
    caption: str = ''
    """Caption under the figure."""


Block = Heading | Paragraph | Warning | Table | Figure


def _md_cell(text: str) -> str:
    return text.replace('|', '\\|').replace('\n', ' ')


def render_markdown(blocks: Sequence[Block], base_dir: str | os.PathLike | None = None) -> str:
    """Markdown text of ``blocks``; figure links are relative to ``base_dir``."""
    out: list[str] = []
    for b in blocks:
        if isinstance(b, Heading):
            out.append('#' * max(1, min(4, b.level)) + ' ' + b.text)
        elif isinstance(b, Paragraph):
            out.append(b.text)
        elif isinstance(b, Warning):
            out.append('> **WARNING:** ' + b.text)
        elif isinstance(b, Table):
            if b.caption:
                out.append(f'*{b.caption}*\n')
            lines = [
                '| ' + ' | '.join(_md_cell(h) for h in b.header) + ' |',
                '|' + '|'.join('---' for _ in b.header) + '|',
            ]
            lines += ['| ' + ' | '.join(_md_cell(c) for c in r) + ' |' for r in b.rows]
            out.append('\n'.join(lines))
        elif isinstance(b, Figure):
            p = Path(b.path)
            rel = os.path.relpath(p, base_dir) if base_dir is not None else str(p)
            out.append(f'![{b.caption}]({rel})\n\n*{b.caption}*')
        else:
            raise TypeError(f'unknown block {type(b).__name__}')
    return '\n\n'.join(out) + '\n'


_CSS = """
body{font-family:-apple-system,'Segoe UI',Helvetica,Arial,sans-serif;max-width:1100px;margin:2em auto;
     padding:0 1em;color:#222;line-height:1.45}
h1{border-bottom:2px solid #0072B2;padding-bottom:.2em}h2{border-bottom:1px solid #ccc;margin-top:2em}
table{border-collapse:collapse;margin:.5em 0 1.2em;font-size:.88em}
th,td{border:1px solid #bbb;padding:.25em .55em;text-align:right}
th{background:#eef3f8}td:first-child,th:first-child{text-align:left}
tr:nth-child(even) td{background:#fafafa}
.warn{background:#fde2e1;border:2px solid #c0392b;color:#7b1d14;padding:.6em 1em;font-weight:600;margin:1em 0}
figure{margin:1em 0}figure img{max-width:100%;border:1px solid #ddd}
figcaption{font-size:.88em;color:#444}.caption{font-style:italic;color:#444}
"""


def _inline(text: str) -> str:
    """Escape, then render ``**bold**`` and ``code`` spans."""
    esc = html.escape(text)
    parts = esc.split('**')
    esc = ''.join(f'<b>{p}</b>' if i % 2 else p for i, p in enumerate(parts))
    parts = esc.split('`')
    return ''.join(f'<code>{p}</code>' if i % 2 else p for i, p in enumerate(parts))


def render_html(blocks: Sequence[Block], title: str = 'ceco report') -> str:
    """A self-contained HTML page of ``blocks`` (figures embedded as base64)."""
    body: list[str] = []
    for b in blocks:
        if isinstance(b, Heading):
            lvl = max(1, min(4, b.level))
            body.append(f'<h{lvl}>{_inline(b.text)}</h{lvl}>')
        elif isinstance(b, Paragraph):
            body.append(f'<p>{_inline(b.text)}</p>')
        elif isinstance(b, Warning):
            body.append(f'<div class="warn">WARNING: {_inline(b.text)}</div>')
        elif isinstance(b, Table):
            cap = f'<p class="caption">{_inline(b.caption)}</p>' if b.caption else ''
            # cells get the same inline formatter as paragraphs: **bold** and `code` render, never show
            head = ''.join(f'<th>{_inline(h)}</th>' for h in b.header)
            rows = ''.join('<tr>' + ''.join(f'<td>{_inline(c)}</td>' for c in r) + '</tr>' for r in b.rows)
            body.append(f'{cap}<table><thead><tr>{head}</tr></thead><tbody>{rows}</tbody></table>')
        elif isinstance(b, Figure):
            data = base64.b64encode(Path(b.path).read_bytes()).decode('ascii')
            body.append(
                f'<figure><img alt="{html.escape(b.caption)}" src="data:image/png;base64,{data}">'
                f'<figcaption>{_inline(b.caption)}</figcaption></figure>'
            )
        else:
            raise TypeError(f'unknown block {type(b).__name__}')
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f'<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>\n'
        + '\n'.join(body)
        + '\n</body></html>\n'
    )


def fmt_value(x, spec: str) -> str:
    """``x`` in the format ``spec`` (e.g. ``'.1f'``); 'n/a' for None, NaN or infinity (not defined, not recorded).

    A bool is 'yes' / 'no' and text is shown as it is (a table row mixes them with numbers).
    """
    if x is None:
        return 'n/a'
    if isinstance(x, bool):
        return 'yes' if x else 'no'
    if isinstance(x, str):
        return x
    x = float(x)
    return format(x, spec) if math.isfinite(x) else 'n/a'


def fmt_num(x, digits=3) -> str:
    """A table number: thousands grouped, 1 decimal from 100, else ``digits`` (tiny values in g); 'n/a' for NaN.

    Not :func:`fmt_value`: the format follows the magnitude (a column of the report spans kWh and thousands of
    ppm), and what is not a number is shown as it is (``str``), an infinity as ``inf``.
    """
    try:
        x = float(x)
    except (TypeError, ValueError):
        return str(x)
    if math.isnan(x):
        return 'n/a'
    if abs(x) >= 1000:
        return f'{x:,.0f}'
    if abs(x) >= 100:
        return f'{x:.1f}'
    return f'{x:.{digits}g}' if abs(x) < 1e-3 and x != 0 else f'{x:.{digits}f}'


def fmt_pct(x) -> str:
    """A signed percentage with one decimal; 'n/a' for NaN."""
    x = float(x)
    return 'n/a' if math.isnan(x) else f'{x:+.1f} %'


def slug(text: str) -> str:
    """``text`` as a file-name part: letters, digits, - and _ kept, the rest _."""
    return ''.join(c if c.isalnum() or c in '-_' else '_' for c in text)
