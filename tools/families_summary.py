#!/usr/bin/env python3
"""The baseline families on every case of a results file: Markdown tables for docs/results.md.

Usage (repository root, after ``source tools/env.sh``)::

    python tools/families_summary.py runs/fam/results.json > /tmp/families.md

Per case, at three discomfort levels relative to D_lo (the least discomfort of any family vertex):
1.002 D_lo (as comfortable as any baseline), 1.02 D_lo (the comfort phase held near the band edge:
where the strategies sit) and 1.25 D_lo,
the energy of each family's front there (``front.Envelope`` semantics: a family past its least
comfortable vertex keeps that vertex's energy; n/a below its most comfortable one), the strongest family,
and the energy the strongest family saves against the production PI (the plain family with the
production gains) at that discomfort; then which family is the strongest (results.json's
``strongest.family``). Everything is read from results.json and computed with
``ceco_bringup.benchmark.front``.
"""

from __future__ import annotations

import argparse
import json
import sys

from ceco_bringup.benchmark import front as fr
from ceco_bringup.benchmark.schema import FAMILIES

FACTORS = (1.002, 1.02, 1.25)
"""Levels as multiples of D_lo. Not D_lo itself: the fronts are nearly vertical there (the pull-down's
discomfort is common to every law; 2e-5 PMV h more can cost 7 % more energy), so 1.002 D_lo stands for
"as comfortable as any baseline"."""


def _fronts(case) -> dict:
    return {
        fam: fr.build_front([(p['controller'], p['discomfort'], p['energy']) for p in pts]) if pts else None
        for fam, pts in case['fronts'].items()
    }


def _energy(front, x):
    """A family's energy at a discomfort budget x: its front at min(x, D_max); None below D_min (or no front)."""
    if front is None or x < front.d_range[0]:
        return None
    return front.energy_at(min(x, front.d_range[1]))


def family_table(doc) -> str:
    """One row per case and level: each family's energy, the strongest, its saving against the production PI."""
    fams = list(FAMILIES)
    lines = [
        '| case | level [PMV·h] | '
        + ' | '.join(f'E {f} [kWh]' for f in fams)
        + ' | strongest | saving vs production PI [%] |',
        '|---|---|' + '---|' * len(fams) + '---|---|',
    ]
    for case in doc['cases']:
        fronts = _fronts(case)
        env = fr.Envelope.of(fronts)
        d_lo = env.d_range[0]
        for k in FACTORS:
            x = k * d_lo
            cells = []
            for f in fams:
                e = _energy(fronts[f], x)
                cells.append('n/a' if e is None else f'{e:.4f}')
            e_env, e_pl = env.energy_at(x), _energy(fronts['plain'], x)
            save = 'n/a' if e_env is None or e_pl is None else f'{100.0 * (e_pl - e_env) / e_pl:+.1f}'
            lines.append(
                f"| {case['case']} | {x:.4f} ({k:g} D_lo) | " + ' | '.join(cells) + f' | {env.family_at(x)} | {save} |'
            )
    return '\n'.join(lines)


def strongest_table(doc) -> str:
    """The strongest family per case at the oracle's levels (recomputed with this code's ``runner.oracle_levels``)."""
    from ceco_bringup.benchmark import runner

    lines = ['| case | strongest family | at the oracle levels [PMV·h: family] |', '|---|---|---|']
    for case in doc['cases']:
        st = fr.strongest_by_level(fr.Envelope.of(_fronts(case)), runner.oracle_levels(case['runs']))
        per = ', '.join(f"{x['discomfort']:.4f}: {x['family']}" for x in st['levels'])
        lines.append(f"| {case['case']} | {st['family']} | {per} |")
    return '\n'.join(lines)


def main(argv=None) -> int:
    """Print the tables."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('results', help='results.json of ceco benchmark')
    args = ap.parse_args(argv)
    doc = json.loads(open(args.results, encoding='utf-8').read())
    print(family_table(doc))
    print()
    print(strongest_table(doc))
    return 0


if __name__ == '__main__':
    sys.exit(main())
