"""``ceco bench plant``: the simulator's plant step, today's implementation against the numeric and compiled paths.

Three evaluations of the simulator's plant step (``ScenarioPlant.step``: truth environment, PMV bounds,
the scored comfort at t_n, the plant over [t_n, t_n + dt), its report) are timed in the same run on the
same command sequence:

* ``reference``: the plant of commit 8546529 (:mod:`ceco_plant_sim.reference_plant`, frozen) with the
  numeric scored comfort: "today's implementation" of issue 19;
* ``python``: the plant's equations written once (:mod:`ceco_plant_sim.plant_equations`), numeric;
* ``compiled``: the same equations and comfort as generated C (:mod:`ceco_plant_sim.compiled_plant`).

The commands: one per control period of 5 s (the product's Ts), drawn uniformly in the actuator
ranges (blower 0.05-0.17 kg/s, set-point 3-10 degC) from ``--seed``, the same for every path. Printed
per scenario: the time per plant step of each path (the fastest of ``--repeat`` runs of ``--steps``
steps, after one untimed run), the ratios to the reference, and the largest relative difference of
every per-step series (plant outputs and scored comfort; per series over the run's largest magnitude)
of each path to the reference. ``--callgrind`` adds instruction counts per step under valgrind
(independent of the machine's load): the difference of two runs of different lengths, so the start-up
cancels. Last line: one JSON object.

This is a benchmark, not a test: wall-clock times depend on the machine and its load (printed,
``os.getloadavg``); only ratios measured in the same run compare.

    ceco bench plant [--scenarios sc03,udds] [--steps 600] [--repeat 3] [--seed 0] [--callgrind]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

from ceco_core import cli_flags
from ceco_core.contracts import MDOT_BL_MAX_KGPS, MDOT_BL_MIN_KGPS, T_EVAP_SP_MAX_C, T_EVAP_SP_MIN_C, AcInput
from ceco_core.scenario_types import ScenarioError
from ceco_v2x_preview.scenario import load_scenario

from .compiled_plant import PlantEvaluation
from .reference_plant import reference_scenario_plant
from .scenario_plant import ScenarioPlant

__all__ = ["PATHS", "NOT_IN_REFERENCE", "commands", "run_path", "series_difference", "bench_plant", "main"]

NOT_IN_REFERENCE = frozenset(
    {"out.recirc_share", "out.co2_cab_ppm", "out.m_co2_in_kg", "out.m_co2_out_kg", "out.m_co2_gen_kg"}
)
"""Series 8546529's plant does not have (issue 21's door and cabin CO2): compared between the Python and
the compiled paths only."""
PATHS = ("reference", "python", "compiled")
"""The timed evaluations, the reference first."""
HOLD_STEPS = 5
"""Plant steps a command is held (the control period 5 s over the plant step 1 s)."""


def commands(n_steps: int, seed: int) -> list[AcInput]:
    """``n_steps`` commands, a new uniform draw in the actuator ranges every :data:`HOLD_STEPS` steps."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(0, n_steps, HOLD_STEPS):
        u = AcInput(
            mdot_bl_kgps=float(rng.uniform(MDOT_BL_MIN_KGPS, MDOT_BL_MAX_KGPS)),
            t_evap_sp_c=float(rng.uniform(T_EVAP_SP_MIN_C, T_EVAP_SP_MAX_C)),
        )
        out.extend([u] * min(HOLD_STEPS, n_steps - k))
    return out


def _plant(path: str, scenario, plant_dt_s: float) -> ScenarioPlant:
    if path == "reference":
        return reference_scenario_plant(scenario, plant_dt_s)
    sp = ScenarioPlant(scenario, plant_dt_s, evaluation=PlantEvaluation(path))
    if path == "compiled" and not sp.compiled:
        raise RuntimeError("ceco bench plant: the compiled path could not be built (see the warning above)")
    return sp


def run_path(path: str, scenario, cmds: list[AcInput], plant_dt_s: float = 1.0) -> tuple[float, dict]:
    """Wall time of the steps [s] (construction excluded) and the per-step series of one path."""
    sp = _plant(path, scenario, plant_dt_s)
    t0 = time.perf_counter()
    recs = [sp.step(u) for u in cmds]
    dt = time.perf_counter() - t0
    return dt, _series(recs)


def _series(recs) -> dict:
    """Every plant output and scored comfort series of a run's records (``out.*``, ``comfort.*``)."""
    series: dict[str, list] = {}
    for r in recs:
        for k, v in dataclasses.asdict(r.out).items():
            series.setdefault(f"out.{k}", []).append(float(v))
        for k, v in dataclasses.asdict(r.comfort).items():
            series.setdefault(f"comfort.{k}", []).append(float(v))
    return {k: np.asarray(v) for k, v in series.items()}


def series_difference(got: dict, ref: dict, skip=frozenset()) -> tuple[float, str]:
    """The largest relative difference over every series but ``skip`` (per series over the reference's largest)."""
    worst, name = 0.0, ""
    for k, r in ref.items():
        if k in skip:
            continue
        scale = max(float(np.max(np.abs(r))), 1e-300)
        d = float(np.max(np.abs(got[k] - r))) / scale
        if not d <= worst:  # NaN counts as the worst
            worst, name = d, k
    return worst, name


def bench_plant(scenarios: list[str], steps: int, repeat: int, seed: int) -> list[dict]:
    """One row per scenario: seconds per step of every path (best of ``repeat``), ratios, differences."""
    rows = []
    for name in scenarios:
        sc = load_scenario(name)
        n = min(steps, int(sc.duration_s))
        cmds = commands(n, seed)
        best: dict[str, float] = {}
        series: dict[str, dict] = {}
        for path in PATHS:  # one untimed run: tables, tracing, compiling or loading, first-call effects
            _, series[path] = run_path(path, sc, cmds)
        for _ in range(repeat):
            for path in PATHS:
                dt, _ = run_path(path, sc, cmds)
                best[path] = min(best.get(path, float("inf")), dt / n)
        row = {"scenario": name, "steps": n, "load_1min": os.getloadavg()[0]}
        for path in PATHS:
            row[f"{path}_ms"] = best[path] * 1e3
            row[f"{path}_speedup"] = best["reference"] / best[path]
            if path != "reference":
                row[f"{path}_max_rel"], row[f"{path}_worst"] = series_difference(
                    series[path], series["reference"], NOT_IN_REFERENCE
                )
        # every series, the door and CO2 included: the compiled path against the Python evaluation
        row["compiled_vs_python_max_rel"], _ = series_difference(series["compiled"], series["python"])
        rows.append(row)
    return rows


def _callgrind_ir(path: str, scenario: str, steps: int, seed: int) -> int:
    """Instructions of ``steps`` plant steps of ``path`` (and the start-up) under callgrind."""
    with tempfile.TemporaryDirectory(prefix="ceco_cg_") as tmp:
        cmd = [
            "valgrind",
            "--tool=callgrind",
            "--trace-children=yes",  # the interpreter may re-execute itself (environment set-up)
            f"--callgrind-out-file={os.path.join(tmp, 'callgrind.%p.out')}",
            sys.executable,
            "-m",
            "ceco_plant_sim.bench_plant",
            "--one",
            path,
            "--scenarios",
            scenario,
            "--steps",
            str(steps),
            "--seed",
            str(seed),
        ]
        subprocess.run(cmd, check=True, capture_output=True, text=True)
        total = None
        for name in sorted(os.listdir(tmp)):  # one file per executed image
            with open(os.path.join(tmp, name)) as f:
                for line in f:
                    if line.startswith(("summary:", "totals:")):
                        total = (total or 0) + int(line.split()[1])
                        break
    if total is None:
        raise RuntimeError("callgrind wrote no summary")
    return total


def callgrind_per_step(scenario: str, steps: int, seed: int) -> dict[str, float]:
    """Instructions per plant step of every path: (Ir(2 steps) - Ir(steps)) / steps, start-up cancelled."""
    return {
        p: (_callgrind_ir(p, scenario, 2 * steps, seed) - _callgrind_ir(p, scenario, steps, seed)) / steps
        for p in PATHS
    }


def main(argv=None) -> int:
    """CLI entry (``ceco bench plant``)."""
    ap = cli_flags.Parser(prog="ceco bench plant", description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenarios", default="sc03,udds", help="comma-separated scenario names (default sc03,udds)")
    ap.add_argument("--steps", type=int, default=600, help="plant steps per run (default 600; capped by the scenario)")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per path; the fastest counts (default 3)")
    ap.add_argument(
        "--seed", type=cli_flags.nonnegative_int, default=0, help="seed of the command sequence (default 0)"
    )
    ap.add_argument(
        "--callgrind",
        type=int,
        default=0,
        metavar="STEPS",
        help="also count instructions per step under valgrind (runs of STEPS and 2 STEPS steps, first scenario)",
    )
    ap.add_argument("--one", choices=PATHS, help=argparse.SUPPRESS)  # one untimed run (under callgrind)
    args = ap.parse_args(argv)
    if args.steps < 1 or args.repeat < 1 or args.callgrind < 0:
        ap.error("--steps and --repeat must be >= 1, --callgrind >= 0")
    scenarios = [s.strip() for s in args.scenarios.split(",") if s.strip()]
    if not scenarios:
        ap.error(f"argument --scenarios: expected comma-separated scenario names, got {args.scenarios!r}")
    for name in scenarios:  # an unknown name or a bad file: one line before anything runs
        try:
            load_scenario(name)
        except (ScenarioError, OSError) as exc:
            ap.error(f"argument --scenarios: {exc}")
    if args.one:
        sc = load_scenario(scenarios[0])
        sp = _plant(args.one, sc, 1.0)
        for u in commands(min(args.steps, int(sc.duration_s)), args.seed):  # the steps only, no records kept
            sp.step(u)
        return 0
    print(f"ceco bench plant: {args.steps} steps, best of {args.repeat}; load {os.getloadavg()[0]:.2f}", flush=True)
    rows = bench_plant(scenarios, args.steps, args.repeat, args.seed)
    print(
        f"{'scenario':14s} {'steps':>5s} {'ref ms':>8s} {'py ms':>8s} {'C ms':>8s} {'py x':>6s} {'C x':>6s} "
        f"{'py max rel':>10s} {'C max rel':>10s} {'load':>5s}"
    )
    for r in rows:
        print(
            f"{r['scenario']:14s} {r['steps']:5d} {r['reference_ms']:8.3f} {r['python_ms']:8.3f} "
            f"{r['compiled_ms']:8.3f} {r['python_speedup']:6.2f} {r['compiled_speedup']:6.1f} "
            f"{r['python_max_rel']:10.2e} {r['compiled_max_rel']:10.2e} {r['load_1min']:5.2f}"
        )
    summary = {"bench": "plant", "rows": rows, "load_1min_end": os.getloadavg()[0]}
    if args.callgrind:
        if shutil.which("valgrind") is None:
            print("--callgrind: valgrind not found; skipped", flush=True)
        else:
            ir = callgrind_per_step(scenarios[0], args.callgrind, args.seed)
            print(
                f"callgrind {scenarios[0]}: instructions per step "
                + ", ".join(f"{p} {v:.3g}" for p, v in ir.items())
                + f"; compiled x{ir['reference'] / ir['compiled']:.1f}, python x{ir['reference'] / ir['python']:.2f}"
            )
            summary["callgrind_ir_per_step"] = ir
    print(json.dumps(summary))
    ok = all(
        r["compiled_max_rel"] <= 1e-9 and r["python_max_rel"] <= 1e-9 and r["compiled_vs_python_max_rel"] <= 1e-9
        for r in rows
    )
    if not ok:
        print("ceco bench plant: a path differs from the reference by more than 1e-9 relative", flush=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
