"""Where cells run: the resumable log and the backends (local process pool, Ray).

The functions here run any module-level (picklable) cell function, so ``ceco
sweep`` and ``ceco benchmark`` share them. Resume: each finished cell is appended
to ``cells.jsonl`` as one line with a single ``write`` on an ``O_APPEND``
descriptor and ``fsync``-ed; :func:`read_done` gives the cells already done.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import json
import multiprocessing
import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

__all__ = ['read_done', 'append_row', 'WORKER_THREAD_ENV', 'run_local', 'run_ray']


def read_done(log_path: str | os.PathLike) -> dict:
    """``{cell_id: row}`` of the finished cells in a ``cells.jsonl``: status 'ok' or 'failed'.

    A 'failed' run (the benchmark's verdict that its controller did not control it) is finished and
    deterministic, so a resume keeps it; an 'error' row is run again. Later lines win; an unreadable
    line, e.g. torn by a crash, is skipped.
    """
    done: dict = {}
    p = Path(log_path)
    if not p.is_file():
        return done
    for line in p.read_text(encoding='utf-8').splitlines():
        try:
            row = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(row, dict) and row.get('status') in ('ok', 'failed') and 'cell_id' in row:
            done[row['cell_id']] = row
    return done


def append_row(log_path: Path, row: Mapping) -> None:
    """Append one JSON line atomically: one write() on an O_APPEND fd, fsync."""
    data = (json.dumps(row, allow_nan=True, separators=(',', ':')) + '\n').encode('utf-8')
    fd = os.open(log_path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        # A torn last line (crash mid-write) is skipped by read_done; start on a new line.
        if os.fstat(fd).st_size:
            with open(log_path, 'rb') as fh:
                fh.seek(-1, os.SEEK_END)
                if fh.read(1) != b'\n':
                    data = b'\n' + data
        written = os.write(fd, data)
        if written != len(data):
            raise OSError(f'{log_path}: short write ({written} of {len(data)} bytes)')
        os.fsync(fd)
    finally:
        os.close(fd)


def _pythonpath() -> str:
    """Source dirs of the ceco packages as imported here, as a PYTHONPATH value.

    Spawned or Ray workers then import the same code.
    """
    dirs = []
    for mod in ('ceco_bringup', 'ceco_controller', 'ceco_plant_sim', 'ceco_v2x_preview', 'ceco_core', 'ceco_ros'):
        try:
            m = __import__(mod)
        except ImportError:
            continue
        dirs.append(str(Path(m.__file__).resolve().parent.parent))
    extra = os.environ.get('PYTHONPATH', '')
    return os.pathsep.join(dict.fromkeys(dirs + ([extra] if extra else [])))


WORKER_THREAD_ENV = {'OMP_NUM_THREADS': '1', 'OPENBLAS_NUM_THREADS': '1', 'MKL_NUM_THREADS': '1'}
"""Environment of parallel workers: one BLAS/OpenMP thread each. The solver
(IPOPT/MUMPS) and numpy otherwise start a thread per core in every worker;
two workers on two cores then ran a cell 2-3x slower than one worker alone
(measured: docs/analysis.md). A value the user set is kept."""


@contextlib.contextmanager
def _worker_env():
    """Set :data:`WORKER_THREAD_ENV` (where unset) while workers start.

    Spawned processes copy the environment at start.
    """
    added = {k: v for k, v in WORKER_THREAD_ENV.items() if k not in os.environ}
    os.environ.update(added)
    try:
        yield {k: os.environ[k] for k in WORKER_THREAD_ENV}
    finally:
        for k in added:
            os.environ.pop(k, None)


def run_local(items: Sequence, workers: int, on_done: Callable, fn: Callable, *args) -> None:
    """Run ``fn(item, *args)`` for every item, ``on_done(result)`` as each finishes.

    ``workers == 1``: in this process, in order. Otherwise a
    ``ProcessPoolExecutor`` with the ``spawn`` start method (``fn`` and the items
    must be picklable: module-level functions and plain data), each worker with
    :data:`WORKER_THREAD_ENV`. Ctrl-C cancels what has not started.
    """
    if workers == 1:
        for c in items:
            on_done(fn(c, *args))
        return
    ctx = multiprocessing.get_context('spawn')
    with _worker_env(), cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
        futures = [pool.submit(fn, c, *args) for c in items]
        try:
            for fut in cf.as_completed(futures):
                on_done(fut.result())
        except KeyboardInterrupt:
            for f in futures:
                f.cancel()
            raise


def run_ray(items: Sequence, workers: int, address: str | None, on_done: Callable, fn: Callable, *args) -> None:
    """Run ``fn(item, *args)`` for every item as Ray tasks (``num_cpus=1``, no retries).

    Without ``address`` a local Ray instance with ``workers`` CPUs is started and shut
    down at the end; with ``address`` the cluster is used and left running.
    """
    try:
        import ray  # optional extra
    except ImportError as exc:
        raise RuntimeError(
            '--backend ray needs the optional Ray extra: pip install -r requirements/analysis.txt (ray==2.60.0)'
        ) from exc
    with _worker_env() as thread_env:
        runtime_env = {'env_vars': {'PYTHONPATH': _pythonpath(), **thread_env}}
    started = False
    if not ray.is_initialized():
        if address:
            ray.init(address=address, runtime_env=runtime_env, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(num_cpus=workers, runtime_env=runtime_env, include_dashboard=False, log_to_driver=False)
        started = True
    try:
        remote = ray.remote(num_cpus=1, max_retries=0)(fn)
        pending = [remote.remote(c, *args) for c in items]
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            for ref in ready:
                on_done(ray.get(ref))
    finally:
        if started:
            ray.shutdown()
