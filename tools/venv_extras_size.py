"""Size of the venv and of the optional analysis extras in it (requirements/analysis.txt and what only they pull in).

    python tools/venv_extras_size.py

The extras' share: the installed files of every distribution that the extras require (transitively) and no
other requirement file does (core, ROS, test). Prints MiB and the share; last line one JSON object.
"""

from __future__ import annotations

import json
import re
import sys
from importlib import metadata
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BASE = ('core.txt', 'ros-jazzy.txt', 'test.txt')
EXTRAS = ('analysis.txt',)


def _canon(name: str) -> str:
    return re.sub(r'[-_.]+', '-', name).lower()


def _names(files) -> set[str]:
    out = set()
    for f in files:
        for line in (ROOT / 'requirements' / f).read_text().splitlines():
            line = line.split('#', 1)[0].strip()
            if line and not line.startswith('-'):
                out.add(_canon(re.split(r'[<>=!~;\[ ]', line, maxsplit=1)[0]))
    return out


def _closure(names: set[str], dists: dict) -> set[str]:
    seen, todo = set(), list(names)
    while todo:
        n = todo.pop()
        if n in seen or n not in dists:
            continue
        seen.add(n)
        for req in dists[n].requires or []:
            if 'extra ==' in req:  # an optional extra of that package, not installed for it
                continue
            todo.append(_canon(re.split(r'[<>=!~;\[ (]', req, maxsplit=1)[0]))
    return seen


def _size_mib(dist) -> float:
    total = 0
    for f in dist.files or []:
        p = Path(dist.locate_file(f))
        if p.is_file():
            total += p.stat().st_size
    return total / 2**20


def main() -> int:
    dists = {_canon(d.metadata['Name']): d for d in metadata.distributions()}
    base = _closure(_names(BASE), dists)
    only_extras = _closure(_names(EXTRAS), dists) - base
    venv = sum(p.stat().st_size for p in Path(sys.prefix).rglob('*') if p.is_file() and not p.is_symlink()) / 2**20
    extras = sum(_size_mib(dists[n]) for n in only_extras)
    print(f'venv {sys.prefix}: {venv:.0f} MiB')
    names = ', '.join(sorted(only_extras))
    print(f'optional extras ({names}): {extras:.0f} MiB = {100 * extras / venv:.0f} % of the venv')
    print(f'without the extras: {venv - extras:.0f} MiB')
    print(json.dumps({'venv_mib': venv, 'extras_mib': extras, 'extras_packages': sorted(only_extras)}))
    return 0


if __name__ == '__main__':
    sys.exit(main())
