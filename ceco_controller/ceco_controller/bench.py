"""``ceco bench nmpc``: NMPC solve times in closed loop against a reference solver.

For each CECO strategy and horizon Np in (6, 12, 24, 60), a closed-loop SC03
run is simulated with the product solver settings. At every control step the
very same NLP instance (same parameters) is also solved by the reference:
CasADi + IPOPT with its default settings and no warm start (what the paper's
MPCTools did), started from the same model-rollout guess a cold solve gets.
Printed: per-step solve time (median, p95, max) of both, the speed-up of the
medians, and the largest relative difference of the optimal costs over the
steps where both solvers report success, with its sign (the NLP is
non-convex: during the pull-down the two solvers can end in different local
optima; ``max_rel_cost_excess`` is how much *worse* the product's optimum was).
Last line: one JSON object.

This is a benchmark, not a test: wall-clock times depend on the machine and
its load (2 shared cores here); nothing in the controller uses them.

    python -m ceco_controller.bench nmpc [--quick] [--jit | --no-codegen] [--horizons 6,12] [--strategies ceco,ceco-c]
                                         [--method auto|ipopt|sqpmethod|fatrop]
                                         [--transcription auto|single-shooting|multiple-shooting]

``--method`` / ``--transcription`` pick the product solver and NLP transcription
(``SolverSettings.name`` / ``.transcription``; default: the controller's defaults, 'auto':
SQP on the single-shooting NLP up to Np = 12, warm IPOPT on the multiple-shooting NLP beyond).
sqpmethod/fatrop run with their IPOPT fallback: a failed warm solve is retried with warm IPOPT,
and its time counts in the product's; the number of retries is printed (``ipopt fallbacks``).

The reference is always the multiple-shooting NLP (MPCTools' transcription) with IPOPT's
defaults. When the product's NLP is the single-shooting one, IPOPT's defaults on that NLP are
timed as well (``ref_same_nlp_median_ms``), so the speed-up can be read against either
formulation.

The product solver runs with ``codegen`` (compiled NLP functions from the on-disk
cache; the first run compiles each NLP once). The reference always uses the
in-process functions, as MPCTools did.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from ceco_v2x_preview.scenario import load_scenario

from . import closed_loop as cl
from . import model as cm
from .solvers import NlpData
from .strategies import CECO_STRATEGIES, SolverSettings

__all__ = ["main", "bench_nmpc"]


def _stats(x):
    x = np.asarray(x, float)
    if x.size == 0:
        return {"median": float("nan"), "p95": float("nan"), "max": float("nan")}
    return {"median": float(np.median(x)), "p95": float(np.percentile(x, 95)), "max": float(np.max(x))}


def _json_float(v: float) -> float | None:
    """NaN (a statistic with no sample, e.g. no same-NLP reference) as JSON null, not the invalid NaN."""
    return None if v != v else v


def bench_nmpc(strategies, horizons, duration_s=None, jit=False, scenario="sc03", progress=False,
               codegen=True, method=SolverSettings().name,
               transcription=SolverSettings().transcription) -> list[dict]:
    """Run the benchmark; return one dict per (strategy, horizon)."""
    sc = load_scenario(scenario)
    mp = cm.load_params()
    rows = []
    for np_ in horizons:
        for strat in strategies:
            overrides = {"solver": SolverSettings(name=method, jit=jit, codegen=codegen and not jit,
                                                  transcription=transcription)}
            ctrl = cl.make_controller(strat, sc, sc.control.control_period_s, np_, mp, overrides)
            # the reference: MPCTools' transcription (multiple shooting), IPOPT defaults, in-process functions
            ref_ctrl = cl.make_controller(strat, sc, sc.control.control_period_s, np_, mp, {
                "solver": SolverSettings(name="ipopt", default_options=True, transcription="multiple-shooting")})
            # and, if the product's transcription differs, IPOPT defaults on the product's own NLP
            same_solver = (ctrl.make_solver(SolverSettings(name="ipopt", default_options=True))
                           if ctrl.transcription != "multiple-shooting" else None)
            ours_t, ref_t, diffs, sdiffs, ours_it, ref_it, same_t = [], [], [], [], [], [], []
            n_fail = n_ref_fail = n_same_fail = 0
            orig = ctrl.compute

            def compute(obs, _orig=orig, _ctrl=ctrl):
                nonlocal n_fail, n_ref_fail, n_same_fail
                cmd, diag = _orig(obs)
                data = _ctrl.last_nlp()
                if diag.solve_time_ms is not None:
                    ours_t.append(diag.solve_time_ms)
                    ours_it.append(diag.iterations)
                if not diag.success:
                    n_fail += 1
                # the reference solves the same instance from the cold model-rollout guess
                ref = ref_ctrl.solve_nlp(NlpData(p=data.p, x0=ref_ctrl.initial_guess(data.p)), ref_ctrl.solver)
                if same_solver is not None:
                    same = _ctrl.solve_nlp(NlpData(p=data.p, x0=_ctrl.initial_guess(data.p)), same_solver)
                    same_t.append(same.time_ms)
                    n_same_fail += not same.success
                ref_t.append(ref.time_ms)
                ref_it.append(ref.iterations)
                if not ref.success:
                    n_ref_fail += 1
                if ref.success and diag.success and diag.cost_total is not None:
                    sdiffs.append((diag.cost_total - ref.f) / max(abs(ref.f), 1e-9))
                    diffs.append(abs(sdiffs[-1]))
                return cmd, diag

            ctrl.compute = compute
            cl.simulate(sc, strat, cl.SimSettings(horizon_steps=np_, duration_s=duration_s, progress=progress),
                        controller=ctrl)
            o, r, sm = _stats(ours_t), _stats(ref_t), _stats(same_t)
            rows.append({"strategy": strat, "np": np_, "solver": ctrl.settings.solver.name,
                         "transcription": ctrl.transcription, "steps": len(ours_t),
                         "ours_median_ms": o["median"], "ours_p95_ms": o["p95"], "ours_max_ms": o["max"],
                         "ours_iter_median": float(np.median(ours_it)) if ours_it else float("nan"),
                         "ref_median_ms": r["median"], "ref_p95_ms": r["p95"], "ref_max_ms": r["max"],
                         "ref_iter_median": float(np.median(ref_it)) if ref_it else float("nan"),
                         "ref_same_nlp_median_ms": sm["median"],
                         "speedup_median": r["median"] / o["median"] if o["median"] > 0 else float("nan"),
                         "max_rel_cost_diff": max(diffs) if diffs else float("nan"),
                         "max_rel_cost_excess": max(max(sdiffs), 0.0) if sdiffs else float("nan"),
                         "n_rel_cost_diff_gt_1e-4": int(sum(d > 1e-4 for d in diffs)),
                         "n_fail": n_fail, "n_ref_fail": n_ref_fail, "n_ref_same_nlp_fail": n_same_fail,
                         "n_ipopt_fallbacks": ctrl.n_ipopt_fallbacks})
            rr = rows[-1]
            print(f"{strat:10s} Np={np_:3d} steps={rr['steps']:4d}  ours median {rr['ours_median_ms']:7.2f} ms "
                  f"p95 {rr['ours_p95_ms']:7.2f} max {rr['ours_max_ms']:7.2f} (it {rr['ours_iter_median']:.0f})  |  "
                  f"IPOPT default median {rr['ref_median_ms']:7.2f} p95 {rr['ref_p95_ms']:7.2f} "
                  f"max {rr['ref_max_ms']:7.2f} (it {rr['ref_iter_median']:.0f})"
                  + (f" [on our NLP: median {rr['ref_same_nlp_median_ms']:.2f}]" if same_t else "")
                  + f"  speed-up "
                  f"{rr['speedup_median']:5.1f}x  max rel cost diff {rr['max_rel_cost_diff']:.1e} "
                  f"(ours higher by <= {rr['max_rel_cost_excess']:.1e}; {rr['n_rel_cost_diff_gt_1e-4']} steps > 1e-4)  "
                  f"fails {n_fail}/{n_ref_fail}  [{rr['solver']}, {rr['transcription']}; "
                  f"ipopt fallbacks {ctrl.n_ipopt_fallbacks}]", flush=True)
    return rows


def main(argv=None) -> int:
    """CLI entry: ``nmpc`` is the only benchmark."""
    ap = argparse.ArgumentParser(prog="ceco bench", description="solver benchmarks")
    ap.add_argument("what", choices=["nmpc"], help="benchmark to run")
    ap.add_argument("--quick", action="store_true", help="Np 6 and 12 only, first 200 s of SC03")
    ap.add_argument("--jit", action="store_true", help="compile the NLP functions with gcc (slow to build)")
    ap.add_argument("--no-codegen", action="store_true",
                    help="in-process NLP functions (default: compiled, cached, as solver.codegen: true)")
    ap.add_argument("--horizons", default=None, help="comma-separated horizons (default 6,12,24,60)")
    ap.add_argument("--strategies", default=None, help=f"comma-separated subset of {','.join(CECO_STRATEGIES)}")
    ap.add_argument("--duration", type=float, default=None, help="run length [s] (default: whole SC03)")
    ap.add_argument("--method", choices=["auto", "ipopt", "sqpmethod", "fatrop"], default=SolverSettings().name,
                    help=f"product solver (SolverSettings.name; default {SolverSettings().name})")
    ap.add_argument("--transcription", choices=["auto", "single-shooting", "multiple-shooting"],
                    default=SolverSettings().transcription,
                    help=f"product NLP transcription (default {SolverSettings().transcription}); the reference is "
                         "always multiple shooting")
    ap.add_argument("--progress", action="store_true", help="show progress bars")
    args = ap.parse_args(argv)
    horizons = [int(h) for h in args.horizons.split(",")] if args.horizons else ([6, 12] if args.quick
                                                                                 else [6, 12, 24, 60])
    strategies = args.strategies.split(",") if args.strategies else list(CECO_STRATEGIES)
    duration = args.duration if args.duration is not None else (200.0 if args.quick else None)
    codegen = not args.no_codegen and not args.jit
    print(f"ceco bench nmpc: product solver {args.method}, transcription {args.transcription}"
          + (", compiled functions" if codegen and args.method != "fatrop" else ", in-process functions"), flush=True)
    rows = bench_nmpc(strategies, horizons, duration, jit=args.jit, progress=args.progress, codegen=codegen,
                      method=args.method, transcription=args.transcription)
    # The np6_* keys summarise Np = 6 only; without an Np = 6 run they are null
    # (never the numbers of another horizon under the np6 name).
    np6 = [r for r in rows if r["np"] == 6]

    def _np6(values, reduce):
        return float(reduce(values)) if np6 else None

    summary = {
        "np6_median_ms": _np6([r["ours_median_ms"] for r in np6], np.median),
        "np6_p95_ms": _np6([r["ours_p95_ms"] for r in np6], np.max),
        "np6_max_ms": _np6([r["ours_max_ms"] for r in np6], np.max),
        "np6_ref_median_ms": _np6([r["ref_median_ms"] for r in np6], np.median),
        "np6_speedup_vs_ipopt_default": (float(np.median([r["ref_median_ms"] for r in np6])
                                               / np.median([r["ours_median_ms"] for r in np6])) if np6 else None),
        "max_rel_cost_diff": float(np.nanmax([r["max_rel_cost_diff"] for r in rows])),
        "max_rel_cost_excess": float(np.nanmax([r["max_rel_cost_excess"] for r in rows])),
        "n_steps_rel_cost_diff_gt_1e-4": int(sum(r["n_rel_cost_diff_gt_1e-4"] for r in rows)),
        "n_steps": int(sum(r["steps"] for r in rows)),
        "solver": (args.method + "-warm-" + args.transcription) + ("+jit" if args.jit else "")
                  + ("+codegen" if codegen and args.method != "fatrop" else ""),
        "np6_solver": sorted({f"{r['solver']}/{r['transcription']}" for r in np6}),
        "n_ipopt_fallbacks": int(sum(r["n_ipopt_fallbacks"] for r in rows)),
        "horizons": horizons,
        "strategies": strategies,
        "duration_s": duration,
        "per_case": [{k: (_json_float(round(v, 4)) if isinstance(v, float) else v) for k, v in r.items()}
                     for r in rows],
    }
    summary = {k: (_json_float(v) if isinstance(v, float) else v) for k, v in summary.items()}
    print(json.dumps(summary, allow_nan=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
