"""The benchmark's baseline laws in closed loop: the tuned production law and the comfort-feedback PI.

Steady state on a constant-weather, constant-speed scenario (35 degC, 40 % RH, 600 W/m2, 50 km/h,
cabin started near its steady state): integral action must bring the controlled variable to its
set-point. The tolerances are the loop's residual ripple measured on this scenario plus a margin;
a law without integral action (or a sign error) misses them by far.
"""

import dataclasses
import math

import numpy as np
import pytest
from observations import observation

from ceco_controller.baseline import BaselineController
from ceco_controller.closed_loop import SimSettings, simulate
from ceco_controller.comfort_feedback import measured_pmv
from ceco_core.acc_law import AccSettings, feedback_pmv
from ceco_core.cabin_comfort import ComfortParams
from ceco_v2x_preview.scenario import scenario_from_dict

DURATION_S = 1800
TAIL_S = 600  # the last 10 minutes are averaged


def _scenario(tmp_path):
    cycle = tmp_path / "steady.csv"
    cycle.write_text(f"time_s,speed_mps\n0,13.9\n{DURATION_S},13.9\n", encoding="utf-8")
    return scenario_from_dict(
        {
            "name": "steady",
            "drive_cycle": str(cycle),
            "duration_s": DURATION_S,
            "weather": {"time_s": [0], "t_amb_c": 35.0, "solar_wm2": 600.0, "rh": 0.4},
            "occupant": {"met": 1.2, "clo": 0.5},
            "comfort_bounds": {"time_s": [0], "pmv_lb": -0.5, "pmv_ub": 0.5},
            "initial": {"t_cab_c": 27.0, "t_int_c": 32.0, "t_shell_c": 36.0},
        }
    )


def _run(sc, overrides, measurements="full"):
    r = simulate(
        sc,
        "baseline",
        SimSettings(progress=False, strategy_overrides=tuple(sorted(overrides.items())), measurements=measurements),
    )
    ts = r.timeseries
    tail = ts["t_s"] >= DURATION_S - TAIL_S
    return ts, tail, r


@pytest.mark.parametrize("kp, ti", [(0.25, 120.0), (0.5, 30.0)])
def test_temperature_law_settles_at_its_setpoint(tmp_path, kp, ti):
    ts, tail, _ = _run(_scenario(tmp_path), {"setpoint_c": 25.0, "kp_per_k": kp, "ti_s": ti})
    err = ts["t_cab_c"][tail] - 25.0
    assert abs(err.mean()) < 0.05, err.mean()  # offset-free: integral action
    assert np.abs(err).max() < 0.3  # no limit cycle
    assert ts["mdot_bl_kgps"][tail].min() >= 0.05 and ts["t_evap_sp_c"][tail].max() <= 10.0


def _pmv_gains():
    """The frozen gains of the benchmark's pmv family (data/benchmark/baselines.yaml)."""
    from ceco_bringup.benchmark.runner import load_baselines

    s = load_baselines().families["pmv"][0]
    return {"kp_per_pmv": s["kp_per_pmv"], "ti_s": s["ti_s"]}


@pytest.mark.parametrize(
    "sp, measurements, gains, tol",
    [
        (0.3, "full", {"kp_per_pmv": 0.8, "ti_s": 120.0}, 0.05),
        (0.0, "full", {"kp_per_pmv": 0.8, "ti_s": 120.0}, 0.05),
        (0.3, "vehicle", {"kp_per_pmv": 0.8, "ti_s": 120.0}, 0.1),
        (0.3, "full", "tuned", 0.05),
    ],
)
def test_pmv_law_settles_at_its_pmv_setpoint(tmp_path, sp, measurements, gains, tol):
    """The scored PMV settles at the PMV set-point on average over the last 10 minutes.

    The loop limit-cycles: the PMV contains the vent-jet air, which swings as the compressor cycles at this
    light load (measured with the production-equivalent gains: +0.07..+0.52 around 0.3, -0.31..+0.30
    around 0), so the test asserts the mean (within 0.05 when the law reads the plant's states; within
    0.1 when the surfaces are the estimator's from a car's sensors, whose T_mr error shifts the PMV), no
    drift between the two halves of the window, and a swing below 0.8.
    """
    g = _pmv_gains() if gains == "tuned" else gains
    ts, tail, _ = _run(_scenario(tmp_path), {"feedback": "pmv", "setpoint_pmv": sp, **g}, measurements)
    pmv = ts["pmv"][tail]
    half = len(pmv) // 2
    assert abs(pmv.mean() - sp) < tol, pmv.mean()
    assert abs(pmv[:half].mean() - pmv[half:].mean()) < 0.05  # settled, not drifting
    assert pmv.max() - pmv.min() < 0.8
    if sp == 0.0:  # the set-point acts: 0.3 higher, ~0.3 higher PMV and less compressor power
        ts2, tail2, _ = _run(_scenario(tmp_path), {"feedback": "pmv", "setpoint_pmv": 0.3, **g})
        assert ts2["pmv"][tail2].mean() - pmv.mean() == pytest.approx(0.3, abs=0.05)
        assert ts2["p_comp_w"][tail2].mean() < ts["p_comp_w"][tail].mean()


def test_pmv_law_reads_the_observation_and_faults_safely():
    """Unit level: the controller computes the PMV from the observation; a missing vent-air reading holds the last
    command (a sensor fault); a cabin humidity or glazing temperature the car does not measure does not: the PMV is
    then the one at the paper's 1700 Pa, with the interior for the glazing (comfort_feedback.measured_pmv)."""
    ctrl = BaselineController(AccSettings(feedback="pmv", setpoint_pmv=0.0), comfort_params=ComfortParams())
    hot = observation(7, t_cab=30.0, t_int_c=34.0, t_shell_c=38.0, t_glass_c=40.0, t_vent_c=12.0, rh_cab=0.3)
    cmd, diag = ctrl.compute(hot)
    assert diag.status in ("pi", "pulldown") and "pmv_measured=" in diag.message
    cool = observation(7, t_cab=20.0, t_int_c=21.0, t_shell_c=22.0, t_glass_c=22.0, t_vent_c=8.0, rh_cab=0.4)
    law2 = BaselineController(AccSettings(feedback="pmv", setpoint_pmv=0.0), comfort_params=ComfortParams())
    cmd2, _ = law2.compute(cool)
    assert cmd2.t_evap_sp_c > cmd.t_evap_sp_c  # a cool cabin: less cooling than a hot one
    bad = dataclasses.replace(hot, t_vent_c=float("nan"))
    held, d3 = ctrl.compute(bad)
    assert d3.status == "sensor_fault" and (held.mdot_bl_kgps, held.t_evap_sp_c) == (cmd.mdot_bl_kgps, cmd.t_evap_sp_c)
    unmeasured = dataclasses.replace(hot, rh_cab=float("nan"), t_glass_c=float("nan"))
    _, d4 = BaselineController(AccSettings(feedback="pmv", setpoint_pmv=0.0), comfort_params=ComfortParams()).compute(
        unmeasured
    )
    pmv_of = lambda d: float(d.message.split("pmv_measured=")[1].split()[0])  # noqa: E731
    assert d4.status in ("pi", "pulldown") and math.isfinite(pmv_of(d4))
    # the scored PMV written out, not through measured_pmv (the function under test): 1700 Pa, the interior's 34 degC
    # for the glazing
    expected = feedback_pmv(
        t_cab_c=30.0,
        t_vent_c=12.0,
        t_int_c=34.0,
        t_shell_c=38.0,
        t_glass_c=34.0,
        rh_cab=math.nan,
        mdot_bl_kgps=unmeasured.mdot_bl_prev_kgps,
        solar_wm2=unmeasured.solar_wm2,
        params=ComfortParams(),
        pa_pa=1700.0,
    )
    assert pmv_of(d4) == pytest.approx(expected, abs=5e-4) and abs(expected - pmv_of(diag)) > 0.01
    assert measured_pmv(unmeasured, ComfortParams(), math.nan, math.nan) == pytest.approx(expected, rel=1e-12)
    # implausible readings are not measurements either (the observation check's values): the same PMV
    implausible = dataclasses.replace(hot, rh_cab=1.5, t_glass_c=400.0)
    law5 = BaselineController(AccSettings(feedback="pmv", setpoint_pmv=0.0), comfort_params=ComfortParams())
    _, d5 = law5.compute(implausible)
    assert d5.status in ("pi", "pulldown") and pmv_of(d5) == pmv_of(d4)
