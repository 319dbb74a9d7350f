"""Two runs side by side, window by window: where one uses less energy than the other, and how each ends.

    python tools/phase_energy.py RUN_A RUN_B [--windows 0,300,600,END] [--names A,B]

RUN_A and RUN_B are run directories with a ``timeseries.csv`` (``ceco sim``, ``ceco run``, ``ceco oracle``'s
``level-N``, ``ceco benchmark --save-runs``' ``runs/...``) of the same scenario on the same plant step. For each
window [t_i, t_i+1) of ``--windows`` [s after key-on; END the runs' end]: each run's energy (compressor + blower +
condenser fan: the benchmark's ``energy_kwh`` of the window's plant steps, ``ceco_core.kpis.compute_kpis``) [kWh],
B − A, the mean coil set-point [degC], blower flow [kg/s] and scored PMV. Then each run's state at its end: cabin
air, interior, shell, glazing and coil wall [degC]. A whole-drive optimum that knows where the drive ends may
spend, in its last minute, cold stored in these (docs/oracle.md, "The drive's end"); the end states show whether
it did.

A study, not a test: it reads what the runs wrote.
"""

from __future__ import annotations

import argparse
import math
import pathlib

import numpy as np

END_STATES = ('t_cab_c', 't_int_c', 't_shell_c', 't_glass_c', 't_evap_c')
"""The end states printed (the cabin's heat stores and the coil wall) [degC]."""
KPI_COLUMNS = ('p_comp_w', 'p_blower_w', 'p_cond_fan_w', 'pmv_lb', 'pmv_ub')
"""The columns the benchmark's KPIs read besides :data:`MEAN_COLUMNS` (``ceco_core.kpis.compute_kpis``)."""
MEAN_COLUMNS = ('t_evap_sp_c', 'mdot_bl_kgps', 'pmv')
"""The means per window."""


def read_timeseries(run_dir: str) -> dict[str, np.ndarray]:
    """A run directory's ``timeseries.csv`` as columns (``ceco_core.rundir.read_csv_columns``)."""
    from ceco_core.rundir import read_csv_columns

    path = pathlib.Path(run_dir) / 'timeseries.csv'
    if not path.is_file():
        raise SystemExit(f'phase_energy: {path} not found (a run directory holds timeseries.csv)')
    cols = read_csv_columns(path)
    missing = [c for c in ('t_s', *KPI_COLUMNS, *MEAN_COLUMNS, *END_STATES) if c not in cols]
    if missing:
        raise SystemExit(f'phase_energy: {path} lacks {", ".join(missing)}')
    return cols


def windows_of(text: str, t_end_s: float) -> list[tuple[float, float]]:
    """``[(t0, t1), ...]`` of a comma-separated list of increasing times [s]; END is ``t_end_s``."""
    edges = [t_end_s if x.strip().upper() == 'END' else float(x) for x in text.split(',')]
    if len(edges) < 2 or any(not math.isfinite(x) for x in edges) or any(b <= a for a, b in zip(edges, edges[1:])):
        raise SystemExit(f'phase_energy: --windows must be two or more increasing times, got {text!r}')
    return list(zip(edges, edges[1:]))


def window_table(ts: dict[str, np.ndarray], windows: list[tuple[float, float]]) -> list[dict]:
    """Per window: the benchmark's energy of its plant steps [kWh] (``compute_kpis``' ``energy_kwh``) and the means
    of :data:`MEAN_COLUMNS`."""
    from ceco_core.kpis import compute_kpis

    t = ts['t_s']
    out = []
    for a, b in windows:
        m = (t >= a) & (t < b)
        if np.count_nonzero(m) < 2:
            raise SystemExit(f'phase_energy: the window {a:g}-{b:g} s holds fewer than two plant steps')
        kpis, _ = compute_kpis({c: v[m] for c, v in ts.items() if v.dtype.kind == 'f'})
        row = {'from_s': a, 'to_s': b, 'energy_kwh': kpis['energy_kwh']}
        row.update({c: float(np.mean(ts[c][m])) for c in MEAN_COLUMNS})
        out.append(row)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog='phase_energy', description=__doc__.split('\n\n')[2])
    ap.add_argument('run_a', help='the first run directory')
    ap.add_argument('run_b', help='the second run directory')
    ap.add_argument('--windows', default='0,300,600,END', help='window edges [s], END: the end (default 0,300,600,END)')
    ap.add_argument('--names', default='A,B', help='the two runs\' names in the table (default A,B)')
    a = ap.parse_args(argv)
    names = a.names.split(',')
    if len(names) != 2:
        raise SystemExit('phase_energy: --names takes two names')
    ta, tb = read_timeseries(a.run_a), read_timeseries(a.run_b)
    if ta['t_s'].shape != tb['t_s'].shape or not np.array_equal(ta['t_s'], tb['t_s']):
        raise SystemExit('phase_energy: the two runs are not on the same time grid')
    t_end = float(ta['t_s'][-1] + (ta['t_s'][-1] - ta['t_s'][-2]))
    wins = windows_of(a.windows, t_end)
    ra, rb = window_table(ta, wins), window_table(tb, wins)
    na, nb = names
    print(
        f'| window [s] | {na} E [kWh] | {nb} E [kWh] | {nb} − {na} [kWh] | set-point [°C] {na} / {nb} '
        f'| blower [kg/s] {na} / {nb} | PMV {na} / {nb} |'
    )
    print('|---|---|---|---|---|---|---|')
    for x, y in zip(ra, rb):
        print(
            f'| {x["from_s"]:g}-{x["to_s"]:g} | {x["energy_kwh"]:.4f} | {y["energy_kwh"]:.4f} '
            f'| {y["energy_kwh"] - x["energy_kwh"]:+.4f} | {x["t_evap_sp_c"]:.2f} / {y["t_evap_sp_c"]:.2f} '
            f'| {x["mdot_bl_kgps"]:.4f} / {y["mdot_bl_kgps"]:.4f} | {x["pmv"]:+.3f} / {y["pmv"]:+.3f} |'
        )
    ea, eb = (sum(r['energy_kwh'] for r in rr) for rr in (ra, rb))
    print(f'| all | {ea:.4f} | {eb:.4f} | {eb - ea:+.4f} | | | |')
    print()
    print('| end state [°C] | ' + ' | '.join(END_STATES) + ' |')
    print('|---|' + '---|' * len(END_STATES))
    for name, ts in ((na, ta), (nb, tb)):
        print(f'| {name} | ' + ' | '.join(f'{ts[c][-1]:.2f}' for c in END_STATES) + ' |')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
