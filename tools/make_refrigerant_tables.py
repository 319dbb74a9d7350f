#!/usr/bin/env python3
"""Regenerate the plant's refrigerant cycle tables, ceco_plant_sim/ceco_plant_sim/data/cycle_tables_R1234yf.npz.

Usage (from the repository root):

    .venv/bin/python tools/make_refrigerant_tables.py            # write the shipped file
    .venv/bin/python tools/make_refrigerant_tables.py --check    # exit 1 if it is stale
    .venv/bin/python tools/make_refrigerant_tables.py --show     # print its provenance

The file holds the raw float64 values that ``ceco_plant_sim.refrigerant.build_cycle_tables``
computes with CoolProp for the default ``PlantParams`` (R-1234yf, superheat 5 K, subcooling
5 K) on ``DEFAULT_GRID`` (t_e -30..30 degC and t_c 10..85 degC at 0.5 K, the isentropic work
at 2.5 K), with its provenance: format, fluid, superheat, subcooling, grid, CoolProp version
and git revision, this command, the UTC date, the machine and the ceco commit. The plant
loads it without importing CoolProp (``ceco_plant_sim.refrigerant.cycle_tables``).

``--check`` compares the file bit for bit with a fresh build by the installed CoolProp (and
its version with the one recorded), as tests/test_refrigerant.py does. Run this after
changing CoolProp, the grid, the default superheat/subcooling or the table code.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
for pkg in ('ceco_core', 'ceco_plant_sim'):
    sys.path.insert(0, str(ROOT / pkg))


def _commit() -> str:
    try:
        out = subprocess.run(
            ['git', '-C', str(ROOT), 'describe', '--always', '--dirty', '--abbrev=12'],
            capture_output=True,
            text=True,
            timeout=10,
        )
    except (OSError, subprocess.SubprocessError):
        return 'unknown'
    return out.stdout.strip() or 'unknown'


def main(argv=None) -> int:
    from ceco_plant_sim import refrigerant as r
    from ceco_plant_sim.plant_params import PlantParams

    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--out', default=r.SHIPPED_TABLES, help='file to write or check (default: the shipped one)')
    p.add_argument('--check', action='store_true', help='check the file against a fresh CoolProp build')
    p.add_argument('--show', action='store_true', help='print the provenance of the file')
    args = p.parse_args(argv)
    if args.show:
        prov, _ = r.read_tables_file(args.out)
        print(json.dumps(prov, indent=2, sort_keys=True))
        return 0
    if args.check:
        try:
            prov = r.check_tables_file(args.out)
        except r.StaleTablesError as err:
            print(f'STALE: {err}', file=sys.stderr)
            return 1
        print(
            f'{args.out}: current (CoolProp {prov["coolprop_version"]}, generated {prov["date_utc"]}, '
            f'equal bit for bit to a fresh build)'
        )
        return 0
    pp = PlantParams()
    prov = r.write_tables_file(
        args.out,
        pp.refrigerant,
        pp.superheat_k,
        pp.subcool_k,
        r.DEFAULT_GRID,
        command=r.REGENERATE_COMMAND,
        extra={'ceco_commit': _commit()},
    )
    r.check_tables_file(args.out)
    print(
        f'wrote {args.out}: {prov["fluid"]}, superheat {prov["superheat_k"]} K, subcooling '
        f'{prov["subcool_k"]} K, CoolProp {prov["coolprop_version"]}, grid {prov["grid"]}'
    )
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
