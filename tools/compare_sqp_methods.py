"""ceco's dense SQP against CasADi's sqpmethod (the solver it replaced) on the same recorded instances.

For each strategy, a closed-loop SC03 run (product settings) records every warm NLP instance (the
shifted primal-dual start and the parameters). Each instance is then solved, interleaved, by

* ``sqp``            ceco's SQP (exact eigendecomposition per Hessian block), in-process functions;
* ``sqpmethod-10k``  CasADi's sqpmethod as shipped before (eigen-clip, ``max_iter_eig`` 10 000,
                     dense qpOASES, same tolerances), in-process functions;
* ``sqpmethod-200``  the same with CasADi's default ``max_iter_eig`` (200);
* ``ipopt-default``  IPOPT with its defaults from the same start (the time reference of the run).

Printed per strategy and solver: failures (including sqpmethod's ``stats()`` raising), median
iterations, median time and its ratio to the reference's median in the same run, and the largest
relative cost difference to ``sqp``. A benchmark, not a test (times depend on the load, printed).

    python tools/compare_sqp_methods.py [--strategies ceco,ceco-c] [--duration 600]
"""

from __future__ import annotations

import argparse
import os
import time

import casadi
import numpy as np

from ceco_controller import closed_loop as cl
from ceco_controller.codegen import stdout_silenced


def _sqpmethod(nlp, max_iter_eig: int):
    opts = {
        "print_time": False,
        "qpsol": "qpoases",
        "qpsol_options": {"printLevel": "none", "sparse": False, "error_on_fail": False, "CPUtime": 0.05},
        "max_iter": 20,
        "print_iteration": False,
        "print_header": False,
        "print_status": False,
        "tol_pr": 1e-6,
        "tol_du": 1e-4,
        "convexify_strategy": "eigen-clip",
        "max_iter_eig": float(max_iter_eig),
        "error_on_fail": False,
    }
    with stdout_silenced():
        return casadi.nlpsol("old", "sqpmethod", nlp, opts)


def _casadi_solve(fn, data, bounds):
    args = {"x0": data.x0, "p": data.p, **bounds}
    if data.lam_g0 is not None:
        args.update(lam_x0=data.lam_x0, lam_g0=data.lam_g0)
    t0 = time.perf_counter()
    sol = fn(**args)
    dt = 1e3 * (time.perf_counter() - t0)
    try:
        st = fn.stats()
        ok, it = bool(st["success"]), st.get("iter_count", np.nan)
    except RuntimeError:  # sqpmethod after an eigen-decomposition failure in iteration 0
        ok, it = False, np.nan
    return ok, float(sol["f"]), it, dt


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--strategies", default="ceco,ceco-e,ceco-c,ceco-ioch")
    ap.add_argument("--duration", type=float, default=None, help="run length [s] (default: whole SC03)")
    args = ap.parse_args()
    print(f"load {os.getloadavg()}")
    for strat in args.strategies.split(","):
        ctrl = cl.make_controller(strat, cl.load_scenario("sc03"), 5.0, 6)
        recorded = []
        orig = ctrl.compute

        def compute(obs, _orig=orig, _ctrl=ctrl, _rec=recorded):
            out = _orig(obs)
            data = _ctrl.last_nlp()
            if data is not None and data.lam_g0 is not None:
                _rec.append(data)
            return out

        ctrl.compute = compute
        cl.simulate("sc03", strat, cl.SimSettings(progress=False, duration_s=args.duration), controller=ctrl)
        prob = ctrl.problem
        ref = casadi.nlpsol("ref", "ipopt", prob.nlp, {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes"}})
        solvers = {
            "sqp": None,
            "sqpmethod-10k": _sqpmethod(prob.nlp, 10000),
            "sqpmethod-200": _sqpmethod(prob.nlp, 200),
            "ipopt-default": ref,
        }
        res = {k: [] for k in solvers}
        for data in recorded:
            for name, fn in solvers.items():
                if fn is None:
                    t0 = time.perf_counter()
                    r = ctrl.solver.solve(data)
                    res[name].append((r.success, r.f, r.iterations, 1e3 * (time.perf_counter() - t0)))
                elif name == "ipopt-default":
                    res[name].append(_casadi_solve(fn, type(data)(p=data.p, x0=data.x0), prob.bounds_dm))
                else:
                    res[name].append(_casadi_solve(fn, data, prob.bounds_dm))
        t_ref = np.median([x[3] for x in res["ipopt-default"]])
        f_sqp = np.array([x[1] for x in res["sqp"]])
        for name, rows in res.items():
            ok = np.array([x[0] for x in rows])
            f = np.array([x[1] for x in rows])
            both = ok & np.array([x[0] for x in res["sqp"]])
            dc = np.max(np.abs(f[both] - f_sqp[both]) / np.abs(f_sqp[both])) if both.any() else np.nan
            t = np.median([x[3] for x in rows])
            its = [x[2] for x in rows if x[2] == x[2]]
            print(
                f"{strat:10s} {name:14s} instances {len(rows):4d} failures {int(np.sum(~ok)):4d}  iterations median "
                f"{(np.median(its) if its else np.nan):4.0f}  time median {t:6.2f} ms = {t / t_ref:5.3f} x IPOPT "
                f"default  max rel cost diff to sqp {dc:.1e}",
                flush=True,
            )
    print(f"load {os.getloadavg()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
