"""Where cells run: the resumable log and the backends (local process pool, Ray), with warm workers.

The functions here run any module-level (picklable) cell function ``fn(item, *args,
controller_cache=...)``, so ``ceco sweep`` and ``ceco benchmark`` share them. Resume: each
finished cell is appended to ``cells.jsonl`` as one line with a single ``write`` on an
``O_APPEND`` descriptor and ``fsync``-ed; :func:`read_done` gives the cells already done.

Warm workers: a worker process (a pool process, a Ray actor, or the calling process with one
worker) imports the simulator once and keeps a :class:`WarmWorker`: the NMPC controllers it
built (:class:`ceco_controller.factory.ControllerCache`), reused after a reset by its later
cells, so no cell re-imports or re-builds what an earlier one on the same worker had (a reset
controller computes what a fresh one computes, bit for bit: ``tests/test_sweep.py``). Cells are
started longest first (:func:`estimated_cost`), so the last ones to finish are short and no
worker idles while another runs a long cell.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import json
import multiprocessing
import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from ceco_bringup.cli import SINGLE_THREAD_ENV

__all__ = [
    'read_done',
    'append_row',
    'WORKER_THREAD_ENV',
    'WarmWorker',
    'LocalPool',
    'estimated_cost',
    'run_local',
    'run_ray',
]


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


WORKER_THREAD_ENV = SINGLE_THREAD_ENV
"""Environment of parallel workers: one BLAS/OpenMP thread each. The solver
(IPOPT/MUMPS) and numpy otherwise start a thread per core in every worker;
two workers on two cores then ran a cell 2-3x slower than one worker alone
(measured: docs/analysis.md). A value the user set is kept. The ``ceco``
command sets the same for a single worker (this process)."""


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


class WarmWorker:
    """What one worker keeps between cells: the controllers it built.

    ``run(fn, item, *args)`` calls ``fn(item, *args, controller_cache=self.cache)``.
    """

    def __init__(self):
        import ceco_controller.closed_loop  # noqa: F401  (the simulator, imported once per worker, before its first cell)
        from ceco_controller.factory import ControllerCache

        self.cache = ControllerCache()
        """The worker's built controllers."""
        self.cells = 0
        """Cells this worker ran."""

    def run(self, fn: Callable, item, *args):
        """Run one cell with this worker's controllers."""
        self.cells += 1
        return fn(item, *args, controller_cache=self.cache)


_WORKER: WarmWorker | None = None
"""The pool worker's :class:`WarmWorker` (set by :func:`_start_worker` in each pool process only)."""


def _start_worker() -> None:
    """Pool initializer: the worker's imports and its :class:`WarmWorker`, before its first cell."""
    global _WORKER
    _WORKER = WarmWorker()


def _run_in_worker(fn: Callable, item, *args):
    """A pool task: the cell on this process's warm worker."""
    if _WORKER is None:  # (only if the pool was made without the initializer)
        _start_worker()
    assert _WORKER is not None
    return _WORKER.run(fn, item, *args)


NMPC_COST_FACTOR = 3.0
"""Run time of an NMPC cell relative to a baseline cell of the same length (measured on sc03: 2-4)."""


def estimated_cost(item: Mapping) -> float:
    """Relative run time of a cell (plain data with ``spec``): its length, times :data:`NMPC_COST_FACTOR` for an NMPC.

    Only the order in which cells start depends on it, never a result.
    """
    spec = item.get('spec', {}) if isinstance(item, Mapping) else {}
    scenario = spec.get('scenario') if isinstance(spec.get('scenario'), Mapping) else {}
    try:
        duration = float(spec.get('duration_s') or scenario.get('duration_s') or 600.0)
    except (TypeError, ValueError):
        duration = 600.0
    nmpc = spec.get('strategy') not in (None, 'baseline')
    horizon = spec.get('horizon_steps') or 6
    try:
        horizon_factor = max(1.0, float(horizon) / 6.0)
    except (TypeError, ValueError):
        horizon_factor = 1.0
    return duration * (NMPC_COST_FACTOR * horizon_factor if nmpc else 1.0)


def _longest_first(items: Sequence) -> list:
    return sorted(items, key=estimated_cost, reverse=True)


def _ready() -> int:
    """A no-op pool task: submitted at pool start so that every worker spawns (and imports) at once."""
    return os.getpid()


class LocalPool:
    """Warm workers on this machine, started when the pool is made (context manager).

    ``workers == 1``: one :class:`WarmWorker` in this process, made at the first :meth:`run`.
    Otherwise a ``ProcessPoolExecutor`` with the ``spawn`` start method and ``workers``
    processes, each a :class:`WarmWorker` with :data:`WORKER_THREAD_ENV`, spawned at once: they
    import the simulator while the caller still plans its cells (the pool is made first, the
    cells submitted later). :meth:`run` may be called more than once (the benchmark's runs, then
    its oracle cells) on the same warm workers. :meth:`close` does not wait for the worker
    processes to exit (their interpreter teardown overlaps the caller's report).
    """

    def __init__(self, workers: int):
        self.workers = max(1, int(workers))
        """Worker processes (1: this process)."""
        self._local: WarmWorker | None = None
        self._pool: cf.ProcessPoolExecutor | None = None
        if self.workers > 1:
            ctx = multiprocessing.get_context('spawn')
            with _worker_env():  # spawned processes copy the environment when they start: start them all here
                self._pool = cf.ProcessPoolExecutor(max_workers=self.workers, mp_context=ctx, initializer=_start_worker)
                for _ in range(self.workers):  # one submit spawns one process (spawn context, Python >= 3.9)
                    self._pool.submit(_ready)

    def worker_pids(self) -> set[int]:
        """The pool's process ids (this process's with one worker)."""
        if self._pool is None:
            return {os.getpid()}
        return {p.pid for p in self._pool._processes.values()}  # the executor's own record of its processes

    def __enter__(self) -> LocalPool:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def run(self, items: Sequence, on_done: Callable, fn: Callable, *args) -> None:
        """Run ``fn(item, *args, controller_cache=...)`` for every item, ``on_done(result)`` as each finishes.

        One worker: in order, in this process. Otherwise cells started longest first; Ctrl-C
        cancels what has not started. ``fn`` and the items must be picklable (module-level
        functions and plain data).
        """
        if self._pool is None:
            if self._local is None:
                self._local = WarmWorker()
            for c in items:
                on_done(self._local.run(fn, c, *args))
            return
        futures = [self._pool.submit(_run_in_worker, fn, c, *args) for c in _longest_first(items)]
        try:
            for fut in cf.as_completed(futures):
                on_done(fut.result())
        except BaseException:
            for f in futures:
                f.cancel()
            raise

    def close(self) -> None:
        """Stop the workers (cancel what has not started; do not wait for the processes to exit)."""
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None


def run_local(items: Sequence, workers: int, on_done: Callable, fn: Callable, *args) -> None:
    """Run ``fn(item, *args, controller_cache=...)`` for every item on a :class:`LocalPool` of ``workers``.

    ``on_done(result)`` as each finishes; see :meth:`LocalPool.run`.
    """
    with LocalPool(workers) as pool:
        pool.run(items, on_done, fn, *args)


class _RayWorker(WarmWorker):
    """A Ray actor: a :class:`WarmWorker` that also names the Ray node it runs on in each row."""

    def __init__(self):
        super().__init__()
        import ray

        self.node_id = ray.get_runtime_context().get_node_id()

    def run(self, fn: Callable, item, *args):
        """Run one cell; the row gets ``ray_node`` (this actor's node id)."""
        row = super().run(fn, item, *args)
        if isinstance(row, dict):
            row['ray_node'] = self.node_id
        return row


def run_ray(items: Sequence, workers: int | None, address: str | None, on_done: Callable, fn: Callable, *args) -> None:
    """Run ``fn(item, *args, controller_cache=...)`` for every item on Ray actors (one CPU each), longest first.

    Each actor is a :class:`WarmWorker` that stays up for the whole run; every row gets ``ray_node``.
    Without ``address`` a local Ray instance with ``workers`` CPUs is started and shut down at the
    end; with ``address`` (``auto``, ``HOST:PORT`` of a cluster's head, ``ray://HOST:10001``) the
    cluster is used and left running, with ``workers`` actors (None: one per CPU of the cluster).
    """
    try:
        import ray  # optional extra
        from ray.util import ActorPool
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
            ray.init(
                num_cpus=workers or os.cpu_count(),
                runtime_env=runtime_env,
                include_dashboard=False,
                log_to_driver=False,
            )
        started = True
    try:
        n = workers if workers else max(1, int(ray.cluster_resources().get('CPU', 1)))
        actor = ray.remote(num_cpus=1, max_restarts=0, max_task_retries=0)(_RayWorker)
        pool = ActorPool([actor.remote() for _ in range(max(1, min(n, len(items))))])
        for row in pool.map_unordered(lambda a, c: a.run.remote(fn, c, *args), _longest_first(items)):
            on_done(row)
    finally:
        if started:
            ray.shutdown()
