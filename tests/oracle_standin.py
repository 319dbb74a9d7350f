"""A stand-in for the oracle's entry point in the benchmark's plumbing tests (not an optimum).

``solve_front(case, seed, levels)`` has the interface of ``ceco_controller.oracle.solve_front``
(docs/benchmark.md, "The oracle") and returns real scored runs: the production law at one warm
set-point per level (the simulator and ``compute_kpis``, as every benchmark run), with the
first level left unsolved (None) so that a missing level is exercised. It makes no claim to
be a bound: the tests that use it check the plumbing (cells, caching, the results format,
headroom_captured from whatever front the oracle returns), never its numbers.
"""

from ceco_controller.closed_loop import SimSettings, simulate
from ceco_core.kpis import compute_kpis

CALLS = []
"""(case name, seed, levels) of every call in this process (the tests check the caching)."""


def solve_front(case, seed, levels):
    """One item per level: None for the first, then the KPIs of the PI law at 27, 28, ... degC."""
    CALLS.append((case.name, seed, list(levels)))
    out = [None]
    for i, _ in enumerate(levels[1:]):
        settings = SimSettings(progress=False, strategy_overrides=(('setpoint_c', 27.0 + i),))
        res = simulate(case.load_scenario(), 'baseline', settings)
        kpis, _ = compute_kpis(
            res.timeseries,
            step_time_s=res.step_time_s,
            control_period_s=res.metrics['control_period_s'],
            fallback_steps=0,
        )
        out.append(kpis)
    return out


def solve_front_accounted(case, seed, levels):
    """``solve_front``'s items in the form ceco's oracle returns (``{'kpis', 'solver'}``): the first level
    unsolved with a wall-limit account, the others with the KPIs above and a made-up, well-formed account
    (the plumbing keeps whatever the entry point says; these are not IPOPT's numbers)."""
    items = solve_front(case, seed, levels)
    out = [{'kpis': None, 'solver': {'status': 'Maximum_WallTime_Exceeded', 'iterations': 57, 'wall_time_s': 900.4}}]
    for i, k in enumerate(items[1:]):
        acc = {'status': 'Solve_Succeeded', 'iterations': 10 + i, 'wall_time_s': 1.5, 'evaluation': 'compiled'}
        out.append({'kpis': k, 'solver': acc})
    return out


def solve_front_bad_account(case, seed, levels):
    """Items whose solver account is malformed (a negative iteration count): the cell must fail with why."""
    bad = {'status': 'Solve_Succeeded', 'iterations': -1, 'wall_time_s': 1.0}
    return [{'kpis': None, 'solver': dict(bad)} for _ in levels]
