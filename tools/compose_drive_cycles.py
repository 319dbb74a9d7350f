"""Compose the benchmark's constructed drive cycles from the bundled EPA schedules (deterministic).

    python tools/compose_drive_cycles.py     # rewrites the three files below in ceco_v2x_preview's data

Each output is 1 Hz, ``time_s,speed_mph``, made only of pieces of the public-domain EPA schedules
and stretches at standstill; the recipe is in the file's comment header and in
``ceco_v2x_preview/ceco_v2x_preview/data/drive_cycles/README.md``:

* ``sc03_idle``: SC03 0-360 s (the car is standing in SC03's stop at 350-370 s), 300 s more at
  standstill (a long idle in traffic), then SC03 361-600 s: 900 s.
* ``hwfet_udds``: the whole HWFET (765 s, ends at rest), then UDDS 1-505 s (the FTP's cold-transient
  phase, "bag 1", which ends at rest): highway to city, 1270 s.
* ``sc03_stop``: the whole SC03 (600 s, ends at rest), 240 s parked, then SC03 1-240 s: 1080 s.
"""

from __future__ import annotations

import csv
from pathlib import Path

DATA = Path(__file__).resolve().parents[1] / 'ceco_v2x_preview' / 'ceco_v2x_preview' / 'data' / 'drive_cycles'


def _read(name: str) -> list[float]:
    with open(DATA / f'{name}.csv', encoding='utf-8') as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].startswith('#')][1:]
    speeds = [float(r[1]) for r in rows]
    assert [int(float(r[0])) for r in rows] == list(range(len(rows))), f'{name}: not 1 Hz from 0'
    return speeds


def _write(name: str, speeds: list[float], recipe: str) -> None:
    lines = [f'# {line}' for line in recipe.strip().splitlines()]
    lines.append('time_s,speed_mph')
    lines += [f'{i},{v:g}' for i, v in enumerate(speeds)]
    (DATA / f'{name}.csv').write_text('\n'.join(lines) + '\n', encoding='utf-8')


def main() -> int:
    sc03, udds, hwfet = _read('sc03'), _read('udds'), _read('hwfet')
    assert sc03[360] == 0.0 and sc03[600] == 0.0 and hwfet[765] == 0.0 and udds[505] == 0.0
    _write(
        'sc03_idle',
        sc03[:361] + [0.0] * 300 + sc03[361:601],
        'Constructed by tools/compose_drive_cycles.py from the EPA SC03 schedule (public domain):\n'
        'SC03 0-360 s, 300 s more at standstill from 361 s (a long idle in traffic), SC03 361-600 s.',
    )
    _write(
        'hwfet_udds',
        hwfet[:766] + udds[1:506],
        'Constructed by tools/compose_drive_cycles.py from the EPA HWFET and UDDS schedules (public domain):\n'
        'HWFET 0-765 s (ends at rest), then UDDS 1-505 s (bag 1, ends at rest): highway to city.',
    )
    _write(
        'sc03_stop',
        sc03[:601] + [0.0] * 240 + sc03[1:241],
        'Constructed by tools/compose_drive_cycles.py from the EPA SC03 schedule (public domain):\n'
        'SC03 0-600 s (ends at rest), 240 s parked (601-840 s), then SC03 1-240 s.',
    )
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
