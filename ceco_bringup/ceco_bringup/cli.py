"""The `ceco` command: one verb per module, each module owning its argparse.

ceco run      run the node stack over DDS and record a rosbag2 bag
ceco play     republish a recorded bag on DDS
ceco report   metrics and figures from run directories
ceco sweep    scenario grids with the in-process simulator
ceco benchmark  named test cases, baseline family, savings at matched comfort
ceco sim      one closed-loop run in-process (no ROS)
ceco oracle   the whole-drive optimum of a benchmark case (the bound)
ceco identify identify the control-oriented model from plant data
ceco bench    benchmarks: NMPC solver (nmpc), plant step (plant)
ceco security create-keystore DIR: an SROS2 keystore with ceco's access control
"""

import importlib
import os
import sys

VERBS = {
    'run': ('ceco_bringup.run', 'run the node stack over DDS and record a rosbag2 bag'),
    'play': ('ceco_bringup.play', 'republish a recorded bag on DDS'),
    'report': ('ceco_bringup.report', 'metrics, figures and reports from run directories'),
    'sweep': ('ceco_bringup.sweep', 'run a grid of scenarios with the in-process simulator'),
    'benchmark': ('ceco_bringup.benchmark.cli', 'savings at matched comfort on the named test cases'),
    'sim': ('ceco_bringup.sim', 'one closed-loop run in-process (no ROS)'),
    'oracle': ('ceco_bringup.oracle_cli', 'the whole-drive optimum of a benchmark case (the bound)'),
    'identify': ('ceco_controller.identification', 'identify the control-oriented model'),
    'bench': (
        'ceco_controller.bench',
        'benchmarks (ceco bench nmpc: the NMPC solver; ceco bench plant: the plant step)',
    ),
    'security': ('ceco_bringup.security', 'SROS2 keystore (ceco security create-keystore DIR)'),
}

SINGLE_THREAD_VERBS = frozenset({'sweep', 'benchmark', 'sim'})
"""Verbs that run the in-process simulator: one BLAS/OpenMP thread (:data:`SINGLE_THREAD_ENV`), as their pool
workers (``ceco_bringup.sweep.backends.WORKER_THREAD_ENV``). Its matrices are tiny (4x4 to ~100x100): a second
BLAS thread only contends; measured on the 2-core machine at load 3: the CO2 estimator's 4x4 ``expm`` 5.5 ms per
call with OpenBLAS' default threads, 0.07 ms with one (docs/analysis.md)."""

SINGLE_THREAD_ENV = {'OMP_NUM_THREADS': '1', 'OPENBLAS_NUM_THREADS': '1', 'MKL_NUM_THREADS': '1'}
"""The thread environment of :data:`SINGLE_THREAD_VERBS` (the same values as the pool workers')."""


class PipeSafeStdout:
    """Standard output that goes on to /dev/null once its reader has closed the pipe (``ceco sim ... | head -1``).

    Python ignores SIGPIPE, so a write to a closed pipe raised BrokenPipeError from the first table line: a
    traceback, and ``ceco sim`` never wrote its job's files (comparison.csv, verdict.json, ...), which come after
    the table. Now the first such write points file descriptor 1 at /dev/null and the verb goes on: what was
    left to print is dropped, every file is written, the exit status is the verb's.
    """

    def __init__(self, inner):
        self._inner = inner

    def _to_devnull(self) -> None:
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, self._inner.fileno())
        finally:
            os.close(devnull)

    def write(self, text: str) -> int:
        """Write ``text``; to /dev/null from the first write that finds the reader gone."""
        try:
            return self._inner.write(text)
        except BrokenPipeError:
            self._to_devnull()
            return len(text)

    def flush(self) -> None:
        """Flush; a reader gone sends the buffered text to /dev/null."""
        try:
            self._inner.flush()
        except BrokenPipeError:
            self._to_devnull()
            self._inner.flush()  # what was buffered goes to /dev/null

    def __getattr__(self, name):
        return getattr(self._inner, name)


def _usage() -> str:
    lines = ['usage: ceco VERB [options]   (ceco VERB --help for a verb\'s options)', '']
    lines += [f'  {verb:<9} {help_}' for verb, (_, help_) in VERBS.items()]
    return '\n'.join(lines)


def main(argv=None) -> int:
    """Run the ``ceco`` command: hand the arguments after the verb to that verb's module ``main``.

    Args:
        argv: the command-line arguments after ``ceco``, verb first (default ``sys.argv[1:]``).

    Returns:
        The exit status: the verb's own, 0 for ``--help``, 2 without a verb or for an unknown verb
        (the usage is printed in those cases).
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    if not isinstance(sys.stdout, PipeSafeStdout) and sys.stdout is not None:
        sys.stdout = PipeSafeStdout(sys.stdout)
    if not argv or argv[0] in ('-h', '--help'):
        print(_usage())
        return 0 if argv else 2
    verb, rest = argv[0], argv[1:]
    if verb not in VERBS:
        print(f'ceco: unknown verb {verb!r}\n\n{_usage()}', file=sys.stderr)
        return 2
    if verb in SINGLE_THREAD_VERBS:
        for k, v in SINGLE_THREAD_ENV.items():
            os.environ.setdefault(k, v)  # before numpy is imported; a value the user set is kept
    module = importlib.import_module(VERBS[verb][0])
    return int(module.main(rest) or 0)


if __name__ == '__main__':
    sys.exit(main())
