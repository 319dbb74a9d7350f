"""Check a DDS run against the in-process closed-loop simulator.

    python -m ceco_bringup.compare_sim DIR [DIR ...] [--rtol 1e-6]

DIR is a run directory or a job directory of `ceco run` (its runs are its subdirectories:
``ceco_bringup.rundata.discover_runs``). For each run written by `ceco run` (metrics.json + bag/), re-runs
`ceco_controller.closed_loop.simulate` with the same scenario, strategy,
Ts, Np, preview quality and duration, recomputes the metrics from the bag
alone, and prints the relative difference of every numeric metric and
the bag's message counts per step. Exit status 1 if any metric differs by
more than --rtol, a step has not exactly one state / one command, or a run
failed (it is named with its reason: a run whose controller did not control
has nothing to compare); 2 for a DIR that holds no run.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

KEYS = (
    'E_tot_J',
    'E_comp_J',
    'E_blower_J',
    'I_pmv',
    'otc_violation_pct',
    'time_to_comfort_s',
    'pmv_mean',
    'pmv_max',
    'pmv_min',
)


def rel_diff(a: float, b: float) -> float:
    """Relative difference ``|a - b| / max(|a|, |b|)`` of two metric values [-].

    0.0 when ``a == b`` (including both 0) or both are NaN.
    """
    if (isinstance(a, float) and math.isnan(a)) and (isinstance(b, float) and math.isnan(b)):
        return 0.0
    if a == b:
        return 0.0
    return abs(a - b) / max(abs(a), abs(b))


def check(run_dir: Path, rtol: float) -> tuple[bool, str]:
    """Compare one ``ceco run`` directory with a re-run of the in-process simulator.

    Args:
        run_dir: a run directory holding ``metrics.json`` and the rosbag2 bag ``bag/``.
        rtol: the largest relative difference [-] allowed between a simulator metric and the
            same metric recomputed from the bag (``metrics.json`` must equal the bag exactly).

    Returns:
        ``(ok, report)``: ``ok`` is True if every metric agrees and every plant step has exactly
        one state and every control step exactly one command in the bag; ``report`` is the
        per-metric comparison and the message counts, as printed text.
    """
    import numpy as np

    from ceco_bringup import bagio
    from ceco_controller.closed_loop import SimSettings, simulate
    from ceco_core.metrics import run_metrics
    from ceco_v2x_preview.preview import parse_quality

    m = json.loads((run_dir / 'metrics.json').read_text())
    bag = run_dir / 'bag'
    ts = bagio.load_run_timeseries(bag)
    from_bag = run_metrics(ts)
    duration = float(ts['t_s'].size)  # plant_dt_s = 1 s
    sim = simulate(
        m['scenario'],
        m['strategy'],
        SimSettings(
            control_period_s=m['control_period_s'],
            horizon_steps=m['horizon_steps'],
            preview_quality=parse_quality(m['preview_quality']),
            duration_s=duration,
            progress=False,
        ),
    ).metrics
    lines = [f'{run_dir} ({m["strategy"]}, {m["scenario"]}, {int(duration)} s):']
    ok = True
    for key in KEYS:
        d_sim = rel_diff(sim[key], from_bag[key])
        d_json = rel_diff(m[key] if m[key] is not None else math.nan, from_bag[key])
        ok &= d_sim <= rtol and d_json == 0.0
        lines.append(
            f'  {key:<18} sim {sim[key]:>16.10g}  dds {from_bag[key]:>16.10g}  rel diff {d_sim:.1e}'
            f'  (metrics.json vs bag {d_json:.1e})'
        )
    states = bagio.read_messages(bag, (bagio.TOPIC_STATE,))
    n_state = np.bincount([msg.step_index for _, _, msg in states], minlength=ts['t_s'].size)
    cmds = bagio.load_commands(bag)
    n_cmd = np.bincount(cmds['k'], minlength=int(round(duration / m['control_period_s'])))
    one_state = bool(np.all(n_state == 1))
    one_cmd = bool(np.all(n_cmd == 1))
    ok &= one_state and one_cmd
    lines.append(
        f'  bag: {n_state.size} plant steps, states per step min {n_state.min()} max {n_state.max()}; '
        f'{n_cmd.size} control steps, commands per step min {n_cmd.min()} max {n_cmd.max()}'
    )
    return ok, '\n'.join(lines)


def main(argv=None) -> int:
    """Command line (module docstring): compare each run directory, print the reports and a verdict.

    Args:
        argv: the command-line arguments (default ``sys.argv[1:]``).

    Returns:
        The exit status: 0 if every run equals the simulator, 1 otherwise.
    """
    p = argparse.ArgumentParser(prog='python -m ceco_bringup.compare_sim', description=__doc__.split('\n\n')[0])
    p.add_argument('run_dirs', nargs='+', type=Path)
    p.add_argument('--rtol', type=float, default=1e-6)
    args = p.parse_args(argv)
    from ceco_bringup import bagrun, rundata

    try:
        runs = rundata.discover_runs(args.run_dirs)
    except ValueError as err:
        print(f'compare_sim: {err}', file=sys.stderr)
        return 2
    all_ok = True
    for d in runs:
        why = rundata.failed_reason(d)
        if why is not None:
            print(f'{d}: FAILED run, not compared: {why}')
            all_ok = False
            continue
        if not (d / 'metrics.json').is_file() or bagrun.bag_dir_of(d) is None:
            print(f'{d}: not compared: a `ceco run` directory holds metrics.json and its bag in bag/')
            all_ok = False
            continue
        ok, text = check(d, args.rtol)
        print(text)
        all_ok &= ok
    print('OK: every DDS run equals the simulator' if all_ok else 'MISMATCH')
    return 0 if all_ok else 1


if __name__ == '__main__':
    sys.exit(main())
