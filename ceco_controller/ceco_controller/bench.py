"""``ceco bench nmpc``: NMPC solve and step times in closed loop against a reference solver.

For each CECO strategy and horizon Np in (6, 12, 24, 60), a closed-loop SC03 run is simulated
with the product solver settings. At every control step the very same NLP instance (same
parameters) is also solved by the reference: CasADi + IPOPT with its default settings and no
warm start (what the paper's MPCTools did), started from the same model-rollout guess a cold
solve gets. Printed per case: solve time (median, p95, max) of both and the speed-up of the
medians; the whole control step (observation built, checks, solve chain, command; median,
p99); the largest relative difference of the optimal costs over the steps where both solvers
report success, with its sign (the NLP is non-convex: ``max_rel_cost_excess`` is how much *worse*
the product's optimum was); the steps without a usable NMPC solution (``failures``).

Then the slow-down table (:func:`ceco_controller.bench_cases.slowdown_table`, SC03, Np = 6):
the time budgets divided by 1, 10 and 100, full SQP and the bounded-cost mode (one QP per step),
steps under NMPC control and the bounded-cost mode's optimality loss. Last line: one JSON object.

This is a benchmark, not a test: wall-clock times depend on the machine and its load (2 shared
cores here, ``os.getloadavg`` printed); only ratios measured in the same run compare.

    python -m ceco_controller.bench nmpc [--quick] [--jit | --no-codegen] [--horizons 6,12]
        [--strategy ceco,ceco-c] [--duration-s 200] [--method auto|ipopt|sqp|fatrop]
        [--transcription auto|single-shooting|multiple-shooting] [--cpu-slowdown 100]
        [--slowdown-factors 1,10,100 | --slowdown-factors ''] [--no-prepare] [--robustness] [--rti-cases]
        [--node] [--no-progress]

Per case it also prints the whole step's CPU time and the solver's (``time.thread_time``: on a
loaded machine the wall clock mostly measures the wait for a core), the share of the step that is
not the solver and the step / solver ratio; at the end the horizon table (product solver, speed-up
over IPOPT's defaults in wall and CPU time, cost difference). ``--node`` adds the whole step inside
``mpc_node`` at Np = 6, message in to command out (:mod:`ceco_controller.bench_node`).

``--cpu-slowdown F`` runs the main cases with every time budget divided by F (an ECU F times
slower). ``--robustness`` adds the sweep over every benchmark scenario and preview fault
(:func:`~ceco_controller.bench_cases.robustness`); ``--rti-cases`` the bounded-cost mode against the
full SQP on every benchmark scenario. ``--no-prepare``: the first step is solved
inside its budget instead of by :meth:`NmpcController.prepare` before the controller takes over.

The reference is always the multiple-shooting NLP (MPCTools' transcription) with IPOPT's
defaults, in-process functions; when the product's NLP is the single-shooting one, IPOPT's
defaults on that NLP are timed as well (``ref_same_nlp_median_ms``). The product solver runs
with ``codegen`` (compiled functions from the on-disk cache; ``python -m
ceco_controller.nlp_cache --fill`` compiles them ahead of time).
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

from ceco_core import cli_flags
from ceco_core.contracts import BASELINE_STRATEGY, STRATEGIES
from ceco_v2x_preview.scenario import load_scenario

from . import closed_loop as cl
from . import model as cm
from .bench_cases import BENCH_SCENARIOS, budget_settings, robustness, slowdown_table, timed_run
from .solvers import NlpData
from .strategies import CECO_STRATEGIES, SOLVER_NAMES, SolverSettings

__all__ = ["main", "bench_nmpc", "non_solver", "horizon_table"]

_DEFAULT = SolverSettings()


def _stats(x):
    x = np.asarray(x, float)
    if x.size == 0:
        return {"median": float("nan"), "p95": float("nan"), "p99": float("nan"), "max": float("nan")}
    return {
        "median": float(np.median(x)),
        "p95": float(np.percentile(x, 95)),
        "p99": float(np.percentile(x, 99)),
        "max": float(np.max(x)),
    }


def _json_float(v: float) -> float | None:
    """NaN (a statistic with no sample, e.g. no same-NLP reference) as JSON null, not the invalid NaN."""
    return None if v != v else v


def non_solver(step_ms: np.ndarray, solve_ms: np.ndarray) -> dict:
    """What of the whole step is not the solver: per step ``step - solve`` [ms].

    Returns ``non_solver_median_ms`` (median over the steps), ``non_solver_share`` (the sum over the
    steps over the sum of the step times: the share of the step's time spent around the solver) and
    ``step_over_solve`` (median step time over median solver time; the target is <= 2).
    """
    step_ms, solve_ms = np.asarray(step_ms, float), np.asarray(solve_ms, float)
    if step_ms.size == 0 or step_ms.size != solve_ms.size:
        return {"non_solver_median_ms": float("nan"), "non_solver_share": float("nan"), "step_over_solve": float("nan")}
    rest = step_ms - solve_ms
    solved = solve_ms > 0
    return {
        "non_solver_median_ms": float(np.median(rest)),
        "non_solver_share": float(np.sum(rest) / np.sum(step_ms)),
        "step_over_solve": float(np.median(step_ms) / np.median(solve_ms[solved])) if solved.any() else float("nan"),
    }


def _bench_case(strat, np_, sc, mp, overrides, duration_s, progress, prepare) -> tuple[dict, np.ndarray]:
    ctrl = cl.make_controller(strat, sc, sc.control.control_period_s, np_, mp, overrides)
    # the reference: MPCTools' transcription (multiple shooting), IPOPT defaults, in-process functions
    ref_ctrl = cl.make_controller(
        strat,
        sc,
        sc.control.control_period_s,
        np_,
        mp,
        {"solver": SolverSettings(name="ipopt", default_options=True, transcription="multiple-shooting")},
    )
    # and, if the product's transcription differs, IPOPT defaults on the product's own NLP
    same_solver = (
        ctrl.make_solver(SolverSettings(name="ipopt", default_options=True))
        if ctrl.transcription != "multiple-shooting"
        else None
    )
    acc: dict[str, list] = {
        k: []
        for k in (
            "ours_t",
            "ref_t",
            "ref_cpu",
            "diffs",
            "sdiffs",
            "ours_it",
            "ref_it",
            "same_t",
            "step_solve",
            "step_solve_cpu",
        )
    }
    fails = {"n_fail": 0, "n_ref_fail": 0, "n_ref_same_nlp_fail": 0}

    def on_step(obs, cmd, diag):
        data = ctrl.last_nlp()
        chain = ctrl.last_chain() if diag.solve_time_ms is not None else None
        acc["step_solve"].append(diag.solve_time_ms or 0.0)
        acc["step_solve_cpu"].append((chain.cpu_ms or 0.0) if chain is not None else 0.0)
        if diag.solve_time_ms is not None:
            acc["ours_t"].append(diag.solve_time_ms)
            acc["ours_it"].append(diag.iterations if diag.iterations is not None else np.nan)
        fails["n_fail"] += diag.fallback != ""
        if data is None:
            return
        # the reference solves the same instance from the cold model-rollout guess
        ref = ref_ctrl.solve_nlp(NlpData(p=data.p, x0=ref_ctrl.initial_guess(data.p)), ref_ctrl.solver)
        if same_solver is not None:
            same = ctrl.solve_nlp(NlpData(p=data.p, x0=ctrl.initial_guess(data.p)), same_solver)
            acc["same_t"].append(same.time_ms)
            fails["n_ref_same_nlp_fail"] += not same.success
        acc["ref_t"].append(ref.time_ms)
        acc["ref_cpu"].append(ref.cpu_ms if ref.cpu_ms is not None else np.nan)
        acc["ref_it"].append(ref.iterations)
        fails["n_ref_fail"] += not ref.success
        if ref.success and diag.success and diag.cost_total is not None:
            acc["sdiffs"].append((diag.cost_total - ref.f) / max(abs(ref.f), 1e-9))
            acc["diffs"].append(abs(acc["sdiffs"][-1]))

    cpu_ms: list[float] = []
    res, step_ms = timed_run(
        ctrl,
        sc,
        strat,
        cl.SimSettings(horizon_steps=np_, duration_s=duration_s, progress=progress),
        on_step,
        prepare,
        cpu_ms,
    )
    o, r, sm, st = _stats(acc["ours_t"]), _stats(acc["ref_t"]), _stats(acc["same_t"]), _stats(step_ms)
    share = non_solver(step_ms, np.asarray(acc["step_solve"], float))
    share_cpu = {f"cpu_{k}": v for k, v in non_solver(np.asarray(cpu_ms), np.asarray(acc["step_solve_cpu"])).items()}
    diffs, sdiffs, c = acc["diffs"], acc["sdiffs"], ctrl.counters
    row = {
        "strategy": strat,
        "np": np_,
        "solver": ctrl.settings.solver.name + ("-rti" if ctrl.settings.solver.rti else ""),
        "transcription": ctrl.transcription,
        "steps": len(step_ms),
        "budget_ms": 1e3 * ctrl.settings.solver.step_budget_s,
        "ours_median_ms": o["median"],
        "ours_p95_ms": o["p95"],
        "ours_max_ms": o["max"],
        "ours_iter_median": float(np.nanmedian(acc["ours_it"])) if acc["ours_it"] else float("nan"),
        "step_median_ms": st["median"],
        "step_p99_ms": st["p99"],
        "step_max_ms": st["max"],
        "step_cpu_median_ms": float(np.median(cpu_ms)) if cpu_ms else float("nan"),
        "step_cpu_p99_ms": float(np.percentile(cpu_ms, 99)) if cpu_ms else float("nan"),
        "solve_cpu_median_ms": float(np.median([c for c in acc["step_solve_cpu"] if c > 0] or [np.nan])),
        **share,
        **share_cpu,
        "ref_median_ms": r["median"],
        "ref_p95_ms": r["p95"],
        "ref_max_ms": r["max"],
        "ref_iter_median": float(np.median(acc["ref_it"])) if acc["ref_it"] else float("nan"),
        "ref_same_nlp_median_ms": sm["median"],
        "speedup_median": r["median"] / o["median"] if o["median"] > 0 else float("nan"),
        "ref_cpu_median_ms": float(np.nanmedian(acc["ref_cpu"])) if acc["ref_cpu"] else float("nan"),
        "max_rel_cost_diff": max(diffs) if diffs else float("nan"),
        "max_rel_cost_excess": max(max(sdiffs), 0.0) if sdiffs else float("nan"),
        "n_rel_cost_diff_gt_1e-4": int(sum(d > 1e-4 for d in diffs)),
        **fails,
        "failures": fails["n_fail"],
        "n_ipopt_fallbacks": ctrl.n_ipopt_fallbacks,
        "accepted_iterates": c.accepted_iterates,
        "deadline_hits": c.deadline_hits,
        "load_1min": os.getloadavg()[0],
    }
    row["speedup_cpu"] = row["ref_cpu_median_ms"] / row["solve_cpu_median_ms"]
    return row, step_ms


def bench_nmpc(
    strategies,
    horizons,
    duration_s=None,
    jit=False,
    scenario="sc03",
    progress=False,
    codegen=True,
    method=_DEFAULT.name,
    transcription=_DEFAULT.transcription,
    cpu_slowdown: float = 1.0,
    prepare: bool = True,
) -> tuple[list[dict], dict]:
    """Run the benchmark; return one dict per (strategy, horizon) and the whole-step times per horizon [ms]."""
    sc = load_scenario(scenario)
    mp = cm.load_params()
    rows: list = []
    steps: dict = {}
    for np_ in horizons:
        for strat in strategies:
            overrides = {
                "solver": budget_settings(
                    cpu_slowdown, name=method, jit=jit, codegen=codegen and not jit, transcription=transcription
                )
            }
            rr, step_ms = _bench_case(strat, np_, sc, mp, overrides, duration_s, progress, prepare)
            rows.append(rr)
            steps.setdefault(np_, []).extend(step_ms.tolist())
            print(
                f"{strat:10s} Np={np_:3d} steps={rr['steps']:4d}  ours median {rr['ours_median_ms']:7.2f} ms "
                f"p95 {rr['ours_p95_ms']:7.2f} max {rr['ours_max_ms']:7.2f} (it {rr['ours_iter_median']:.0f}); "
                f"whole step median {rr['step_median_ms']:6.2f} p99 {rr['step_p99_ms']:6.2f} (not solver "
                f"{rr['non_solver_median_ms']:.2f} ms = {100 * rr['non_solver_share']:.0f} %, step/solve "
                f"{rr['step_over_solve']:.2f}; CPU: step {rr['step_cpu_median_ms']:.2f}, solver "
                f"{rr['solve_cpu_median_ms']:.2f}, not solver {100 * rr['cpu_non_solver_share']:.0f} %, step/solve "
                f"{rr['cpu_step_over_solve']:.2f})  |  "
                f"IPOPT default median {rr['ref_median_ms']:7.2f} p95 {rr['ref_p95_ms']:7.2f} "
                f"max {rr['ref_max_ms']:7.2f} (it {rr['ref_iter_median']:.0f})"
                + (
                    f" [on our NLP: median {rr['ref_same_nlp_median_ms']:.2f}]"
                    if rr["ref_same_nlp_median_ms"] == rr["ref_same_nlp_median_ms"]
                    else ""
                )
                + f"  speed-up {rr['speedup_median']:5.1f}x (CPU time {rr['speedup_cpu']:.1f}x)  max rel cost diff "
                f"{rr['max_rel_cost_diff']:.1e} "
                f"(ours higher by <= {rr['max_rel_cost_excess']:.1e}; {rr['n_rel_cost_diff_gt_1e-4']} steps > 1e-4)  "
                f"failures {rr['failures']} (ref fails {rr['n_ref_fail']})  [{rr['solver']}, {rr['transcription']}; "
                f"ipopt retries {rr['n_ipopt_fallbacks']}, iterates {rr['accepted_iterates']}; budget "
                f"{rr['budget_ms']:.0f} ms; load {rr['load_1min']:.1f}]",
                flush=True,
            )
    return rows, steps


def horizon_table(rows: list[dict]) -> list[dict]:
    """One row per horizon over the strategies: the product solver against IPOPT's defaults.

    ``speedup`` is the ratio of the medians over all steps of all strategies (each strategy's median
    first, then the median of those); ``max_rel_cost_diff`` the largest over the strategies.
    """
    out = []
    for np_ in sorted({r["np"] for r in rows}):
        rs = [r for r in rows if r["np"] == np_]
        ours = float(np.median([r["ours_median_ms"] for r in rs]))
        ref = float(np.median([r["ref_median_ms"] for r in rs]))
        out.append(
            {
                "np": np_,
                "solver": sorted({f"{r['solver']}/{r['transcription']}" for r in rs}),
                "ours_median_ms": ours,
                "ref_median_ms": ref,
                "speedup": ref / ours if ours > 0 else float("nan"),
                "speedup_min": float(np.nanmin([r["speedup_median"] for r in rs])),
                "speedup_cpu": float(
                    np.median([r["ref_cpu_median_ms"] for r in rs]) / np.median([r["solve_cpu_median_ms"] for r in rs])
                ),
                "speedup_cpu_min": float(np.nanmin([r["speedup_cpu"] for r in rs])),
                "max_rel_cost_diff": float(np.nanmax([r["max_rel_cost_diff"] for r in rs])),
                "step_median_ms": float(np.median([r["step_median_ms"] for r in rs])),
                "step_p99_ms": float(np.max([r["step_p99_ms"] for r in rs])),
                "non_solver_share": float(np.median([r["non_solver_share"] for r in rs])),
                "failures": int(sum(r["failures"] for r in rs)),
            }
        )
    return out


def _print_horizon_table(table: list[dict]) -> None:
    print(
        "horizon table: Np | product solver | ours median [ms] | IPOPT defaults median [ms] | speed-up "
        "(worst strategy) | speed-up in CPU time (worst) | max rel cost diff | whole step median / p99 [ms] | "
        "not solver | failures",
        flush=True,
    )
    for t in table:
        print(
            f"  {t['np']:3d} | {', '.join(t['solver'])} | {t['ours_median_ms']:.2f} | {t['ref_median_ms']:.2f} | "
            f"{t['speedup']:.1f}x ({t['speedup_min']:.1f}x) | {t['speedup_cpu']:.1f}x ({t['speedup_cpu_min']:.1f}x) | "
            f"{t['max_rel_cost_diff']:.1e} | "
            f"{t['step_median_ms']:.2f} / {t['step_p99_ms']:.2f} | {100 * t['non_solver_share']:.0f} % | "
            f"{t['failures']}",
            flush=True,
        )


def _summary(rows, steps, args, codegen, horizons, strategies, duration) -> dict:
    # The np6_* keys summarise Np = 6 only; without an Np = 6 run they are null
    # (never the numbers of another horizon under the np6 name).
    np6 = [r for r in rows if r["np"] == 6]

    def _np6(values, reduce):
        return float(reduce(values)) if np6 else None

    s6 = np.asarray(steps.get(6, []), float)
    return {
        "np6_median_ms": _np6([r["ours_median_ms"] for r in np6], np.median),
        "np6_p95_ms": _np6([r["ours_p95_ms"] for r in np6], np.max),
        "np6_max_ms": _np6([r["ours_max_ms"] for r in np6], np.max),
        "np6_step_median_ms": float(np.median(s6)) if s6.size else None,
        "np6_step_p99_ms": float(np.percentile(s6, 99)) if s6.size else None,
        "np6_non_solver_share": _np6([r["non_solver_share"] for r in np6], np.median),
        "np6_step_over_solve": _np6([r["step_over_solve"] for r in np6], np.median),
        "np6_ref_median_ms": _np6([r["ref_median_ms"] for r in np6], np.median),
        "np6_speedup_vs_ipopt_default": (
            float(np.median([r["ref_median_ms"] for r in np6]) / np.median([r["ours_median_ms"] for r in np6]))
            if np6
            else None
        ),
        "max_rel_cost_diff": float(np.nanmax([r["max_rel_cost_diff"] for r in rows])),
        "max_rel_cost_excess": float(np.nanmax([r["max_rel_cost_excess"] for r in rows])),
        "n_steps_rel_cost_diff_gt_1e-4": int(sum(r["n_rel_cost_diff_gt_1e-4"] for r in rows)),
        "n_steps": int(sum(r["steps"] for r in rows)),
        "failures": int(sum(r["failures"] for r in rows)),
        "solver": (args.method + "-warm-" + args.transcription)
        + ("+jit" if args.jit else "")
        + ("+codegen" if codegen and args.method != "fatrop" else ""),
        "np6_solver": sorted({f"{r['solver']}/{r['transcription']}" for r in np6}),
        "n_ipopt_fallbacks": int(sum(r["n_ipopt_fallbacks"] for r in rows)),
        "accepted_iterates": int(sum(r["accepted_iterates"] for r in rows)),
        "cpu_slowdown": args.cpu_slowdown,
        "prepare": not args.no_prepare,
        "horizons": horizons,
        "strategies": strategies,
        "duration_s": duration,
        "load_1min": os.getloadavg()[0],
    }


def _node_case(strategy: str, duration_s, codegen: bool) -> dict:
    """One strategy's steps inside mpc_node (:func:`ceco_controller.bench_node.node_step_times`), printed."""
    from .bench_node import node_step_times

    r = node_step_times(strategy, duration_s=duration_s, codegen=codegen)
    step, solve = r["node_ms"][1:], r["solve_ms"][1:]  # (step 0: the cold first solve, as in the simulator's)
    cpu = {f"cpu_{k}": v for k, v in non_solver(r["node_cpu_ms"][1:], r["solve_cpu_ms"][1:]).items()}
    row = {
        "strategy": strategy,
        "steps": int(step.size),
        "node_median_ms": float(np.median(step)),
        "node_p99_ms": float(np.percentile(step, 99)),
        "node_cpu_median_ms": float(np.median(r["node_cpu_ms"][1:])),
        "node_cpu_p99_ms": float(np.percentile(r["node_cpu_ms"][1:], 99)),
        "solve_median_ms": float(np.median(solve)),
        "solve_cpu_median_ms": float(np.median(r["solve_cpu_ms"][1:])),
        "fallback_steps": int(np.sum(r["fallback"])),
        "max_command_diff_to_simulator": r["max_command_diff_to_simulator"],
        **non_solver(step, solve),
        **cpu,
        "load_1min": os.getloadavg()[0],
    }
    print(
        f"{strategy:10s} mpc_node step median {row['node_median_ms']:.3f} ms p99 {row['node_p99_ms']:.3f} "
        f"(p99/median {row['node_p99_ms'] / row['node_median_ms']:.1f}; CPU median {row['node_cpu_median_ms']:.3f} "
        f"p99 {row['node_cpu_p99_ms']:.3f}) | "
        f"solver median {row['solve_median_ms']:.3f} ms | step/solve {row['step_over_solve']:.2f}, not solver "
        f"{row['non_solver_median_ms']:.3f} ms = {100 * row['non_solver_share']:.0f} % | CPU: step "
        f"{row['node_cpu_median_ms']:.3f}, solver {row['solve_cpu_median_ms']:.3f} ms, step/solve "
        f"{row['cpu_step_over_solve']:.2f}, not solver {100 * row['cpu_non_solver_share']:.0f} % | commands equal "
        f"to the simulator's to {row['max_command_diff_to_simulator']:.1e} | fallbacks "
        f"{row['fallback_steps']} [load {row['load_1min']:.1f}]",
        flush=True,
    )
    return row


def _median_or_none(values) -> float | None:
    return float(np.median(values)) if len(values) else None


def _clean(v):
    if isinstance(v, float):
        return _json_float(round(v, 6))
    if isinstance(v, dict):
        return {k: _clean(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_clean(x) for x in v]
    return v


def build_parser() -> cli_flags.Parser:
    """The parser of ``ceco bench nmpc`` (``ceco bench plant`` has its own: :mod:`ceco_plant_sim.bench_plant`)."""
    ap = cli_flags.Parser(prog="ceco bench", description="solver benchmarks")
    ap.add_argument("what", choices=["nmpc", "plant"], help="benchmark to run (plant: ceco bench plant --help)")
    ap.add_argument("--quick", action="store_true", help="Np 6 and 12 only, first 200 s of SC03")
    ap.add_argument("--jit", action="store_true", help="compile the NLP functions with gcc (slow to build)")
    ap.add_argument(
        "--no-codegen",
        action="store_true",
        help="in-process NLP functions (default: compiled, cached, as solver.codegen: true)",
    )
    ap.add_argument(
        "--horizons",
        type=cli_flags.comma_list(cli_flags.horizon_steps),
        default=None,
        help="comma-separated horizons Np [steps], each in 1..60 as --horizon-steps (default 6,12,24,60; "
        "with --quick 6,12)",
    )
    cli_flags.add_strategy(
        ap,
        default=None,
        help_extra=f" (default: all; all here means the NMPC strategies {','.join(CECO_STRATEGIES)})",
        deprecated=("--strategies",),
    )
    cli_flags.add_duration(ap, default_text="the whole of SC03; with --quick 200")
    ap.add_argument(
        "--method",
        choices=list(SOLVER_NAMES),
        default=_DEFAULT.name,
        help="product solver (SolverSettings.name)",
    )
    ap.add_argument(
        "--transcription",
        choices=["auto", "single-shooting", "multiple-shooting"],
        default=_DEFAULT.transcription,
        help=f"product NLP transcription (default {_DEFAULT.transcription}); the reference is always multiple shooting",
    )
    ap.add_argument(
        "--cpu-slowdown",
        type=cli_flags.positive_float,
        default=1.0,
        help="divide every time budget of the main cases by this (an ECU that many times slower)",
    )
    ap.add_argument(
        "--slowdown-factors",
        type=cli_flags.comma_list(cli_flags.positive_float, allow_empty=True),
        default=[1.0, 10.0, 100.0],
        help="factors of the slow-down table (SC03, Np = 6); '' skips it",
    )
    ap.add_argument("--no-prepare", action="store_true", help="no first solve before the controller takes over")
    ap.add_argument(
        "--robustness", action="store_true", help="also run every benchmark scenario x preview fault and count failures"
    )
    ap.add_argument(
        "--rti-cases",
        action="store_true",
        help="also compare the bounded-cost mode with the full SQP on every benchmark scenario",
    )
    ap.add_argument(
        "--node",
        action="store_true",
        help="also time the whole step inside mpc_node (message in to command out) at Np = 6 "
        "(ceco_controller.bench_node; needs the built workspace)",
    )
    cli_flags.add_no_progress(ap)
    ap.add_argument("--progress", action="store_true", help=argparse.SUPPRESS)  # the old opt-in (deprecated)
    return ap


def parse_args(argv):
    """``ceco bench nmpc``'s arguments and what they resolve to: (args, horizons, strategies, duration [s] or None).

    ``--strategy all`` (or none given) is the NMPC strategies; the baseline named on its own is an error (it has no
    solver to time), never dropped without a word. Old names (``--strategies``, ``--duration``) say so; ``--progress``
    (the old opt-in) says that progress bars are now shown unless ``--no-progress``.
    """
    ap = build_parser()
    args = ap.parse_args(argv)
    if args.progress:
        print(
            "ceco bench: --progress is deprecated and goes in the next release: progress bars are shown by default "
            "(--no-progress hides them)",
            file=sys.stderr,
        )
    args.progress = not args.no_progress
    horizons = args.horizons or ([6, 12] if args.quick else [6, 12, 24, 60])
    if args.strategy is None or args.strategy == list(STRATEGIES):
        strategies = list(CECO_STRATEGIES)
    elif BASELINE_STRATEGY in args.strategy:
        ap.error(f"argument --strategy: {BASELINE_STRATEGY} has no solver to time: name NMPC strategies or all")
    else:
        strategies = list(args.strategy)
    duration = args.duration_s if args.duration_s is not None else (200.0 if args.quick else None)
    return args, horizons, strategies, duration


def main(argv=None) -> int:
    """CLI entry: ``nmpc`` (this module) or ``plant`` (:mod:`ceco_plant_sim.bench_plant`, its own flags)."""
    args_in = sys.argv[1:] if argv is None else list(argv)
    if args_in[:1] == ["plant"]:
        from ceco_plant_sim.bench_plant import main as bench_plant_main

        return bench_plant_main(args_in[1:])
    args, horizons, strategies, duration = parse_args(args_in)
    codegen = not args.no_codegen and not args.jit
    print(
        f"ceco bench nmpc: product solver {args.method}, transcription {args.transcription}"
        + (", compiled functions" if codegen and args.method != "fatrop" else ", in-process functions")
        + f", budgets / {args.cpu_slowdown:g}; load {os.getloadavg()[0]:.1f}",
        flush=True,
    )
    rows, steps = bench_nmpc(
        strategies,
        horizons,
        duration,
        jit=args.jit,
        progress=args.progress,
        codegen=codegen,
        method=args.method,
        transcription=args.transcription,
        cpu_slowdown=args.cpu_slowdown,
        prepare=not args.no_prepare,
    )
    summary = _summary(rows, steps, args, codegen, horizons, strategies, duration)
    summary["horizon_table"] = table = horizon_table(rows)
    _print_horizon_table(table)
    if args.node:
        print(f"whole step inside mpc_node (Np = 6, lockstep, SC03; load {os.getloadavg()[0]:.1f}):", flush=True)
        summary["node"] = node_rows = [
            _node_case(strat, duration, codegen and args.method != "fatrop") for strat in strategies
        ]
        summary["np6_node_step_median_ms"] = float(np.median([r["node_median_ms"] for r in node_rows]))
        summary["np6_node_step_p99_ms"] = float(np.max([r["node_p99_ms"] for r in node_rows]))
        summary["np6_node_over_solve"] = float(np.median([r["step_over_solve"] for r in node_rows]))
        summary["np6_node_non_solver_share"] = float(np.median([r["non_solver_share"] for r in node_rows]))
    factors = args.slowdown_factors
    if factors:
        print(f"slow-down table (SC03, Np = 6, budgets / factor; load {os.getloadavg()[0]:.1f}):", flush=True)
        table = slowdown_table(
            strategies,
            factors,
            duration_s=duration,
            codegen=codegen,
            prepare=not args.no_prepare,
            progress=args.progress,
        )
        summary["slowdown"] = [
            {
                "factor": f,
                "mode": mode,
                "budget_ms": next(r["budget_ms"] for r in table if r["factor"] == f),
                "steps": sum(r["steps"] for r in table if r["factor"] == f and r["mode"] == mode),
                "steps_nmpc": sum(r["nmpc"] for r in table if r["factor"] == f and r["mode"] == mode),
                "steps_shifted_plan": sum(r["shifted_plan"] for r in table if r["factor"] == f and r["mode"] == mode),
                "steps_acc_law": sum(r["acc_law"] for r in table if r["factor"] == f and r["mode"] == mode),
                "accepted_iterates": sum(
                    r["accepted_iterates"] for r in table if r["factor"] == f and r["mode"] == mode
                ),
                "step_p99_ms": max(r["step_p99_ms"] for r in table if r["factor"] == f and r["mode"] == mode),
                "max_cpu_past_deadline_ms": max(
                    r["max_cpu_past_deadline_ms"] for r in table if r["factor"] == f and r["mode"] == mode
                ),
                "rti_loss_median": _median_or_none(
                    [
                        r["rti_loss_median"]
                        for r in table
                        if r["factor"] == f and r["mode"] == mode and r["rti_loss_median"] is not None
                    ]
                ),
                "rti_loss_max": max(
                    (
                        r["rti_loss_max"]
                        for r in table
                        if r["factor"] == f and r["mode"] == mode and r["rti_loss_max"] is not None
                    ),
                    default=None,
                ),
                "dE_vs_full_1x_pct_max": max(
                    (r.get("dE_vs_full_1x_pct", 0.0) for r in table if r["factor"] == f and r["mode"] == mode),
                    default=None,
                ),
                "dI_pmv_vs_full_1x_pct_max": max(
                    (r.get("dI_pmv_vs_full_1x_pct", 0.0) for r in table if r["factor"] == f and r["mode"] == mode),
                    default=None,
                ),
            }
            for f in factors
            for mode in ("full", "rti")
        ]
        summary["slowdown_cases"] = table
    if args.rti_cases:
        print(f"bounded-cost mode on every benchmark scenario (budget 1x; load {os.getloadavg()[0]:.1f}):", flush=True)
        cases = []
        for name in BENCH_SCENARIOS:
            for r in slowdown_table(
                strategies, (1.0,), scenario=name, codegen=codegen, prepare=not args.no_prepare, progress=args.progress
            ):
                cases.append({"scenario": name, **r})
        summary["rti_cases"] = cases
    if args.robustness:
        print(f"robustness (every scenario x preview fault; load {os.getloadavg()[0]:.1f}):", flush=True)
        rob = robustness(strategies, codegen=codegen, progress=args.progress)
        summary["robustness"] = {
            "runs": len(rob),
            "steps": sum(r["steps"] for r in rob),
            "failures": sum(r["failures"] for r in rob),
            "retries": sum(r["retries"] for r in rob),
            "accepted_iterates": sum(r["accepted_iterates"] for r in rob),
        }
    summary["per_case"] = rows
    print(json.dumps(_clean(summary), allow_nan=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
