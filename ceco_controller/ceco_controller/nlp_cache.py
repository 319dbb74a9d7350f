"""Key-on readiness of the NMPC: fill the compiled-NLP cache ahead of time and measure start-up.

``python -m ceco_controller.nlp_cache [--strategies ceco,ceco-ioch] [--horizons 6] [--fill] [--startup]``

* ``--fill``: build every strategy's controller with ``solver.codegen`` on, so each of its
  compiled objects (the SQP's functions, IPOPT's for the retry and the cold solves) is in the
  cache (``SolverSettings.codegen_cache_dir`` / $CECO_CACHE_DIR / ~/.cache/ceco); a deployment
  runs this once at install time, so no node ever compiles at key-on.
* ``--startup``: for each strategy and each of in-process and compiled (cache hit) functions, a
  fresh Python process is timed from its start to its first command: imports, NLP build
  (:attr:`NmpcController.build_time_s`), :meth:`~NmpcController.warm_up`,
  :meth:`~NmpcController.prepare` on the first observation and the first
  :meth:`~NmpcController.compute`. Printed per phase [ms]; last line one JSON object.

Times depend on the machine and its load (printed with ``os.getloadavg``); the 1.5 s key-on
budget of issue 12 is the reference.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

__all__ = ["fill_cache", "measure_startup", "main"]

_CHILD = r"""
import time
T0 = time.perf_counter()
import json, sys
from ceco_controller.factory import make_controller
from ceco_controller.nmpc import nominal_observation
from ceco_controller.strategies import SolverSettings
from ceco_v2x_preview.scenario import load_scenario
T1 = time.perf_counter()
strategy, horizon, codegen = sys.argv[1], int(sys.argv[2]), sys.argv[3] == "1"
import dataclasses
sc = load_scenario("sc03")
ctrl = make_controller(strategy, sc, 5.0, horizon, overrides={"solver": SolverSettings(codegen=codegen)})
T2 = time.perf_counter()
ctrl.warm_up()
T3 = time.perf_counter()
obs = nominal_observation(horizon + 1)
ctrl.prepare(obs)
T4 = time.perf_counter()
cmd, diag = ctrl.compute(obs)
T5 = time.perf_counter()
print(json.dumps({"import_ms": 1e3 * (T1 - T0), "build_ms": 1e3 * (T2 - T1), "nlp_build_ms": 1e3 * ctrl.build_time_s,
                  "warm_up_ms": 1e3 * (T3 - T2), "prepare_ms": 1e3 * (T4 - T3), "first_compute_ms": 1e3 * (T5 - T4),
                  "fallback": diag.fallback, "status": diag.status}))
"""


def fill_cache(strategies, horizons, config_path=None) -> list[dict]:
    """Build each controller with compiled functions (compiling what the cache lacks); return build times."""
    from ceco_v2x_preview.scenario import load_scenario

    from .factory import make_controller
    from .strategies import SolverSettings

    sc = load_scenario("sc03")
    rows = []
    for n in horizons:
        for s in strategies:
            t0 = time.perf_counter()
            ctrl = make_controller(
                s, sc, 5.0, n, config_path=config_path, overrides={"solver": SolverSettings(codegen=True)}
            )
            rows.append(
                {
                    "strategy": s,
                    "np": n,
                    "build_s": time.perf_counter() - t0,
                    "objects": sorted(
                        {
                            os.path.basename(str(v))
                            for v in list(ctrl.problem.compiled.values())
                            + list((ctrl.cold_path.problem.compiled if ctrl.cold_path else {}).values())
                            if v
                        }
                    ),
                }
            )
            print(
                f"{s:10s} Np={n:3d} built in {rows[-1]['build_s']:6.2f} s: {', '.join(rows[-1]['objects'])}", flush=True
            )
    return rows


def measure_startup(strategies, horizons, repeats: int = 1) -> list[dict]:
    """Time fresh processes from start to first command (see the module docstring)."""
    rows = []
    for n in horizons:
        for s in strategies:
            for codegen in (False, True):
                for _ in range(repeats):
                    t0 = time.perf_counter()
                    out = subprocess.run(
                        [sys.executable, "-c", _CHILD, s, str(n), "1" if codegen else "0"],
                        capture_output=True,
                        text=True,
                        timeout=600,
                        env=dict(os.environ),
                    )
                    wall = 1e3 * (time.perf_counter() - t0)
                    if out.returncode != 0:
                        raise RuntimeError(f"start-up child failed: {out.stderr[-2000:]}")
                    r = json.loads(out.stdout.strip().splitlines()[-1])
                    r.update(
                        {
                            "strategy": s,
                            "np": n,
                            "functions": "compiled" if codegen else "in-process",
                            "process_wall_ms": wall,
                            "load_1min": os.getloadavg()[0],
                        }
                    )
                    rows.append(r)
                    print(
                        f"{s:10s} Np={n:3d} {r['functions']:10s} process {wall:6.0f} ms = "
                        f"import {r['import_ms']:5.0f} + build {r['build_ms']:5.0f} (NLP {r['nlp_build_ms']:5.0f})"
                        f" + warm_up {r['warm_up_ms']:4.0f}"
                        f" + prepare {r['prepare_ms']:4.0f} + first compute {r['first_compute_ms']:4.1f} ms"
                        f" (+ interpreter start/exit); load {r['load_1min']:.1f}",
                        flush=True,
                    )
    return rows


def main(argv=None) -> int:
    """CLI (see the module docstring)."""
    from .strategies import CECO_STRATEGIES

    ap = argparse.ArgumentParser(prog="python -m ceco_controller.nlp_cache", description=__doc__.split("\n\n")[0])
    ap.add_argument("--strategies", default=",".join(CECO_STRATEGIES))
    ap.add_argument("--horizons", default="6")
    ap.add_argument("--config", default=None, help="controller settings file (default: config/controller.yaml)")
    ap.add_argument("--fill", action="store_true", help="compile what the cache lacks")
    ap.add_argument("--startup", action="store_true", help="time fresh processes to their first command")
    ap.add_argument("--repeats", type=int, default=1)
    args = ap.parse_args(argv)
    strategies, horizons = args.strategies.split(","), [int(h) for h in args.horizons.split(",")]
    out: dict = {}
    if args.fill or not args.startup:
        out["fill"] = fill_cache(strategies, horizons, args.config)
    if args.startup:
        out["startup"] = measure_startup(strategies, horizons, args.repeats)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
