"""Worker scaling of ``ceco benchmark``: 2 workers (and Ray) against 1 worker, measured in the same run.

    python tools/bench_workers.py [--case sc03-paper] [--workers 2] [--repeat 2] [--ray] [--before DIR]

Runs ``ceco benchmark CASE --no-sensitivity --workers 1`` and ``--workers N`` (and, with ``--ray``,
``--backend ray --workers N``) as fresh processes, alternating, ``--repeat`` times each, into temporary
directories. Prints per run the wall time, the CPU time of the process and its pool workers (user +
system of the reaped children; a Ray run's actors belong to Ray's daemons and are not counted) and the
1-minute load average before and after; then the speed-up of N workers over 1 (median walls) and Ray
over the local pool, and checks that every run's KPIs are bit-identical to the 1-worker run's (the
same cell ids, the same ``status`` and ``kpis`` in ``cells.jsonl``, but the wall-clock ones). The
issue-19 targets: N = 2 at least 1.7x faster than 1; Ray within 1.2x of the local pool. Other
processes on the machine bias every figure: read the load next to it (the speed-up needs 2 free
cores). ``--before DIR``: also run 1 and N workers from another source tree (e.g. ``git archive main | tar -x
-C DIR``; its package directories put first on PYTHONPATH), interleaved with these runs: before and after at
the same load; the CPU time each adds for N workers over 1 is printed. Last line: one JSON object.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

WALL_CLOCK_KPIS = ('time_ratio_mean', 'time_ratio_max')
"""KPIs measured on the wall clock (control-step time / Ts): they differ from run to run and are not compared."""


def _kpis(out: Path) -> dict:
    """``{cell_id: (status, kpis without WALL_CLOCK_KPIS)}`` of a benchmark directory's ``cells.jsonl``."""
    rows = [json.loads(line) for line in (out / 'cells.jsonl').read_text(encoding='utf-8').splitlines() if line]
    return {
        r['cell_id']: (
            r['status'],
            json.dumps({k: v for k, v in (r['kpis'] or {}).items() if k not in WALL_CLOCK_KPIS}, sort_keys=True),
        )
        for r in rows
    }


PACKAGES = ('ceco_bringup', 'ceco_controller', 'ceco_plant_sim', 'ceco_v2x_preview', 'ceco_core', 'ceco_ros')
"""The package directories of a source tree (each holds the importable package of its name)."""


def run_once(case: str, workers: int, backend: str, root: Path, tag: str, tree: Path | None = None) -> dict:
    """One ``ceco benchmark`` process (of ``tree``'s code if given); wall, CPU, load and its KPIs."""
    out = root / tag
    env = dict(os.environ)
    if tree is not None:
        env['PYTHONPATH'] = os.pathsep.join([str(tree / d) for d in PACKAGES] + [env.get('PYTHONPATH', '')])
    cmd = [sys.executable, '-m', 'ceco_bringup.cli', 'benchmark', case, '--no-sensitivity', '--no-progress']
    cmd += ['--workers', str(workers), '--backend', backend, '--out', str(out)]
    load0 = os.getloadavg()[0]
    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f'{" ".join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-3000:]}')
    return {
        'code': 'before' if tree is not None else 'this',
        'backend': backend,
        'workers': workers,
        'wall_s': wall,
        'cpu_s': (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime),
        'load_before': load0,
        'load_after': os.getloadavg()[0],
        'kpis': _kpis(out),
    }


def main(argv=None) -> int:
    """CLI (see the module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--case', default='sc03-paper')
    ap.add_argument('--workers', type=int, default=2, help='the parallel run (default 2)')
    ap.add_argument('--repeat', type=int, default=2)
    ap.add_argument('--ray', action='store_true', help='also --backend ray (the optional Ray extra)')
    ap.add_argument('--before', type=Path, default=None, help='another source tree to compare (1 and N workers)')
    args = ap.parse_args(argv)
    configs = [(None, 'local', 1), (None, 'local', args.workers)]
    configs += [(None, 'ray', args.workers)] if args.ray else []
    configs += [(args.before, 'local', 1), (args.before, 'local', args.workers)] if args.before else []
    runs: list[dict] = []
    with tempfile.TemporaryDirectory(prefix='ceco-bench-workers-') as tmp:
        for i in range(args.repeat):
            for tree, backend, n in configs if i % 2 == 0 else configs[::-1]:
                r = run_once(args.case, n, backend, Path(tmp), f'{tree is not None}-{backend}-{n}-{i}', tree)
                runs.append(r)
                print(
                    f'{r["code"]:6s} {backend:5s} workers {n}: wall {r["wall_s"]:6.1f} s, CPU {r["cpu_s"]:6.1f} s '
                    f'(load {r["load_before"]:.2f} -> {r["load_after"]:.2f})',
                    flush=True,
                )
    this = [r for r in runs if r['code'] == 'this']
    ref = next(r for r in this if r['backend'] == 'local' and r['workers'] == 1)['kpis']
    identical = all(r['kpis'] == ref for r in this)  # (another tree's code gives other cell ids)

    def median_of(key: str, backend: str, n: int, code: str = 'this') -> float:
        rs = [r[key] for r in runs if r['code'] == code and r['backend'] == backend and r['workers'] == n]
        return statistics.median(rs)

    def median_wall(backend: str, n: int) -> float:
        return median_of('wall_s', backend, n)

    one, many = median_wall('local', 1), median_wall('local', args.workers)
    summary = {
        'case': args.case,
        'runs_per_benchmark': len(ref),
        'wall_1_s': one,
        f'wall_{args.workers}_s': many,
        'speedup': one / many,
        'identical_kpis': identical,
        'load_1min': [r['load_before'] for r in runs],
    }
    print(
        f'{args.workers} workers vs 1: {summary["speedup"]:.2f}x '
        f'(median walls {one:.1f} / {many:.1f} s; target >= 1.7x)'
    )
    if args.ray:
        ray = median_wall('ray', args.workers)
        summary['wall_ray_s'], summary['ray_vs_local'] = ray, ray / many
        print(f'Ray vs local pool ({args.workers} workers): {ray / many:.2f}x the local wall (target <= 1.2x)')
    for code in ('this', 'before') if args.before else ('this',):
        extra = median_of('cpu_s', 'local', args.workers, code) - median_of('cpu_s', 'local', 1, code)
        summary[f'extra_cpu_{code}_s'] = extra
        speed = median_of('wall_s', 'local', 1, code) / median_of('wall_s', 'local', args.workers, code)
        summary[f'speedup_{code}'] = speed
        print(f'{code}: {args.workers} workers use {extra:+.1f} s of CPU over 1 worker (median); speed-up {speed:.2f}x')
    print(f'KPIs bit-identical across every run of this code: {identical}')
    print(json.dumps(summary))
    return 0 if identical else 1


if __name__ == '__main__':
    sys.exit(main())
