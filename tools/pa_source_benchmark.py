"""The controller's PMV vapour pressure at matched comfort: the paper's 1700 Pa against the measured cabin RH.

    source tools/env.sh
    python tools/pa_source_benchmark.py [CASE ...] [--workers 2] [--out runs/pa_source.json]
    python tools/pa_source_benchmark.py --table runs/pa_source.json     # the table again, no runs

Every CECO strategy runs twice per case and seed, with ``pmv_pa_source: paper`` (the default,
the paper's constant 1700 Pa in the NLP's PMV) and ``pmv_pa_source: measured`` (the vapour
pressure of the measured cabin RH at the measured T_cab, held over the horizon;
docs/controller.md 4.1), next to the benchmark's baseline families on the same cells
(``ceco_bringup.benchmark.runner``: same cases, seeds, forecast uncertainty, KPIs, fronts and
matching as ``ceco benchmark``; no sensitivity runs). Prints one Markdown table: per case and
strategy the energy saving at matched comfort against the stronger of the two baseline fronts
(docs/results.md's headline: ``tools/benchmark_summary.stronger_front``; the seeds' mean, and
whether the strategy is dominated) for both settings, and the seeds' mean discomfort and energy.
Nothing is asserted: numbers only (docs/results.md, "The controller's vapour pressure").
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

from benchmark_summary import stronger_front  # tools/, next to this script

from ceco_bringup.benchmark import runner
from ceco_bringup.benchmark.cases import DEFAULT_CASES, load_case
from ceco_bringup.sweep import backends
from ceco_bringup.sweep.cells import code_fingerprint

MEASURED = '[pa=measured]'
KPIS = ('discomfort_pmvh', 'energy_kwh')


def _specs() -> list[runner.ControllerSpec]:
    baselines = [s for s in runner.controllers(runner.load_baselines(), strategies=()) if s.kind != 'strategy']
    variants = []
    for s in runner.STRATEGY_NAMES:
        variants.append(runner.ControllerSpec(s, 'strategy', s))
        variants.append(runner.ControllerSpec(s + MEASURED, 'strategy', s, (('pmv_pa_source', 'measured'),)))
    return baselines + variants


def _fmt(m: dict) -> str:
    x, dominated = stronger_front(m)
    return ('n/a' if x is None else f'{x:+.1f}') + (' (dom.)' if dominated else '')


def print_table(docs: list[dict]) -> None:
    """The Markdown table of the assembled cases."""
    print(
        '| case | strategy | ΔE, paper 1700 Pa [%] | ΔE, measured RH [%] '
        '| discomfort paper / measured [PMV h] | energy paper / measured [kWh] |'
    )
    print('|---|---|---|---|---|---|')
    for doc in docs:
        kp: dict = {}
        for r in doc['runs']:
            if r['kind'] == 'strategy' and r['status'] == 'ok':
                kp.setdefault(r['controller'], []).append(r['kpis'])
        mean = {(n, key): statistics.fmean(k[key] for k in ks) for n, ks in kp.items() for key in KPIS}
        for s in runner.STRATEGY_NAMES:
            paper, meas = doc['matched'][s], doc['matched'][s + MEASURED]
            d, e = (f'{mean[s, k]:.4f} / {mean[s + MEASURED, k]:.4f}' for k in KPIS)
            print(f"| {doc['case']} | {s} | {_fmt(paper)} | {_fmt(meas)} | {d} | {e} |")


def main(argv=None) -> int:
    """Run the cases, print the table, optionally write the assembled cases as JSON."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('cases', nargs='*', default=list(DEFAULT_CASES))
    ap.add_argument('--workers', type=int, default=2)
    ap.add_argument('--out', default='')
    ap.add_argument('--table', default='', help='print the table of a file written with --out, run nothing')
    args = ap.parse_args(argv)
    if args.table:
        with open(args.table) as f:
            print_table(json.load(f))
        return 0
    code, specs = code_fingerprint(), _specs()
    t0, docs = time.perf_counter(), []
    for name in args.cases:
        case = load_case(name)
        cells = runner.case_cells(case, specs, code)
        rows: list = []
        items = [dict(id=c.id, axes=c.axes, spec=c.spec) for c in cells]
        backends.run_local(items, args.workers, rows.append, runner.run_benchmark_cell)
        failed = [r for r in rows if r['status'] != 'ok']
        docs.append(runner.assemble_case(case, rows))
        print(f'{name}: {len(rows)} runs, {len(failed)} failed, {time.perf_counter() - t0:.0f} s', flush=True)
    print()
    print_table(docs)
    print(f'\n{sum(len(d["runs"]) for d in docs)} runs in {time.perf_counter() - t0:.0f} s, code {code}')
    if args.out:
        with open(args.out, 'w') as f:
            json.dump(docs, f, indent=1)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
