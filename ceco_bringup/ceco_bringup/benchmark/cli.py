"""``ceco benchmark [CASE...] --out DIR``: run (or resume) the benchmark, write results and the report.

    ceco benchmark --out runs/bench                       # every bundled case, the sensitivity, the report
    ceco benchmark sc03-paper udds-hot --out runs/b2      # some cases (names or case-file paths)
    ceco benchmark --quick --out runs/quick               # 3 cases, first seeds, 3 set-points per family: CI smoke test
    ceco benchmark --oracle --out runs/b3                 # with the whole-drive optimum (slow: docs/oracle.md)
    ceco benchmark --controller-cmd "python my_node.py" --controller-name mine --out runs/mine
    ceco benchmark --validate runs/bench/results.json

Writes ``DIR/results.json`` (``ceco-benchmark/2``, validated before it is written),
``DIR/kpis.csv``, ``DIR/report.md``, ``DIR/report.html``, ``DIR/figures/``; the run log
``DIR/cells.jsonl`` makes a rerun resume (docs/benchmark.md).
"""

from __future__ import annotations

import argparse
import csv
import datetime
import json
import os
import shlex
import shutil
import socket
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from ceco_bringup import cli_args
from ceco_bringup.sweep import backends
from ceco_bringup.sweep.cells import code_fingerprint

from . import runner
from .cases import DEFAULT_CASES, QUICK_CASES, CaseError, list_cases, load_case
from .schema import BENCHMARK_VERSION, SCHEMA, ResultsError, check_results, read_results, validate_results

__all__ = ['run_benchmark', 'ceco_version', 'build_parser', 'main']


def ceco_version() -> str:
    """The package version (``ceco_bringup/package.xml``) plus ``+g<commit>`` (and ``.dirty``) in a git checkout."""
    import re
    import subprocess

    here = Path(__file__).resolve()
    version = '0'
    for xml in (here.parents[2] / 'package.xml', here.parents[1] / 'package.xml'):
        if xml.is_file():
            m = re.search(r'<version>([^<]+)</version>', xml.read_text(encoding='utf-8'))
            version = m.group(1) if m else version
            break
    try:
        sha = subprocess.run(
            ['git', '-C', str(here.parent), 'rev-parse', '--short', 'HEAD'],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ['git', '-C', str(here.parent), 'status', '--porcelain', '--untracked-files=no'],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout.strip()
        return f'{version}+g{sha}' + ('.dirty' if dirty else '')
    except (OSError, subprocess.SubprocessError):
        return version


def _kpi_table(path: Path, doc: dict) -> None:
    keys: list = []
    for case in doc['cases']:
        for r in case['runs']:
            keys += [k for k in r['kpis'] if k not in keys]
    with open(path, 'w', newline='', encoding='utf-8') as fh:
        w = csv.writer(fh)
        w.writerow(['case', 'controller', 'kind', 'seed', 'setpoint_c', 'source', 'status', *keys])
        for case in doc['cases']:
            for r in case['runs']:
                w.writerow(
                    [
                        case['case'],
                        r['controller'],
                        r['kind'],
                        '' if r['seed'] is None else r['seed'],
                        '' if r['setpoint_c'] is None else repr(r['setpoint_c']),
                        r['source'],
                        r['status'],
                        *['' if r['kpis'].get(k) is None else repr(r['kpis'][k]) for k in keys],
                    ]
                )


def run_benchmark(
    case_names: Sequence[str],
    out_dir,
    *,
    quick: bool = False,
    workers: int | None = None,
    backend: str = 'local',
    address: str | None = None,
    sensitivity: bool = True,
    controller_cmd: str | None = None,
    controller_name: str = 'external',
    save_runs: bool = False,
    progress: bool = True,
    command: str = '',
    log=print,
    setpoints_c: Sequence[float] | None = None,
    sensitivity_path=None,
    setpoints_pmv: Sequence[float] | None = None,
    oracle: bool = False,
    oracle_entry: str = runner.ORACLE_ENTRY,
    oracle_cases: Sequence[str] | None = None,
    strategies: Sequence[str] | None = None,
) -> dict:
    """Run (or resume) the benchmark into ``out_dir``; return the results document (also written).

    ``setpoints_c``, ``setpoints_pmv`` and ``sensitivity_path`` replace the families' set-points and the
    tornado's table (tests and studies; the published benchmark uses the defaults). ``oracle`` (default
    off, ``--oracle``): ask the whole-drive optimum (``oracle_entry``, :data:`runner.ORACLE_ENTRY`) for its
    front on every case (or on ``oracle_cases``; ``--quick``: :data:`QUICK_ORACLE_CASES`) once the case's
    runs are done; a missing oracle module is skipped with one line. ``strategies`` replaces
    :data:`runner.STRATEGY_NAMES` (``()``: the baseline families and compensated laws only, e.g. to study the
    families on every case).
    """
    t0 = time.perf_counter()
    ray_workers = workers
    workers = int(workers or os.cpu_count() or 1)
    # local workers start now and import the simulator while this process plans the cells; closed once the runs
    # are done (an exception drops the pool: its processes stop when it is collected)
    pool = backends.LocalPool(workers if backend == 'local' else 1)
    cases = [load_case(n) for n in (case_names or (QUICK_CASES if quick else DEFAULT_CASES))]
    stray = sorted(set(oracle_cases or ()) - {c.name for c in cases})
    if stray:
        raise ValueError(f'--oracle-cases: {", ".join(stray)} not among the selected cases {[c.name for c in cases]}')
    baselines = runner.load_baselines()
    if setpoints_c is None:
        setpoints_c = runner.QUICK_SETPOINTS_C if quick else runner.SETPOINTS_C
    if setpoints_pmv is None:
        setpoints_pmv = runner.QUICK_SETPOINTS_PMV if quick else runner.SETPOINTS_PMV
    strategies = runner.STRATEGY_NAMES if strategies is None else tuple(strategies)
    specs = runner.controllers(baselines, setpoints_c, strategies, setpoints_pmv)
    door_tuning = runner.load_door_tuning()
    door_specs = [
        c for fam in baselines.door_family_specs() for c in runner.family_members(fam, setpoints_c, setpoints_pmv)
    ]
    code = code_fingerprint()
    seeds = {c.name: (c.seeds[:1] if quick else c.seeds) for c in cases}
    cells, by_case = [], {}
    for c in cases:
        cc = runner.case_cells(c, runner.case_controllers(c, specs, door_specs, door_tuning), code, seeds=seeds[c.name])
        by_case[c.name] = cc
        cells += cc
    sens_plan = []
    sens_specs = [c for c in specs if c.kind in runner.SENSITIVITY_KINDS]
    sens_case_name, params = runner.load_sensitivity(sensitivity_path)
    if sensitivity and not quick and any(c.name == sens_case_name for c in cases):
        case = next(c for c in cases if c.name == sens_case_name)
        for p in params:
            ends = []
            for end in ('low', 'high'):
                kw = (
                    {'plant_overrides': getattr(p, end)}
                    if p.target == 'plant'
                    else {'comfort_overrides': getattr(p, end)}
                )
                ends.append(
                    runner.case_cells(
                        case, sens_specs, code, seeds=seeds[case.name], variant=f'sens:{p.parameter}:{end}', **kw
                    )
                )
            sens_plan.append((p, *ends))
            cells += ends[0] + ends[1]
    external = []
    if controller_cmd:
        from . import external as ext  # DDS: needs the built workspace

        # its name, exact command and directory make its cells' ids: another controller never resumes this one's
        ext_spec = runner.ControllerSpec(
            f'external:{controller_name}',
            'external',
            'external',
            command=tuple(shlex.split(controller_cmd)),
            cwd=os.getcwd(),
        )
        for c in cases:
            ec = runner.case_cells(c, [ext_spec], code, seeds=seeds[c.name])
            by_case[c.name] = by_case[c.name] + ec
            external += ec
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    log_path = out / 'cells.jsonl'
    done = backends.read_done(log_path)
    todo = [c for c in cells if c.id not in done]
    todo_ext = [c for c in external if c.id not in done]
    log(
        f'ceco benchmark: {len(cases)} case(s), {len(cells) + len(external)} runs, '
        f'{len(cells) + len(external) - len(todo) - len(todo_ext)} already done, {len(todo) + len(todo_ext)} to run '
        f'({backend}, {workers} worker(s))',
        file=sys.stderr,
    )
    bar = None
    if progress and (todo or todo_ext):
        from tqdm import tqdm

        bar = tqdm(total=len(todo) + len(todo_ext), desc='benchmark', unit='run', file=sys.stderr)
    ran: list = []

    def on_done(row):
        backends.append_row(log_path, row)
        ran.append(row)
        if row['status'] != 'ok':
            log(
                f"ceco benchmark: {row['case']}/{row['controller']}/seed {row['seed']} ({row['variant']}) failed: "
                f"{row['error']}",
                file=sys.stderr,
            )
        if bar is not None:
            bar.update(1)

    runs_dir = str(out / 'runs') if save_runs else None

    def dispatch(cells_, fn):
        # a seeded run that does not depend on its seed (the persistence twin) runs once; the other seeds reuse it
        items, reuse = runner.share_seed_invariant([dict(id=c.id, axes=c.axes, spec=c.spec) for c in cells_])
        if not items:
            return

        def done(row):
            on_done(row)
            for item in reuse.get(row['cell_id'], ()):
                if runs_dir and (Path(runs_dir) / row['cell_id']).is_dir():
                    shutil.copytree(Path(runs_dir) / row['cell_id'], Path(runs_dir) / item['id'], dirs_exist_ok=True)
                on_done(runner.reused_row(row, item))

        n = min(workers, len(items))
        if backend == 'local':
            pool.run(items, done, fn, runs_dir)
        elif backend == 'ray':
            # on a cluster (address) without --workers: one worker per CPU of the cluster
            backends.run_ray(items, None if address and not ray_workers else n, address, done, fn, runs_dir)
        else:
            raise ValueError(f'backend: must be local or ray, got {backend!r}')

    try:
        dispatch(todo, runner.run_benchmark_cell)
        for c in todo_ext:
            on_done(
                ext.run_external_cell(
                    dict(id=c.id, axes=c.axes, spec=c.spec), list(ext_spec.command), out / 'external' / c.id
                )
            )
    finally:
        if bar is not None:
            bar.close()
            bar = None
    t_runs = time.perf_counter()
    done = backends.read_done(log_path)
    failed = {r['cell_id']: r for r in ran if r['status'] != 'ok'}

    def rows(cs):
        return [done.get(c.id) or failed.get(c.id) or _missing(c) for c in cs]

    oracles = _run_oracles(
        cases,
        by_case,
        rows,
        seeds,
        code,
        log_path,
        dispatch,
        log,
        oracle,
        oracle_entry,
        oracle_cases if oracle_cases is not None else (QUICK_ORACLE_CASES if quick else None),
    )
    t_oracle = time.perf_counter()
    pool.close()  # the workers' teardown overlaps the report
    done = backends.read_done(log_path)
    case_docs = []
    for c in cases:
        sens = [(p, rows(lo), rows(hi)) for p, lo, hi in sens_plan] if c.name == sens_case_name else []
        # the seeds run (--quick: the first only), which the validator holds the seeded runs to
        case_docs.append(
            {**runner.assemble_case(c, rows(by_case[c.name]), sens, oracles[c.name]), 'seeds': list(seeds[c.name])}
        )
    all_cells = cells + external
    wall = time.perf_counter() - t0
    sim = [r['sim_time_s'] for r in ran if r['status'] == 'ok' and r.get('kind') != 'oracle']
    oracle_wall = [r['wall_time_s'] for r in ran if r.get('kind') == 'oracle']
    timing = {
        'wall_s': wall,
        'runs': len(all_cells),
        'ran_now': len(ran),
        'failed_now': len(failed),
        'workers': workers,
        'backend': backend,
        'host': socket.gethostname(),
        'sim_time_sum_s': float(sum(sim)),
        'sim_time_mean_s': float(sum(sim) / len(sim)) if sim else None,
        'oracle_cells_now': len(oracle_wall),
        'oracle_wall_sum_s': float(sum(oracle_wall)),
        'runs_phase_s': t_runs - t0,
        'oracle_phase_s': t_oracle - t_runs,
    }
    doc = {
        'schema': SCHEMA,
        'ceco_version': ceco_version(),
        'benchmark_version': BENCHMARK_VERSION,
        'created_utc': datetime.datetime.now(datetime.UTC).strftime('%Y-%m-%dT%H:%M:%SZ'),
        'code_fingerprint': code,
        'command': command,
        'quick': bool(quick),
        'settings': {
            'band': [-0.5, 0.5],
            'front_axis': runner.FRONT_AXIS,
            'energy_axis': runner.ENERGY_AXIS,
            'secondary_axes': list(runner.SECONDARY_AXES),
            'setpoints_c': [float(x) for x in setpoints_c],
            'setpoints_pmv': [float(x) for x in setpoints_pmv],
            'families': {
                f.family: {'kind': f.kind, **dict(f.overrides)}
                for f in baselines.family_specs() + baselines.door_family_specs()
            },
            'strongest': 'pointwise lower envelope of every family front (docs/benchmark.md, "Strongest family")',
            'oracle': {'requested': bool(oracle), 'entry_point': oracle_entry},
            'allowance_k_per_pmv': baselines.allowance_k_per_pmv,
            'compensation': dict(baselines.compensation),
            'baselines_tuned_on': baselines.tuned_on,
            'baselines_sha': baselines.sha,
            'strategies': list(strategies),
        },
        'timing': timing,
        'cases': case_docs,
    }
    validate_results(doc)
    (out / 'results.json').write_text(json.dumps(doc, indent=1, allow_nan=False) + '\n', encoding='utf-8')
    with open(out / 'timing.jsonl', 'a', encoding='utf-8') as fh:
        fh.write(json.dumps(timing) + '\n')
    _kpi_table(out / 'kpis.csv', doc)
    from .report import write_report

    write_report(doc, out)
    return doc


QUICK_ORACLE_CASES: tuple[str, ...] = ()
"""The cases ``--quick`` asks the oracle on: none (sc03-paper's 4 whole-drive levels cost about 17 minutes on the
shared 2-core machine, docs/oracle.md "Cost"; CI keeps its 20-minute budget). ``ceco oracle CASE`` runs one."""


def _run_oracles(cases, by_case, rows, seeds, code, log_path, dispatch, log, oracle, entry, only) -> dict:
    """The ``oracle`` entry of every case: levels from the case's runs, cells through the same backend."""
    levels = {c.name: runner.oracle_levels([runner._run_entry(r) for r in rows(by_case[c.name])]) for c in cases}
    out = {}
    wanted = [c for c in cases if only is None or c.name in only]
    if not oracle:
        for c in cases:
            out[c.name] = runner.oracle_entry(
                'skipped', 'not requested (ceco benchmark --oracle; docs/oracle.md "Cost")', levels[c.name], []
            )
        return out
    why = runner.oracle_unavailable(entry)
    if why:
        log(
            f'ceco benchmark: oracle skipped: {why} (the whole-drive optimum; without --oracle it is not asked)',
            file=sys.stderr,
        )
    plan = {}
    for c in cases:
        if why:
            out[c.name] = runner.oracle_entry('unavailable', why, levels[c.name], [])
        elif c not in wanted or not levels[c.name]:
            note = (
                'no baseline front'
                if c in wanted
                else 'not asked on this case (--quick asks it on none, --oracle-cases on the cases it names)'
            )
            out[c.name] = runner.oracle_entry('skipped', note, levels[c.name], [])
        else:
            # the oracle knows the truth, which does not depend on the preview-error seed: one solve per case
            plan[c.name] = runner.oracle_cells(c, list(seeds[c.name])[:1], levels[c.name], code, entry)
    if plan:
        done = backends.read_done(log_path)
        todo = runner.oracle_cost_order(
            [x for cs in plan.values() for x in cs if x.id not in done], {c.name: c for c in cases}
        )
        log(f'ceco benchmark: oracle on {len(plan)} case(s), {len(todo)} (case, seed) to solve', file=sys.stderr)
        dispatch(todo, runner.run_oracle_cell)
        done = backends.read_done(log_path)
        for name, cs in plan.items():
            got = [
                done.get(x.id) or {**x.axes, 'status': 'error', 'error': 'the oracle failed (see the log)'} for x in cs
            ]
            every = [{**got[0], 'seed': int(sd)} for sd in seeds[name]]
            note = '' if len(every) == 1 else 'one solve per case: the truth does not depend on the seed'
            out[name] = runner.oracle_entry('ok', note, levels[name], every)
    return out


def _missing(cell) -> dict:
    return {
        'cell_id': cell.id,
        **cell.axes,
        'status': 'error',
        'error': 'not run (interrupted?)',
        'kpis': None,
        'kpi_notes': {},
        'source': 'simulator',
    }


def build_parser() -> cli_args.Parser:
    """The parser of ``ceco benchmark`` (``ceco benchmark --help``)."""
    p = cli_args.Parser('ceco benchmark', __doc__.split('\n\n')[0])
    p.add_argument('cases', nargs='*', help=f'case names or case-file paths (default: all bundled: {list_cases()})')
    cli_args.add_out(p, 'output directory (reuse it to resume)', required=False)
    p.add_argument(
        '--quick',
        action='store_true',
        help=f'CI smoke test: cases {", ".join(QUICK_CASES)}, the first seed of each case file, 3 set-points per '
        'family, no sensitivity, no oracle (ceco oracle CASE runs one)',
    )
    cli_args.add_workers(p)
    cli_args.add_backend(p)
    p.add_argument('--no-sensitivity', action='store_true', help='skip the tornado runs')
    p.add_argument(
        '--oracle',
        action=argparse.BooleanOptionalAction,
        default=False,
        help='also solve the whole-drive optimum per case (the bound of headroom_captured); off by default: on '
        'whole drives a level costs minutes and not every level converges yet (docs/oracle.md "Cost")',
    )
    p.add_argument(
        '--oracle-cases',
        type=_case_names,
        default=None,
        metavar='A,B,...',
        help='with --oracle: solve it on these of the selected cases only (comma-separated; default: all of them)',
    )
    p.add_argument(
        '--strategy',
        type=_strategy_names,
        default=None,
        metavar='all|none|A,B,...',
        help='the NMPC strategies to score: all (default: '
        + ', '.join(runner.STRATEGY_NAMES)
        + '), none (the baseline families only), or a comma-separated list of those and the variants '
        + ', '.join(runner.STRATEGY_VARIANTS)
        + ' (ceco-pmv brings its persistence twin, and its door variant on the door cases)',
    )
    p.add_argument(
        '--controller-cmd',
        default=None,
        metavar='CMD',
        help='run your own controller node (any language) in place of mpc_node over DDS and score it',
    )
    p.add_argument('--controller-name', default=None, help='name of that controller in the results (default: external)')
    p.add_argument('--save-runs', action='store_true', help='also write a run directory per run to DIR/runs/')
    p.add_argument('--validate', metavar='FILE', default=None, help='only check FILE against ceco-benchmark/2')
    cli_args.add_no_progress(p)
    return p


def _strategy_names(text: str) -> tuple[str, ...] | None:
    """``--strategy``: 'all' (None: the default set), 'none' (no strategy) or comma-separated known names."""
    t = text.strip()
    if t == 'all':
        return None
    if t == 'none':
        return ()
    names = tuple(x.strip() for x in t.split(',') if x.strip())
    known = (*runner.STRATEGY_NAMES, *runner.STRATEGY_VARIANTS)
    unknown = [n for n in names if n not in known]
    if not names or unknown:
        raise argparse.ArgumentTypeError(
            f'{", ".join(unknown) or repr(text)}: not a strategy (all, none, or some of {", ".join(known)})'
        )
    return tuple(dict.fromkeys(names))


def _case_names(text: str) -> list[str]:
    """Comma-separated case names (argparse type of ``--oracle-cases``), at least one."""
    names = [x.strip() for x in text.split(',') if x.strip()]
    if not names:
        raise argparse.ArgumentTypeError(f'must be comma-separated case names, got {text!r}')
    return names


def controller_cmd_problem(text: str) -> str:
    """What is wrong with ``--controller-cmd TEXT`` before any run, or ''.

    Checked before the baseline runs: a missing program was found only after them, minutes later.
    """
    if not text.strip():
        return 'must not be empty (the command that starts your controller node)'
    try:
        program = shlex.split(text)[0]
    except ValueError as exc:  # an unclosed quote
        return f'{exc} in {text!r}'
    if shutil.which(program) is None:
        where = 'not an executable file' if os.path.exists(program) else 'not found'
        return f'{program!r}: {where} (on PATH or as a path)'
    return ''


def main(argv=None) -> int:
    """CLI of ``ceco benchmark``."""
    p = build_parser()
    args = p.parse_args(argv)
    if args.validate is not None:
        try:
            doc = read_results(args.validate)
        except ValueError as exc:
            print(f'ceco benchmark: {exc}', file=sys.stderr)
            return 2
        errors = check_results(doc)
        for e in errors:
            print(e, file=sys.stderr)
        print(f"{args.validate}: {'valid ' + SCHEMA if not errors else f'{len(errors)} problem(s)'}")
        return 1 if errors else 0
    if not args.out:
        p.error('--out is required (unless --validate)')
    cli_args.check_out(p, args.out)
    if args.controller_cmd is not None:
        why = controller_cmd_problem(args.controller_cmd)
        if why:
            p.error(f'argument --controller-cmd: {why}')
    if args.controller_name is not None and args.controller_cmd is None:
        p.error('argument --controller-name: needs --controller-cmd (it names the controller that command starts)')
    if args.address and args.backend != 'ray':
        p.error('--address needs --backend ray')
    if args.oracle_cases is not None and not args.oracle:
        p.error('--oracle-cases needs --oracle')
    cmd = 'ceco benchmark ' + ' '.join(shlex.quote(a) for a in (argv if argv is not None else sys.argv[1:]))
    try:
        doc = run_benchmark(
            args.cases,
            args.out,
            quick=args.quick,
            workers=args.workers,
            backend=args.backend,
            address=args.address,
            sensitivity=not args.no_sensitivity,
            oracle=args.oracle,
            oracle_cases=args.oracle_cases,
            controller_cmd=args.controller_cmd,
            controller_name=args.controller_name or 'external',
            save_runs=args.save_runs,
            progress=not args.no_progress,
            command=cmd,
            strategies=args.strategy,
        )
    except (CaseError, ResultsError, ValueError, RuntimeError, OSError) as exc:
        print(f'ceco benchmark: error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print('ceco benchmark: interrupted; finished runs are kept, rerun the same command to resume', file=sys.stderr)
        return 130
    t = doc['timing']
    print(
        f"ceco benchmark: {t['runs']} runs ({t['ran_now']} run now, {t['failed_now']} failed) in {t['wall_s']:.1f} s "
        f"on {t['workers']} worker(s) (runs {t['runs_phase_s']:.1f} s, oracle {t['oracle_phase_s']:.1f} s); "
        f"results {Path(args.out) / 'results.json'}, report "
        f"{Path(args.out) / 'report.html'}"
    )
    for line in summary_lines(doc):
        print(line)
    failed = sum(r['status'] != 'ok' for c in doc['cases'] for r in c['runs'])
    return 1 if failed else 0


def summary_lines(doc: dict) -> list[str]:
    """One console line per case and controller of a results document, then one per failed run.

    The matched savings are signed as in results.json: positive = less energy / less discomfort than
    the production-gains front (and, in the parentheses, its allowance front, the strongest family and
    headroom_captured when the case has an oracle front); where the saving is n/a, why (``note``: no
    extrapolation, a saturated discomfort). A run with status failed or error gets a line with its reason
    and no number.
    """

    def f(x):
        return 'n/a' if x is None else f'{x:+.1f} %'

    def strongest(m):
        st = m['strongest']
        h = m.get('headroom') or {}
        cap = h.get('headroom_captured')
        return (
            f"; strongest ({st['family'] or 'n/a'}) {f(st['energy_saving_pct'])}"
            + (', dominated by a family' if st['dominated'] else '')
            + ('' if not h else f"; headroom captured {'n/a' if cap is None else format(cap, '.2f')}")
        )

    lines = [
        f"  {case['case']:<18} {name:<32} energy saved at matched comfort {f(m['energy_saving_pct']):>8} "
        f"(allowance {f((m['allowance'] or {}).get('energy_saving_pct')):>8}{strongest(m)}), discomfort cut at "
        f"matched energy {f(m['discomfort_reduction_pct']):>8}{', dominated' if m['dominated'] else ''}"
        + (f"; n/a: {m['note']}" if m['energy_saving_pct'] is None and m.get('note') else '')
        for case in doc['cases']
        for name, m in case['matched'].items()
    ]
    for case in doc['cases']:
        aq = case.get('air_quality') or {}
        if not case['matched']:  # no front to read them against: said, never left out without a word
            unread = {r['controller'] for r in case['runs'] if r['status'] == 'ok' and r['kind'] in runner.SCORED_KINDS}
            pts = [p for ps in case['fronts'].values() for p in ps or []]
            why = (
                "every baseline's discomfort is saturated (no family front has a vertex)"
                if pts and not any(p['efficient'] for p in pts)
                else 'the production-gains family has no front'
            )
            lines += [
                f"  {case['case']:<18} {name:<32} not matched: {why}"
                for name in sorted(unread - set(aq.get('broken', [])))
            ]
        for name in aq.get('broken', []):
            lines.append(
                f"  {case['case']:<18} {name:<32} BROKE the air-quality limits (CO2 {aq['co2_limit_ppm']:g} ppm, fog "
                f"margin {aq['fog_margin_min_k']:g} K): not matched, no saving"
            )
    return lines + [  # failed runs: no number, the reason (a run whose controller did not control is no result)
        f"  {case['case']:<18} {r['controller']:<32} seed {r['seed']}: "
        f"{'FAILED' if r['status'] == 'failed' else 'ERROR'}: {r['error']}"
        for case in doc['cases']
        for r in case['runs']
        if r['status'] != 'ok'
    ]


if __name__ == '__main__':
    sys.exit(main())
