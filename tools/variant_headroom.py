"""A strategy variant scored against a stored benchmark: its saving at matched comfort and its headroom_captured.

    python tools/variant_headroom.py RESULTS.json CASE [CASE ...] [--strategy ceco-pmv]
                                     [--set NAME=VALUE ...] [--model-params FILE]

Reruns ``--strategy`` on every seed of each case exactly as ``ceco benchmark`` runs it (the case's benchmark
cells, ``runner.run_benchmark_cell``) with the StrategySettings overrides of ``--set`` (e.g.
``--set backoff_min_pmv=0.0``; ``horizon_steps`` and ``control_period_s`` set the run's, as the case's scenario
does; none: the strategy as shipped) and, with ``--model-params``, the controller's
identified model read from FILE instead of the package's (the cells' ``model_params_path``). It scores the runs
with the benchmark's own matching (``runner.matched_of``) against the families' runs and the oracle front stored
in RESULTS.json (a ``ceco benchmark --oracle`` output of the same simulator code for the baselines; a note on
stderr when its code fingerprint is not this checkout's): the saving
against the strongest family [%] (mean over the seeds [min..max]), the seeds it is dominated on, the oracle's saving at
the same discomfort and headroom_captured (docs/benchmark.md), and the band phase's PMV mean and seconds above
+0.5 of the variant, the strongest family and the oracle there (``by_phase``; RESULTS.json must hold the band-phase
KPIs, a run of ceco since 2d65211). The oracle does not depend on the controller
(it knows the drive), so a stored front bounds any variant; the baselines do not either, so only the
variant is rerun (seconds per run instead of the hours of the oracle).

What it prints is a study, not a benchmark result: results.json is not changed. Last line per case: one
JSON object.
"""

from __future__ import annotations

import argparse
import json
import sys

from benchmark_summary import fmt  # tools/: "n/a" for a missing number


def _value(text: str):
    """A --set value: true/false as a bool, a number when it parses as one, else the text."""
    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def load_results(path: str) -> dict:
    """RESULTS.json as a dict; a note on stderr when it was written by other code than this checkout's.

    The study reruns the strategy with this checkout's code and scores it against the families' runs and the oracle
    stored in RESULTS; with other simulator code those are another plant's (the benchmark's own cells would rerun).
    """
    from ceco_bringup.sweep.cells import code_fingerprint

    with open(path, encoding='utf-8') as f:
        results = json.load(f)
    stored, here = results.get('code_fingerprint'), code_fingerprint()
    if stored != here:
        print(
            f'note: {path} was written by code {stored}, this checkout is {here}: its families and oracle are '
            'scored as they are (rerun the benchmark for the same code)',
            file=sys.stderr,
        )
    return results


def strategy_cells(case, strategy: str) -> list:
    """The benchmark's cells of ``strategy`` on ``case`` (one per seed), as ``ceco benchmark`` builds them."""
    from ceco_bringup.benchmark import cli, runner

    specs = runner.controllers(runner.load_baselines(), (26.0,), (strategy,), (0.0,))
    return [c for c in runner.case_cells(case, specs, cli.code_fingerprint()) if c.axes['controller'] == strategy]


RUN_KEYS = ('horizon_steps', 'control_period_s')
"""``--set`` names that are the run's (a benchmark cell's keys, as a case's scenario sets them), not settings."""


def variant_spec(spec: dict, overrides: dict, model_params: str | None = None) -> dict:
    """A copy of a benchmark cell's ``spec`` with the variant's overrides (:data:`RUN_KEYS` to the run, the rest to
    the strategy's settings) and its model file."""
    out = json.loads(json.dumps(spec))
    out.update({k: v for k, v in overrides.items() if k in RUN_KEYS})
    out['strategy_overrides'].update({k: v for k, v in overrides.items() if k not in RUN_KEYS})
    if model_params is not None:
        out['model_params_path'] = model_params
    return out


def study(results: dict, case_name: str, strategy: str, overrides: dict, model_params: str | None = None) -> dict:
    """The variant's matched entry on one case of ``results`` (``runner.matched_of``'s, for ``strategy``)."""
    from ceco_bringup.benchmark import runner
    from ceco_bringup.benchmark.cases import load_case

    case = load_case(case_name)  # a bundled name or a case YAML path (then its name)
    entry = next((c for c in results['cases'] if c['case'] == case.name), None)
    if entry is None:
        raise SystemExit(
            f'variant_headroom: {case_name!r} is not in the results (cases: '
            f'{", ".join(c["case"] for c in results["cases"])})'
        )
    rows = []
    for c in strategy_cells(case, strategy):
        row = runner.run_benchmark_cell(
            {'id': c.id, 'axes': c.axes, 'spec': variant_spec(c.spec, overrides, model_params)}
        )
        if row['status'] != 'ok':
            raise SystemExit(f'variant_headroom: {case_name} seed {c.axes["seed"]}: {row["error"]}')
        rows.append(runner._run_entry(row))
    baselines = [r for r in entry['runs'] if r['kind'].startswith('baseline')]  # every family, door ones too
    bounds = runner.oracle_bounds(entry['oracle'])
    kp = runner.oracle_point_kpis(entry['oracle'])
    matched = runner.matched_of(baselines + rows, runner.FRONT_AXIS, runner.ENERGY_AXIS, bounds, kp)
    m = matched[strategy]
    s, h = m['strongest'], m['headroom'] or {}
    seeds = s.get('seeds') or {}
    return {
        'case': case_name,
        'strategy': strategy,
        'overrides': overrides,
        'model_params': model_params,
        'discomfort_pmvh': [r['kpis']['discomfort_pmvh'] for r in rows],
        'energy_kwh': [r['kpis']['energy_kwh'] for r in rows],
        'saving_pct': s['energy_saving_pct'],
        'saving_pct_seeds': seeds.get('energy_saving_pct'),
        'dominated_seeds': sum(bool(x) for x in seeds.get('dominated') or []),
        'n_seeds': len(rows),
        'strongest_family': s.get('family'),
        'bound_saving_pct': h.get('bound_saving_pct'),
        'headroom_captured': h.get('headroom_captured'),
        'headroom_captured_seeds': (h.get('seeds') or {}).get('headroom_captured'),
        'note': h.get('note', ''),  # why there is no headroom (the plain front's note is not about it)
        'by_phase': m.get('by_phase'),  # the band phase: the variant, the strongest family and the oracle there
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('results', help='a ceco benchmark results.json with the cases (and their oracle fronts)')
    p.add_argument('cases', nargs='+', help='case names in the results')
    p.add_argument('--strategy', default='ceco-pmv', help='the strategy to rerun (default ceco-pmv)')
    p.add_argument('--set', action='append', default=[], metavar='NAME=VALUE', help='a StrategySettings override')
    p.add_argument(
        '--model-params',
        default=None,
        metavar='FILE',
        help="the controller's identified model file (default: the package's)",
    )
    args = p.parse_args(argv)
    model_params = None
    if args.model_params is not None:
        import os

        from ceco_controller.model import load_params

        model_params = os.path.abspath(args.model_params)
        try:
            load_params(model_params)
        except (OSError, ValueError, KeyError, TypeError) as exc:
            p.error(f'--model-params {args.model_params}: {exc}')
    overrides = {}
    for item in args.set:
        name, sep, value = item.partition('=')
        if not sep or not name:
            p.error(f'--set {item!r}: expected NAME=VALUE')
        overrides[name] = _value(value)
    results = load_results(args.results)
    for name in args.cases:
        r = study(results, name, args.strategy, overrides, model_params)
        hs = [x for x in (r['headroom_captured_seeds'] or []) if x is not None]
        ss = [x for x in (r['saving_pct_seeds'] or []) if x is not None]
        print(
            f'{name}: {args.strategy}'
            + (f' {overrides}' if overrides else '')
            + (f' model {model_params}' if model_params else '')
            + ('' if overrides or model_params else ' (as shipped)')
            + f': saving vs strongest ({r["strongest_family"]}) '
            f'{fmt(r["saving_pct"], "+.2f")} %'
            + (f' [{min(ss):+.2f}..{max(ss):+.2f}]' if len(ss) > 1 else '')
            + f', dominated on {r["dominated_seeds"]} of {r["n_seeds"]} seeds; '
            f'oracle {fmt(r["bound_saving_pct"], "+.2f")} %,'
            f' headroom_captured {fmt(r["headroom_captured"], ".2f")}'
            + (f' [{min(hs):.2f}..{max(hs):.2f}]' if len(hs) > 1 else '')
            + (f' ({r["note"]})' if r['note'] else '')
        )
        bp = r['by_phase']
        if bp:
            c, st, b = bp['controller'], bp['strongest'], bp['bound']
            print(
                '  band phase: PMV mean '
                + ' / '.join(fmt(x['pmv_mean_band'], '+.3f') for x in (c, st, b))
                + ', above +0.5 '
                + ' / '.join(fmt(x['pmv_above_band_s'], '.0f') for x in (c, st, b))
                + ' s (variant / strongest family / oracle, at the variant\'s discomfort)'
            )
        print(json.dumps(r))
    return 0


if __name__ == '__main__':
    sys.exit(main())
