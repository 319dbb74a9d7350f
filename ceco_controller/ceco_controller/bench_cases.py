"""Benchmark cases of ``ceco bench nmpc`` besides the solver comparison (:mod:`ceco_controller.bench`).

* :func:`timed_run`: one closed-loop run in which every control step is timed as a whole, from
  building the observation (what a node's message conversion is) to the returned command, and
  handed to ``compute`` as its ``t_start`` so the step deadline covers the same span.
* :func:`slowdown_table`: SC03 at a budget divided by 1, 10, 100 (an ECU that many times slower,
  emulated by scaling ``step_budget_s``, ``step_reserve_s`` and ``max_cpu_time_s``): steps under
  NMPC control with the full SQP and with the bounded-cost mode (one QP per step, ``rti``), and
  the bounded-cost mode's optimality loss against the full SQP solved on the same instances: per
  step, the NLP objective of the applied RTI plan (its comfort/T_evap slacks raised to
  feasibility, :func:`~ceco_controller.warmstart.repair_slacks`, so each 0.01 PMV of violation
  is priced at the exact-penalty weight, 10 kJ) against the converged optimum's, and the energy
  term alone; over the run, the closed-loop energy and comfort against the full SQP at 1x.
* :func:`robustness`: every benchmark scenario x strategy x preview fault, counting the steps in
  which the NMPC had no usable solution (``failures``), IPOPT retries and accepted iterates.

Benchmarks, not tests: wall-clock numbers depend on the machine and its load.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import time

import numpy as np

from ceco_v2x_preview.preview import parse_quality
from ceco_v2x_preview.scenario import load_scenario

from . import closed_loop as cl
from .strategies import SolverSettings
from .warmstart import repair_slacks

__all__ = ["timed_run", "slowdown_table", "robustness", "budget_settings", "BENCH_SCENARIOS", "PREVIEW_FAULTS"]

BENCH_SCENARIOS = ("sc03", "sc03_mild", "udds", "hwfet", "us06", "sc03_hotsoak")
"""The benchmark scenarios."""

PREVIEW_FAULTS = ("perfect", "noisy", "delayed:30", "missing:100-250,policy=drop")
"""Preview qualities of the robustness sweep (docs/results.md's preview cases)."""


def budget_settings(factor: float, **solver) -> SolverSettings:
    """Solver settings with every time budget divided by ``factor`` (an ECU ``factor`` times slower)."""
    base = SolverSettings()
    return SolverSettings(
        step_budget_s=base.step_budget_s / factor,
        step_reserve_s=base.step_reserve_s / factor,
        max_cpu_time_s=base.max_cpu_time_s / factor,
        **solver,
    )


@contextlib.contextmanager
def _timed_steps(ctrl, times: list, cpu_times: list, on_step=None, prepare: bool = True):
    orig_obs = cl.observation
    orig_compute = ctrl.compute
    state: dict = {"t0": None, "c0": None, "first": True}

    def observation(*args, **kwargs):
        state["t0"], state["c0"] = ctrl.clock(), time.thread_time()
        return orig_obs(*args, **kwargs)

    def compute(obs):
        if state["first"]:
            state["first"] = False
            if prepare and hasattr(ctrl, "prepare"):
                ctrl.prepare(obs)  # the node's first solve before it takes control: not a control step
                state["t0"], state["c0"] = ctrl.clock(), time.thread_time()
        cmd, diag = orig_compute(obs, t_start=state["t0"])
        times.append(1e3 * (ctrl.clock() - state["t0"]))
        cpu_times.append(1e3 * (time.thread_time() - state["c0"]))
        if on_step is not None:
            on_step(obs, cmd, diag)
        return cmd, diag

    cl.observation = observation
    ctrl.compute = compute
    try:
        yield
    finally:
        cl.observation = orig_obs
        del ctrl.compute


def timed_run(
    ctrl,
    scenario,
    strategy: str,
    settings: cl.SimSettings,
    on_step=None,
    prepare: bool = True,
    cpu_ms: list | None = None,
):
    """Simulate with ``ctrl``, timing each whole control step [ms]; returns ``(RunResult, step_ms)``.

    ``cpu_ms``: if given, receives each step's CPU time of this thread [ms] (wall minus it is the
    time the thread waited, e.g. preempted by other processes on a loaded machine).
    """
    times: list[float] = []
    cpu: list[float] = [] if cpu_ms is None else cpu_ms
    with _timed_steps(ctrl, times, cpu, on_step, prepare):
        res = cl.simulate(scenario, strategy, settings, controller=ctrl)
    return res, np.array(times)


def _control_counts(diags) -> dict:
    return {
        "steps": len(diags),
        "nmpc": sum(d.fallback == "" for d in diags),
        "shifted_plan": sum(d.fallback == "shifted_plan" for d in diags),
        "acc_law": sum(d.fallback == "baseline" for d in diags),
    }


def slowdown_table(
    strategies,
    factors=(1, 10, 100),
    scenario: str = "sc03",
    horizon: int = 6,
    duration_s=None,
    codegen: bool = True,
    prepare: bool = True,
    progress: bool = False,
) -> list[dict]:
    """One row per (factor, mode, strategy); see the module docstring."""
    sc = load_scenario(scenario)
    sim = cl.SimSettings(horizon_steps=horizon, duration_s=duration_s, progress=progress)
    rows, ref_metrics = [], {}
    for factor in factors:
        for mode in ("full", "rti"):
            for strat in strategies:
                ctrl = cl.make_controller(
                    strat,
                    sc,
                    sc.control.control_period_s,
                    horizon,
                    None,
                    {"solver": budget_settings(factor, rti=mode == "rti", codegen=codegen)},
                )
                full = ctrl.make_solver(dataclasses.replace(ctrl.settings.solver, rti=False)) if mode == "rti" else None
                losses: list[float] = []
                e_losses: list[float] = []

                def on_step(obs, cmd, diag, _ctrl=ctrl, _full=full, _losses=losses, _e=e_losses):
                    if _full is None or diag.status != "RTI_Step":
                        return
                    data, prob = _ctrl.last_nlp(), _ctrl.problem
                    w = repair_slacks(prob, _ctrl._good.w, data.p)  # the true cost of applying the RTI plan
                    ev = prob.evaluate(w, data.p)
                    j_rti = ev.J_e + ev.J_c + ev.J_i + ev.J_s + ev.J_du
                    ref = _full.solve(data)
                    if ref.success:
                        _losses.append((j_rti - ref.f) / max(abs(ref.f), 1e-9))
                        e_ref = prob.evaluate(ref.w, data.p).J_e
                        _e.append((ev.J_e - e_ref) / max(abs(e_ref), 1e-9))

                cpu: list[float] = []
                res, step_ms = timed_run(ctrl, sc, strat, sim, on_step, prepare, cpu)
                cpu_ms = np.array(cpu)
                deadline_ms = 1e3 * (ctrl.settings.solver.step_budget_s - ctrl.settings.solver.step_reserve_s)
                c = ctrl.counters
                m = res.metrics
                budget_ms = 1e3 * ctrl.settings.solver.step_budget_s
                row = {
                    "factor": factor,
                    "mode": mode,
                    "strategy": strat,
                    **_control_counts(res.diag_objects),
                    "converged": c.converged,
                    "accepted_iterates": c.accepted_iterates,
                    "rti_steps": c.rti_steps,
                    "retries": c.retries,
                    "cold_solves": c.cold_solves,
                    "deadline_hits": c.deadline_hits,
                    "budget_ms": budget_ms,
                    "step_median_ms": float(np.median(step_ms)),
                    "step_p99_ms": float(np.percentile(step_ms, 99)),
                    "step_max_ms": float(np.max(step_ms)),
                    "overruns": int(np.sum(step_ms > budget_ms)),
                    "max_past_deadline_ms": float(np.max(step_ms) - deadline_ms),
                    "step_cpu_max_ms": float(np.max(cpu_ms)),
                    "max_cpu_past_deadline_ms": float(np.max(cpu_ms) - deadline_ms),
                    "E_tot_kWh": m["E_tot_kWh"],
                    "I_pmv": m["I_pmv"],
                    "rti_loss_median": float(np.median(losses)) if losses else None,
                    "rti_loss_max": float(np.max(losses)) if losses else None,
                    "rti_loss_n": len(losses),
                    "rti_energy_term_diff_median": float(np.median(e_losses)) if e_losses else None,
                    "rti_energy_term_diff_max_abs": float(np.max(np.abs(e_losses))) if e_losses else None,
                }
                if factor == factors[0] and mode == "full":
                    ref_metrics[strat] = m
                ref = ref_metrics.get(strat)
                if ref is not None:
                    row["dE_vs_full_1x_pct"] = 100.0 * (m["E_tot_kWh"] / ref["E_tot_kWh"] - 1.0)
                    row["dI_pmv_vs_full_1x_pct"] = 100.0 * (m["I_pmv"] / ref["I_pmv"] - 1.0)
                rows.append(row)
                loss = (
                    f"RTI loss median {row['rti_loss_median']:.1e} max {row['rti_loss_max']:.1e} ({len(losses)}); "
                    f"energy term median {row['rti_energy_term_diff_median']:+.1e} "
                    f"max |.| {row['rti_energy_term_diff_max_abs']:.1e}"
                    if losses
                    else ""
                )
                print(
                    f"{factor:4g}x {mode:4s} {strat:10s} budget {budget_ms:7.1f} ms: NMPC {row['nmpc']:3d}/"
                    f"{row['steps']} (converged {c.converged}, iterates {c.accepted_iterates}, rti {c.rti_steps}), "
                    f"shifted {row['shifted_plan']}, ACC {row['acc_law']}; step median {row['step_median_ms']:.2f}"
                    f" p99 {row['step_p99_ms']:.2f} max {row['step_max_ms']:.2f} ms, overruns {row['overruns']} "
                    f"(max {row['max_past_deadline_ms']:+.2f} ms past the deadline, CPU time "
                    f"{row['max_cpu_past_deadline_ms']:+.2f} ms); "
                    f"dE {row.get('dE_vs_full_1x_pct', 0.0):+.3f} % "
                    f"dI_pmv {row.get('dI_pmv_vs_full_1x_pct', 0.0):+.3f} %"
                    f"  {loss}",
                    flush=True,
                )
    return rows


def robustness(
    strategies,
    scenarios=BENCH_SCENARIOS,
    qualities=PREVIEW_FAULTS,
    rti: bool = False,
    codegen: bool = False,
    progress: bool = False,
) -> list[dict]:
    """One row per (scenario, preview quality, strategy): control counts and the solve chain's counters."""
    rows = []
    for name in scenarios:
        sc = load_scenario(name)
        for q in qualities:
            for strat in strategies:
                ctrl = cl.make_controller(
                    strat,
                    sc,
                    sc.control.control_period_s,
                    sc.control.horizon_steps,
                    None,
                    {"solver": SolverSettings(rti=rti, codegen=codegen)},
                )
                res = cl.simulate(
                    sc, strat, cl.SimSettings(preview_quality=parse_quality(q), progress=progress), controller=ctrl
                )
                c = ctrl.counters
                counts = _control_counts(res.diag_objects)
                row = {
                    "scenario": name,
                    "preview": q,
                    "strategy": strat,
                    **counts,
                    "failures": counts["steps"] - counts["nmpc"],
                    "retries": c.retries,
                    "accepted_iterates": c.accepted_iterates,
                    "cold_solves": c.cold_solves,
                    "invalid_observations": c.invalid_observations,
                    "E_tot_kWh": res.metrics["E_tot_kWh"],
                    "I_pmv": res.metrics["I_pmv"],
                }
                rows.append(row)
                print(
                    f"{name:13s} {q:28s} {strat:10s} steps {row['steps']:4d} failures {row['failures']} "
                    f"(shifted {row['shifted_plan']}, ACC {row['acc_law']}) retries {c.retries} "
                    f"iterates {c.accepted_iterates} cold {c.cold_solves}  E {row['E_tot_kWh']:.4f} kWh "
                    f"I_pmv {row['I_pmv']:.1f}; load {os.getloadavg()[0]:.1f}",
                    flush=True,
                )
    return rows
