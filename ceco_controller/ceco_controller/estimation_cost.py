"""The closed-loop cost of estimation.

Every benchmark case and strategy with full state and with vehicle measurements
(``SimSettings.measurements``), in-process.

For each case and strategy: energy E_tot [kWh], I_PMV [s], thermal discomfort [PMV h] (time
integral of the distance of PMV outside the ISO 7730 category B band [-0.5, 0.5], PMV clipped to
+-3: ``ceco_core.kpis.pmv_band_distance``, the benchmark's ``discomfort_pmvh``), the
OTC violation in the comfort-zone phase [%] and, in vehicle mode, the RMSE of the estimated
interior and shell temperatures against the plant truth [K] (whole run and from 120 s on).
Optionally (``--naive``) a third mode without an estimator, T_int = T_shell = T_cab (what the NMPC
would get from a car's sensors with no estimator), to show what the estimator buys.

Sensor offsets (``--offsets``): the vehicle mode with a constant offset on one sensor (what the
sensors' tolerance allows), with the default estimator and with the vent-offset state switched off
(``EstimatorSettings.vent_bias_std_k`` ~ 0), to show why the filter carries that state.

CLI::

    python -m ceco_controller.estimation_cost --out runs/estimation_cost.json [--naive]
    python -m ceco_controller.estimation_cost --cases sc03 --strategies ceco,ceco-ioch \
        --offsets t_vent_c+0.5,t_vent_c-0.5,t_cab_c+0.3 --out runs/estimation_offsets.json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import pathlib
import sys
import time

import numpy as np

from ceco_core import kpis
from ceco_core.kpis import pmv_band_distance

from . import estimator as est
from .closed_loop import SimSettings, simulate
from .estimating_controller import EstimatingController
from .strategies import STRATEGIES

__all__ = [
    "CASES",
    "NaiveVehicleController",
    "SensorOffsetController",
    "discomfort_pmvh",
    "estimation_cost",
    "offset_study",
    "markdown_table",
    "offset_table",
    "main",
]

NO_VENT_OFFSET_STATE = est.EstimatorSettings(vent_bias_std_k=1e-4, vent_bias_drift_k=1e-6)
"""The estimator without its vent-offset state (prior std 1e-4 K, drift 1e-6 K per step)."""

CASES = ("sc03", "sc03_mild", "udds", "hwfet", "us06", "sc03_hotsoak")
"""The benchmark cases (bundled scenarios)."""


def discomfort_pmvh(t_s, pmv) -> float:
    """Time integral of the distance of PMV outside [-0.5, 0.5] (PMV clipped to +-3) [PMV h].

    :func:`ceco_core.kpis.discomfort_pmvh` on the run's uniform series.
    """
    t = np.asarray(t_s, float)
    return kpis.discomfort_pmvh(pmv_band_distance(pmv), float(t[1] - t[0]))


class NaiveVehicleController:
    """No estimator: the wrapped controller gets T_int = T_shell = the measured cabin air temperature."""

    def __init__(self, inner):
        self.inner = inner

    def reset(self) -> None:
        """Reset the wrapped controller."""
        self.inner.reset()

    def compute(self, obs):
        """One control step with the interior and shell temperatures replaced by T_cab."""
        return self.inner.compute(dataclasses.replace(obs, t_int_c=obs.t_cab_c, t_shell_c=obs.t_cab_c))


class SensorOffsetController(EstimatingController):
    """The vehicle mode with constant offsets added to the sensors of every observation (fault study)."""

    def __init__(self, inner, estimator: est.CabinStateEstimator, offsets: dict):
        super().__init__(inner, estimator)
        self.offsets = dict(offsets)
        """Sensor name (a field of the observation) -> offset [its unit]."""

    def estimated_observation(self, obs):
        """The observation with the offsets applied, then the estimator."""
        shifted = {k: getattr(obs, k) + v for k, v in self.offsets.items()}
        return super().estimated_observation(dataclasses.replace(obs, **shifted))


def _parse_offset(text: str) -> tuple[str, float]:
    for i in range(len(text) - 1, 0, -1):
        if text[i] in "+-":
            return text[:i], float(text[i:])
    raise ValueError(f"offset {text!r}: expected <sensor>+<value> or <sensor>-<value>, e.g. t_vent_c+0.5")


def offset_study(cases, strategies, offsets, progress=None) -> list[dict]:
    """Rows of the vehicle mode with each sensor offset, with and without the vent-offset state."""
    from ceco_v2x_preview.scenario import load_scenario

    from . import model as cm
    from .factory import make_controller

    rows = []
    for case in cases:
        sc = load_scenario(case)
        ts, n_p = sc.control.control_period_s, sc.control.horizon_steps
        for strategy in strategies:
            mp = cm.load_params()
            for text in offsets:
                sensor, off = _parse_offset(text)
                for label, settings in (("default", None), ("no vent-offset state", NO_VENT_OFFSET_STATE)):
                    t0 = time.perf_counter()
                    ctrl = SensorOffsetController(
                        make_controller(strategy, sc, ts, n_p, mp),
                        est.CabinStateEstimator(mp, settings=settings, control_period_s=ts),
                        {sensor: off},
                    )
                    res = simulate(case, strategy, SimSettings(progress=False), controller=ctrl)
                    row = _row(case, strategy, f"vehicle {text} ({label})", res, time.perf_counter() - t0)
                    row.update(offset=text, estimator=label)
                    rows.append(row)
                    if progress:
                        progress(row)
    return rows


def _row(case: str, strategy: str, mode: str, res, wall_s: float) -> dict:
    m, ts = res.metrics, res.timeseries
    row = {
        "case": case,
        "strategy": strategy,
        "mode": mode,
        "E_tot_kWh": m["E_tot_kWh"],
        "I_pmv": m["I_pmv"],
        "discomfort_pmvh": discomfort_pmvh(ts["t_s"], ts["pmv"]),
        "otc_violation_zone_pct": m["otc_violation_zone_pct"],
        "otc_violation_pct": m["otc_violation_pct"],
        "n_fallback": m["n_fallback_shifted"] + m["n_fallback_baseline"],
        "wall_s": wall_s,
    }
    for k in (
        "est_t_int_rmse_k",
        "est_t_shell_rmse_k",
        "est_t_glass_rmse_k",
        "est_t_int_rmse_late_k",
        "est_t_shell_rmse_late_k",
        "est_t_glass_rmse_late_k",
        "est_t_int_max_abs_k",
        "est_t_shell_max_abs_k",
        "est_t_glass_max_abs_k",
    ):
        row[k] = m.get(k)
    return row


def estimation_cost(cases=CASES, strategies=STRATEGIES, naive: bool = False, progress=None) -> list[dict]:
    """One row per case, strategy and mode ('full', 'vehicle', and 'naive' if asked)."""
    rows = []
    for case in cases:
        for strategy in strategies:
            modes = ("full", "vehicle") + (("naive",) if naive else ())
            for mode in modes:
                t0 = time.perf_counter()
                settings = SimSettings(progress=False, measurements="full" if mode == "naive" else mode)
                controller = None
                if mode == "naive":
                    from ceco_v2x_preview.scenario import load_scenario

                    from . import model as cm
                    from .factory import make_controller

                    sc = load_scenario(case)
                    mp = cm.load_params() if strategy != "baseline" else None
                    controller = NaiveVehicleController(
                        make_controller(strategy, sc, sc.control.control_period_s, sc.control.horizon_steps, mp)
                    )
                res = simulate(case, strategy, settings, controller=controller)
                rows.append(_row(case, strategy, mode, res, time.perf_counter() - t0))
                if progress:
                    progress(rows[-1])
    return rows


def _f(x, fmt: str = ".2f") -> str:
    return "–" if x is None else format(x, fmt)


def _pct(a: float, b: float) -> str:
    return f"{100.0 * (a - b) / b:+.1f}" if b else "n/a"


def markdown_table(rows: list[dict]) -> str:
    """The estimator table: per case and strategy, full vs vehicle (and naive), with the differences."""
    by = {(r["case"], r["strategy"], r["mode"]): r for r in rows}
    naive = any(r["mode"] == "naive" for r in rows)
    head = (
        "| case | strategy | E_tot full / vehicle [kWh] | ΔE [%] | I_PMV full / vehicle [s] | "
        "discomfort full / vehicle [PMV h] | zone violation full / vehicle [%] | "
        "RMSE T_int / T_shell / T_glass [K] (from 120 s) |"
        + (" naive: ΔE [%], discomfort [PMV h], zone violation [%] |" if naive else "")
    )
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    seen = []
    for r in rows:
        key = (r["case"], r["strategy"])
        if key in seen:
            continue
        seen.append(key)
        f, v = by.get(key + ("full",)), by.get(key + ("vehicle",))
        if f is None or v is None:
            continue
        cell = (
            f"| {key[0]} | {key[1]} | {f['E_tot_kWh']:.4f} / {v['E_tot_kWh']:.4f} | "
            f"{_pct(v['E_tot_kWh'], f['E_tot_kWh'])} | {f['I_pmv']:.0f} / {v['I_pmv']:.0f} | "
            f"{f['discomfort_pmvh']:.4f} / {v['discomfort_pmvh']:.4f} | "
            f"{f['otc_violation_zone_pct']:.1f} / {v['otc_violation_zone_pct']:.1f} | "
            f"{_f(v['est_t_int_rmse_k'])} / {_f(v['est_t_shell_rmse_k'])} / {_f(v['est_t_glass_rmse_k'])} "
            f"({_f(v['est_t_int_rmse_late_k'])} / {_f(v['est_t_shell_rmse_late_k'])} / "
            f"{_f(v['est_t_glass_rmse_late_k'])}) |"
        )
        n = by.get(key + ("naive",))
        if naive and n is not None:
            cell += (
                f" {_pct(n['E_tot_kWh'], f['E_tot_kWh'])}, {n['discomfort_pmvh']:.4f}, "
                f"{n['otc_violation_zone_pct']:.1f} |"
            )
        lines.append(cell)
    return "\n".join(lines)


def offset_table(rows: list[dict], reference: list[dict]) -> str:
    """Markdown table of :func:`offset_study` rows against the offset-free full and vehicle rows."""
    ref = {(r["case"], r["strategy"], r["mode"]): r for r in reference}
    lines = [
        "| case | strategy | sensor offset | estimator | ΔE vs full [%] | discomfort [PMV h] (full) | "
        "zone violation [%] | RMSE T_int / T_shell / T_glass [K] (from 120 s) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        f = ref.get((r["case"], r["strategy"], "full"))
        de = _pct(r["E_tot_kWh"], f["E_tot_kWh"]) if f else "n/a"
        dfull = f"{f['discomfort_pmvh']:.4f}" if f else "n/a"
        lines.append(
            f"| {r['case']} | {r['strategy']} | {r['offset']} | {r['estimator']} | {de} | "
            f"{r['discomfort_pmvh']:.4f} ({dfull}) | {r['otc_violation_zone_pct']:.1f} | "
            f"{_f(r['est_t_int_rmse_k'])} / {_f(r['est_t_shell_rmse_k'])} / {_f(r['est_t_glass_rmse_k'])} "
            f"({_f(r['est_t_int_rmse_late_k'])} / {_f(r['est_t_shell_rmse_late_k'])} / "
            f"{_f(r['est_t_glass_rmse_late_k'])}) |"
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    """CLI: run the study, print the Markdown table, write the rows as JSON."""
    ap = argparse.ArgumentParser(prog="python -m ceco_controller.estimation_cost", description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default=",".join(CASES), help="comma-separated scenarios")
    ap.add_argument("--strategies", default=",".join(STRATEGIES), help="comma-separated strategies")
    ap.add_argument("--naive", action="store_true", help="also run without an estimator (T_int = T_shell = T_cab)")
    ap.add_argument(
        "--offsets",
        default="",
        help="comma-separated sensor offsets, e.g. t_vent_c+0.5,t_cab_c-0.3: "
        "run the sensor-offset study (vehicle mode, with and without the vent-offset state) instead",
    )
    ap.add_argument("--out", default=None, help="JSON file for the rows")
    args = ap.parse_args(argv)

    def show(r):
        extra = (
            f", RMSE T_int {r['est_t_int_rmse_k']:.2f} K, T_shell {r['est_t_shell_rmse_k']:.2f} K, "
            f"T_glass {r['est_t_glass_rmse_k']:.2f} K"
            if r["est_t_int_rmse_k"] is not None
            else ""
        )
        print(
            f"{r['case']}/{r['strategy']}/{r['mode']}: E {r['E_tot_kWh']:.4f} kWh, I_pmv {r['I_pmv']:.0f} s, "
            f"discomfort {r['discomfort_pmvh']:.4f} PMV h{extra} ({r['wall_s']:.1f} s)",
            file=sys.stderr,
        )

    cases, strategies = args.cases.split(","), args.strategies.split(",")
    offsets = [o for o in args.offsets.split(",") if o]
    for o in offsets:
        try:
            _parse_offset(o)
        except ValueError as exc:
            ap.error(str(exc))
    rows = estimation_cost(cases, strategies, args.naive, progress=show)
    ref = rows
    if offsets:
        rows = rows + offset_study(cases, strategies, offsets, progress=show)
    if args.out:
        clean = [
            {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in r.items()} for r in rows
        ]
        pathlib.Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        pathlib.Path(args.out).write_text(json.dumps(clean, indent=1) + "\n", encoding="utf-8")
    print(markdown_table(ref))
    if offsets:
        print()
        print(offset_table([r for r in rows if "offset" in r], ref))
    return 0


if __name__ == "__main__":
    sys.exit(main())
