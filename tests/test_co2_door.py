"""The CO2-holding door beside the NMPC (issue 21 part 2; ceco_core.co2_door, StrategySettings.door_control).

The law's closed-form step against a fine integration of the same balance, its safe defaults on hand-made
inputs, and closed-loop runs of ceco-pmv with the door on hot-commute-4p (UDDS in the SC03 heat, four occupants):
the CO2 held under its target, the door between its ends, less energy than with the plant's fixed 0.8, fresh air
when the sensor dies.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from ceco_core.air_quality import KGKG_PER_PPM, co2_generation_kgps
from ceco_core.co2_door import Co2DoorLaw, Co2DoorSettings, co2_after_ppm, hold_share

_GEN = 4 * co2_generation_kgps(1.2) / KGKG_PER_PPM  # four occupants [ppm kg/s]


def _euler(c0, amb, fresh, leak, gen, m_air, dt, n=20000):
    c, h = c0, dt / n
    for _ in range(n):
        c += h / m_air * ((fresh + leak) * (amb - c) + gen)
    return c


def test_the_step_is_the_exact_solution_of_the_balance_and_the_share_meets_the_target():
    """co2_after_ppm equals a 20000-step integration of m dC/dt = (F + L)(C_amb - C) + n g / k within 0.01 ppm;
    hold_share gives the largest share whose CO2 after the step is at the target (1e-3 more recirculation passes
    it); full recirculation when the cabin stays under it; fresh air when even that does not reach it."""
    args = (1420.0, 420.0, 0.02, 0.004, _GEN, 3.48, 5.0)
    assert co2_after_ppm(*args) == pytest.approx(_euler(*args), abs=0.01)
    r = hold_share(1360.0, 1350.0, 420.0, 0.06, 0.004, _GEN, 3.48, 5.0)
    assert 0.0 < r < 1.0
    after = co2_after_ppm(1360.0, 420.0, (1.0 - r) * 0.06, 0.004, _GEN, 3.48, 5.0)
    assert after == pytest.approx(1350.0, abs=0.05)
    assert co2_after_ppm(1360.0, 420.0, (1.0 - (r + 1e-3)) * 0.06, 0.004, _GEN, 3.48, 5.0) > 1350.0
    assert hold_share(800.0, 1350.0, 420.0, 0.06, 0.004, _GEN, 3.48, 5.0) == 1.0
    assert hold_share(1420.0, 1350.0, 420.0, 0.06, 0.004, _GEN, 3.48, 5.0) == 0.0
    # at the target in steady state the share lets in exactly n g / (k (C_t - C_amb)) - L of fresh air
    r_ss = hold_share(1350.0, 1350.0, 420.0, 0.06, 0.004, _GEN, 3.48, 5.0)
    assert (1.0 - r_ss) * 0.06 == pytest.approx(_GEN / (1350.0 - 420.0) - 0.004, rel=1e-3)


def _step(law, t, **kw):
    base = dict(
        t_s=t,
        dt_s=5.0,
        co2_sensor_fitted=True,
        co2_sensor_ppm=1450.0,
        co2_limit_ppm=1500.0,
        recirc_share=1.0,
        mdot_bl_prev_kgps=0.06,
        mdot_bl_kgps=0.06,
        speed_mps=10.0,
        n_occupants=4,
        t_cab_c=25.0,
        t_amb_c=35.0,
        fog_margin_k=20.0,
        fog_margin_min_k=3.0,
    )
    base.update(kw)
    return law.step(**base)


def test_door_safe_defaults_fog_sensor_fault_and_economiser():
    """Fresh air while fog threatens (bound + 0.5 K, until bound + 1.5 K), while a fitted sensor does not read, and
    when the ambient is cooler than the cabin by 1 K; without a fitted sensor a NaN reading is no fault (the
    balance alone); a high CO2 reading lets fresh air in, a low one keeps full recirculation."""
    law = Co2DoorLaw()
    c = _step(law, 0.0, fog_margin_k=3.4)
    assert (c.recirc_share, c.mode) == (0.0, "fog")
    c = _step(law, 5.0, fog_margin_k=4.0)
    assert (c.recirc_share, c.mode) == (0.0, "fog")  # hysteresis: not yet above bound + 1.5 K
    # fog over; the reading (1450 ppm) with 4 occupants on recirculation is high: as much fresh air as it has
    c = _step(law, 10.0, fog_margin_k=4.6)
    assert (c.recirc_share, c.mode) == (0.0, "co2_max_fresh") and c.co2_estimate_ppm > 1450.0
    fault = _step(law, 15.0, co2_sensor_ppm=math.nan)
    assert (fault.recirc_share, fault.mode) == (0.0, "co2_sensor_fault")
    c = _step(law, 20.0, t_amb_c=23.9)
    assert (c.recirc_share, c.mode) == (0.0, "economiser")
    lo = Co2DoorLaw()
    ok = _step(lo, 0.0, co2_sensor_ppm=600.0)
    assert (ok.recirc_share, ok.mode) == (1.0, "recirc")
    no_sensor = _step(Co2DoorLaw(), 0.0, co2_sensor_fitted=False, co2_sensor_ppm=math.nan)
    assert no_sensor.mode == "recirc" and math.isfinite(no_sensor.co2_estimate_ppm)
    with pytest.raises(ValueError, match="fog_enter_k < fog_exit_k"):
        Co2DoorSettings(fog_enter_k=2.0, fog_exit_k=1.0).validate()
    with pytest.raises(ValueError, match="margin_ppm"):
        Co2DoorSettings(margin_ppm=-1.0).validate()
    from ceco_controller.strategies import strategy_settings

    with pytest.raises(ValueError, match="door_control"):
        strategy_settings("ceco-pmv", door_control="open").validate()


def _hc4(duration_s, door: bool, fail_s=None, strategy="ceco-pmv"):
    from ceco_bringup.benchmark.cases import load_case
    from ceco_controller.closed_loop import SimSettings, simulate
    from ceco_v2x_preview.preview import parse_quality

    sc = load_case("hot-commute-4p").load_scenario()
    if fail_s is not None:
        sc = dataclasses.replace(sc, air_quality=dataclasses.replace(sc.air_quality, co2_sensor_fail_s=fail_s))
    st = SimSettings(
        progress=False,
        seed=0,
        duration_s=duration_s,
        preview_quality=parse_quality("uncertain:medium"),
        strategy_overrides=(("door_control", "co2_hold"),) if door else (),
    )
    r = simulate(sc, strategy, st)
    assert r.metrics["n_fallback_shifted"] + r.metrics["n_fallback_baseline"] == 0
    assert r.metrics["strategy"] == strategy
    return r.timeseries


def _energy(ts):
    return float(np.sum(ts["p_comp_w"] + ts["p_blower_w"] + ts["p_cond_fan_w"]))


def test_closed_loop_ceco_pmv_with_the_door_holds_the_co2_under_its_target_for_less_energy():
    """900 s of hot-commute-4p: without door control (the plant's 0.8) the CO2 rises past 1300 ppm (still
    rising); with it the door recirculates fully, then modulates (shares strictly between 0 and 1) and the true CO2
    stays under the 1350 ppm target + 60 ppm (the estimate's error), for at least 3 % less energy. At key-on the
    soaked cabin is hotter than the ambient: fresh air (the economiser) until it is not."""
    plain = _hc4(900.0, door=False)
    aq = _hc4(900.0, door=True)
    assert np.all(plain["recirc_share_cmd"] == 0.8) and plain["co2_cab_ppm"].max() > 1300.0
    cmd = aq["recirc_share_cmd"]
    assert np.all((cmd >= 0.0) & (cmd <= 1.0))
    t_cab, t_amb = aq["t_cab_c"], aq["t_amb_c"]
    assert t_cab[0] > t_amb[0] + 1.0 and cmd[0] == 0.0  # the soaked cabin is hotter than the air outside
    assert np.any(cmd == 1.0) and np.any((cmd > 0.05) & (cmd < 0.95))
    assert aq["co2_cab_ppm"].max() < 1350.0 + 60.0
    assert _energy(aq) < 0.97 * _energy(plain)


def test_closed_loop_door_goes_to_fresh_air_when_the_co2_sensor_dies():
    """The sensor dies at 300 s: from the first control step after it the door commands fresh air (0), and the
    run goes on (the NMPC keeps controlling)."""
    ts = _hc4(420.0, door=True, fail_s=300.0)
    t, cmd = ts["t_s"], ts["recirc_share_cmd"]
    assert np.any(cmd[t < 300.0] > 0.5)
    assert np.all(cmd[t >= 305.0] == 0.0)


def test_the_named_variant_ceco_pmv_aq_is_ceco_pmv_with_the_co2_holding_door():
    """``simulate(sc, "ceco-pmv-aq")`` (``ceco sim``/``ceco run --strategy ceco-pmv-aq``, mpc_node's
    ``strategy:=ceco-pmv-aq``) gives the run of ceco-pmv with ``door_control: co2_hold``, to the bit, and moves the
    door where plain ceco-pmv leaves it at the plant's 0.8; a caller's overrides still apply on top of it."""
    from ceco_controller.strategies import load_strategy_settings, strategy_settings

    named = _hc4(120.0, door=False, strategy="ceco-pmv-aq")
    long_way = _hc4(120.0, door=True)
    plain = _hc4(120.0, door=False)
    for column in ("recirc_share_cmd", "mdot_bl_kgps", "t_evap_sp_c", "p_comp_w", "co2_cab_ppm"):
        np.testing.assert_array_equal(named[column], long_way[column], err_msg=column)
    assert np.all(plain["recirc_share_cmd"] == 0.8) and np.any(named["recirc_share_cmd"] != 0.8)
    for settings in (strategy_settings("ceco-pmv-aq"), load_strategy_settings("ceco-pmv-aq")):
        assert (settings.name, settings.door_control) == ("ceco-pmv", "co2_hold")
    assert load_strategy_settings("ceco-pmv-aq", door_control="nlp").door_control == "nlp"
    with pytest.raises(ValueError, match="unknown CECO strategy 'ceco-pmv-co2'; choose from .*'ceco-pmv-aq'"):
        load_strategy_settings("ceco-pmv-co2")


def test_benchmark_runs_the_door_variant_of_ceco_pmv_by_name():
    """``ceco-pmv-aq`` in the benchmark's strategies is ceco-pmv with door_control co2_hold (no persistence twin)."""
    from ceco_bringup.benchmark import runner

    specs = runner.controllers(runner.load_baselines(), (25.0,), ("ceco-pmv", "ceco-pmv-aq"), (0.0,))
    aq = [s for s in specs if s.name.startswith("ceco-pmv-aq")]
    assert len(aq) == 1 and aq[0].strategy == "ceco-pmv" and dict(aq[0].overrides) == {"door_control": "co2_hold"}
    assert aq[0].seeded and any(s.name == "ceco-pmv-persistence" for s in specs)


def test_a_baseline_with_the_co2_holding_door_holds_the_co2_like_the_strategy_and_fails_safe():
    """``door_mode: co2_hold`` puts ceco-pmv-aq's door behind a baseline's law (the ``*-doorco2`` families): 900 s of
    hot-commute-4p with the production law at 25 degC: the economiser at key-on, then full recirculation and a
    modulated door; the true CO2 stays under the 1350 ppm target + 60 ppm; each command equals (1e-9) the one a
    fresh Co2DoorLaw gives on the same observed inputs (the same door as the strategy's, replayed from the run); and
    for less energy than the production door logic on the same law. A CO2 sensor that dies at 300 s gives fresh
    air from the next control step on."""
    from ceco_bringup.benchmark.cases import load_case
    from ceco_controller.closed_loop import SimSettings, simulate
    from ceco_core.co2_door import Co2DoorLaw

    sc = load_case("hot-commute-4p").load_scenario()

    def run(mode, duration_s=900.0, scenario=sc):
        ov = (("setpoint_c", 25.0), ("door_mode", mode))
        return simulate(scenario, "baseline", SimSettings(progress=False, duration_s=duration_s, strategy_overrides=ov))

    res = run("co2_hold")
    ts = res.timeseries
    cmd, t = ts["recirc_share_cmd"], ts["t_s"]
    assert cmd[0] == 0.0 and ts["t_cab_c"][0] > ts["t_amb_c"][0] + 1.0  # economiser on the soaked cabin
    assert np.any(cmd == 1.0) and np.any((cmd > 0.05) & (cmd < 0.95))
    assert ts["co2_cab_ppm"].max() < 1350.0 + 60.0
    # replay the door law (the control model's identified CO2 balance) on the run's own inputs, every 5 s
    from ceco_controller import model as cm

    law = Co2DoorLaw(model=cm.co2_estimator_params(cm.load_params()))
    diffs = []
    for k in range(0, len(t) - 5, 5):
        c = law.step(
            t_s=float(t[k]),
            dt_s=5.0,
            co2_sensor_fitted=True,
            co2_sensor_ppm=float(ts["co2_sensor_ppm"][k]),
            co2_limit_ppm=1500.0,
            recirc_share=float(ts["recirc_share"][k]),
            mdot_bl_prev_kgps=float(ts["mdot_bl_kgps"][max(k - 1, 0)]),  # at k = 0 the estimator only corrects
            mdot_bl_kgps=float(ts["mdot_bl_kgps"][k]),
            speed_mps=float(ts["speed_mps"][k]),
            n_occupants=4,
            t_cab_c=float(ts["t_cab_c"][k]),
            t_amb_c=float(ts["t_amb_c"][k]),
            fog_margin_k=float(ts["fog_margin_k"][k]),
            fog_margin_min_k=3.0,
            rh_cab=float(ts["rh_cab"][k]),
            rh_amb=float(ts["rh"][k]),
        )
        diffs.append(abs(c.recirc_share - float(cmd[k])))
    assert len(diffs) == 179 and max(diffs) < 1e-9  # the same door, command for command
    auto = run("auto").timeseries
    assert _energy(ts) < _energy(auto)
    dead = run(
        "co2_hold",
        420.0,
        dataclasses.replace(sc, air_quality=dataclasses.replace(sc.air_quality, co2_sensor_fail_s=300.0)),
    )
    dt, dcmd = dead.timeseries["t_s"], dead.timeseries["recirc_share_cmd"]
    assert np.any(dcmd[dt < 300.0] > 0.5) and np.all(dcmd[dt >= 305.0] == 0.0)


def test_a_baseline_co2_door_that_cannot_step_commands_fresh_air_and_says_why():
    """The baseline's CO2-holding door refused an input (time going back): the door command is fresh air (0) and
    the diagnostics name the mode and the reason; the thermal commands stay bounded; the next valid step
    recirculates again."""
    from observations import observation

    from ceco_controller.baseline import BaselineController
    from ceco_core.contracts import ACTUATOR_LIMITS
    from ceco_core.recirc_law import RecircSettings

    ctl = BaselineController(door=RecircSettings(door_mode="co2_hold"))
    kw = dict(t_amb_c=35.0, co2_sensor_ppm=700.0, recirc_share=1.0, n_occupants=4)
    cmd, _ = ctl.compute(observation(6, k=2, t_cab=28.0, **kw))
    assert cmd.recirc_share == 1.0  # CO2 far under its target, the cabin cooler than the ambient
    cmd, diag = ctl.compute(observation(6, k=1, t_cab=28.0, **kw))  # t = 5 s after t = 10 s
    assert cmd.recirc_share == 0.0 and "door_mode=co2_door_error" in diag.message and "before" in diag.message
    assert ACTUATOR_LIMITS.contains(cmd.mdot_bl_kgps, cmd.t_evap_sp_c)
    cmd, _ = ctl.compute(observation(6, k=3, t_cab=28.0, **kw))
    assert cmd.recirc_share == 1.0
