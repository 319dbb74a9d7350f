"""ceco-pmv (issue 20, section 3): PMV bias feedback, adaptive back-off, preview shrinkage, closed loop.

Unit level: :mod:`ceco_controller.comfort_feedback` on constructed sequences. System level: the real NLP
(:class:`~ceco_controller.nmpc.NmpcController`) against the plant simulator on a constant-weather day.
"""

import math

import numpy as np
import pytest
from observations import observation

from ceco_controller.closed_loop import SimSettings, simulate
from ceco_controller.comfort_feedback import PmvFeedback, PreviewSkill, held, measured_pmv
from ceco_controller.nmpc import NmpcController
from ceco_controller.strategies import strategy_settings
from ceco_v2x_preview.preview import parse_quality
from ceco_v2x_preview.scenario import scenario_from_dict

N1 = 7  # Np + 1


def _feedback(**kw):
    s = strategy_settings("ceco-pmv")
    args = dict(
        bias_filter=s.pmv_bias_filter,
        bias_limit=s.pmv_bias_limit,
        quantile=s.backoff_quantile,
        window=s.backoff_window_steps,
        min_samples=s.backoff_min_samples,
        init=s.backoff_init_pmv,
        lo=s.backoff_min_pmv,
        hi=s.backoff_max_pmv,
        forecast_z=s.backoff_forecast_z,
    )
    args.update(kw)
    return PmvFeedback(**args)


def test_pmv_bias_removes_a_constant_offset():
    # the model predicts 0.30 every step, the measured PMV is 0.45: a constant offset of +0.15
    fb = _feedback()
    for _ in range(40):
        fb.remember(0.30)
        fb.update(0.45)
    assert fb.bias == pytest.approx(0.15, abs=1e-5)
    # the residual of the biased prediction (what the back-off is measured on) goes to zero
    assert abs(fb.residuals[-1]) < 1e-5
    # the prediction the NLP uses (model + bias) now equals the measurement
    assert 0.30 + fb.bias == pytest.approx(0.45, abs=1e-5)
    # an offset larger than the limit is clipped at d_max (bounded), and NaN measurements keep the bias
    fb = _feedback(bias_limit=0.2)
    for _ in range(40):
        fb.remember(0.0)
        fb.update(1.0)
    assert fb.bias == pytest.approx(0.2)
    fb.remember(0.0)
    fb.update(math.nan)
    assert fb.bias == pytest.approx(0.2) and fb.last_error is None


def test_backoff_grows_with_prediction_error():
    rng = np.random.default_rng(3)
    out = {}
    for sigma in (0.01, 0.05, 0.10):
        fb = _feedback()
        assert fb.measured_backoff == pytest.approx(0.1)  # initial back-off until min_samples residuals
        for e in rng.normal(0.0, sigma, 200):
            fb.remember(0.2)
            fb.update(0.2 + fb.bias + e)
        out[sigma] = fb.measured_backoff
    # the 95 % quantile of N(0, sigma) is 1.645 sigma: clipped to [m_min, 0.3], m_min = 0.02 > 1.645 * 0.01
    assert out[0.01] == pytest.approx(0.02) == strategy_settings("ceco-pmv").backoff_min_pmv
    assert 1.2 * 0.05 < out[0.05] < 2.2 * 0.05
    assert 1.2 * 0.10 < out[0.10] < 2.2 * 0.10
    assert out[0.01] < out[0.05] < out[0.10]


def test_backoff_grows_with_forecast_uncertainty():
    fb = _feedback()
    v_small = np.array([0.0, 100.0, 400.0, 900.0])  # solar forecast mse per lead [(W/m2)^2]
    v_large = 16.0 * v_small
    m_small, m_large = fb.backoff(v_small, 1e-3), fb.backoff(v_large, 1e-3)
    # leads 0 and 1 carry the measured back-off only; beyond, z * sigma growth * dPMV/dG
    assert m_small[:2] == pytest.approx([0.1, 0.1]) and m_large[:2] == pytest.approx([0.1, 0.1])
    assert m_small[3] == pytest.approx(0.1 + 1.645 * 1e-3 * math.sqrt(800.0))
    assert m_large[3] == pytest.approx(0.1 + 1.645 * 1e-3 * math.sqrt(16 * 800.0))
    assert np.all(np.diff(m_large) >= 0) and m_large[3] > m_small[3] + 0.1


def test_preview_skill_measures_forecast_error_and_shrinks():
    # measured solar constant 600 W/m2; forecast A says exactly that, forecast B says 600 + 50*lead (wrong)
    def run(err_per_lead):
        sk = PreviewSkill(N1, window=60.0, c=1.0)
        for k in range(30):
            o = observation(N1, k, solar_wm2=600.0, preview_solar_wm2=600.0 + err_per_lead * np.arange(N1))
            sk.update(o, np.ones(N1, bool))
        return sk, o

    good, o = run(0.0)
    bad, _ = run(50.0)
    assert good.forecast_mse("solar") == pytest.approx(np.zeros(N1), abs=1e-9)
    assert bad.forecast_mse("solar")[1:] == pytest.approx((50.0 * np.arange(1, N1)) ** 2, rel=1e-6)
    # estimate: the smaller of forecast and persistence (here persistence is exact): zero
    assert bad.estimate_mse("solar", N1 + 3) == pytest.approx(np.zeros(N1 + 3), abs=1e-9)
    # a previewed change within the forecast's measured error is dropped; with a perfect record it passes whole
    ex = {"solar": 600.0 + 40.0 * np.arange(N1), "t_amb": np.full(N1, 35.0), "speed": np.full(N1, 10.0)}
    assert bad.shrink(ex, o)["solar"] == pytest.approx(np.full(N1, 600.0))
    assert good.shrink(ex, o)["solar"] == pytest.approx(ex["solar"])


def _shrink_reference(sk, series, obs):
    """The shrinkage as the module docstring writes it, on numpy arrays (the reference for the element-wise code)."""
    out = {}
    for q, x in series.items():
        x, p = np.asarray(x, float), float(getattr(obs, {"t_amb": "t_amb_c", "solar": "solar_wm2"}.get(q, "speed_mps")))
        sw = np.asarray(sk.sw_f[q])
        v = held(np.where(sw > 0, np.asarray(sk.se_f[q]) / np.maximum(sw, 1e-300), 0.0), x.size)
        dx = x - p
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.where(dx != 0.0, np.maximum(0.0, 1.0 - sk.c**2 * v / np.maximum(dx * dx, 1e-300)), 1.0)
        out[q] = p + s * dx
    return out


def test_shrinkage_and_error_estimate_equal_the_numpy_formula_to_the_bit():
    # random forecast errors and previews of 7 and 10 points (the horizon extension), a NaN and an inf in a
    # preview: the element-wise code gives numpy's numbers to the bit, NaN and inf where numpy has them
    rng = np.random.default_rng(7)
    sk = PreviewSkill(N1, window=40.0, c=1.3)
    for k in range(25):
        o = observation(
            N1,
            k,
            solar_wm2=500.0 + 80.0 * rng.standard_normal(),
            t_amb_c=35.0 + rng.standard_normal(),
            preview_solar_wm2=500.0 + 120.0 * rng.standard_normal(N1),
            preview_t_amb_c=35.0 + 2.0 * rng.standard_normal(N1),
        )
        sk.update(o, rng.random(N1) > 0.2)
    n_partly = 0
    for n in (N1, N1 + 3) * 10:
        ex = {
            "solar": o.solar_wm2 + 400.0 * rng.standard_normal(n),
            "t_amb": np.r_[o.t_amb_c, o.t_amb_c + 6.0 * rng.standard_normal(n - 1)],
            "speed": np.full(n, o.speed_mps),
        }
        ex["solar"][2], ex["t_amb"][3] = np.nan, np.inf
        got, ref = sk.shrink(ex, o), _shrink_reference(sk, ex, o)
        for q in ex:
            assert got[q].shape == (n,) and np.array_equal(got[q], ref[q], equal_nan=True), q
        assert math.isnan(got["solar"][2]) and got["t_amb"][3] == np.inf
        moved = np.isfinite(got["solar"]) & (ex["solar"] != o.solar_wm2)
        assert np.any(got["solar"][moved] != ex["solar"][moved])  # something was shrunk
        assert np.array_equal(got["speed"], ex["speed"])  # no change, nothing shrunk
        for q in ("solar", "t_amb"):  # changes shrunk part of the way (not to 0, not whole)
            meas = o.solar_wm2 if q == "solar" else o.t_amb_c
            d_got, d_ex = got[q] - meas, ex[q] - meas
            n_partly += int(np.sum(np.isfinite(d_got) & (np.abs(d_got) > 0) & (np.abs(d_got) < np.abs(d_ex))))
        for q in ("solar", "t_amb"):
            f = np.where(np.asarray(sk.sw_f[q]) > 0, np.asarray(sk.se_f[q]) / np.asarray(sk.sw_f[q]), 0.0)
            pe = np.where(np.asarray(sk.sw_p[q]) > 0, np.asarray(sk.se_p[q]) / np.asarray(sk.sw_p[q]), 0.0)
            assert np.array_equal(sk.forecast_mse(q), f) and np.array_equal(sk.persistence_mse(q), pe)
            assert np.array_equal(sk.estimate_mse(q, n), held(np.minimum(f, pe), n))
            assert sk.estimate_mse(q, n)[1:].min() > 0.0  # (lead 0's persistence error is 0)
    assert n_partly > 100


def test_held_extends_with_the_last_value():
    assert held([1.0, 2.0, 3.0], 5) == pytest.approx([1, 2, 3, 3, 3])
    assert held([1.0, 2.0, 3.0], 2) == pytest.approx([1, 2])


def test_controller_caps_the_upper_bound_and_moves_it_by_bias_and_backoff():
    ctrl = NmpcController("ceco-pmv")
    n = ctrl.problem.params.n_grid
    assert n == strategy_settings("ceco-pmv").nlp_steps + 1 == 13
    # the scenario relaxes the upper bound to 3.0 (a pull-down): ceco-pmv caps it at the band's +0.5
    zone = dict(t_int_c=32.0, t_shell_c=32.0, rh_cab=0.45, pmv_ub=np.full(N1, 3.0))
    for k in range(3):
        cmd, diag = ctrl.compute(observation(N1, k, t_cab=26.0, **zone))
        assert diag.success and "comfort: PMV" in diag.message
    fb = ctrl.pmv_feedback
    assert fb is not None and fb.last_error is not None and math.isfinite(fb.bias) and fb.bias != 0.0
    pl, p = ctrl.problem.params, ctrl._last_nlp.p
    # the NLP's bounds: the observation's (the upper one capped at 0.5) moved by -bias, the upper one also by
    # the initial back-off 0.1
    assert pl.get(p, "pmv_ub") == pytest.approx(np.full(n, 0.5 - fb.bias - 0.1))
    assert pl.get(p, "pmv_lb") == pytest.approx(np.full(n, -0.5 - fb.bias))
    # without a humidity measurement the PMV is measured at the paper's 1700 Pa, as the NLP's PMV is then
    # (pmv_pa_source measured): the feedback goes on (it used to keep its bias for good: a car without a cabin
    # humidity sensor had no offset-free feedback)
    dry = observation(N1, 3, t_cab=26.0, t_int_c=32.0, t_shell_c=32.0)
    assert math.isnan(dry.rh_cab)
    ctrl.compute(dry)
    at_1700 = measured_pmv(dry, ctrl.comfort_params, dry.t_glass_c, math.nan)
    assert math.isfinite(at_1700) and fb.last_measured == pytest.approx(at_1700, abs=1e-12)
    humid = measured_pmv(dry, ctrl.comfort_params, dry.t_glass_c, 0.45)
    assert at_1700 != pytest.approx(humid, abs=1e-3)  # 1700 Pa is not 45 % RH at 26 degC (1513 Pa)


_STEADY = {
    "name": "constant_hot",
    "description": "constant 35 degC, 40 % RH, 700 W/m2, cabin near comfort at the start",
    "drive_cycle": "sc03",
    "duration_s": 600,
    "weather": {"time_s": [0, 600], "t_amb_c": [35.0, 35.0], "solar_wm2": [700.0, 700.0], "rh": [0.4, 0.4]},
    "occupant": {"met": 1.2, "clo": 0.5},
    "comfort_bounds": {"time_s": [0, 600], "pmv_lb": [-0.5, -0.5], "pmv_ub": [0.5, 0.5]},
    "initial": {"t_cab_c": 27.0, "t_int_c": 33.0, "t_shell_c": 34.0},
    "control": {"control_period_s": 5, "horizon_steps": 6},
    "seed": 0,
}


def test_steady_state_holds_pmv_within_backoff_under_the_bound():
    sc = scenario_from_dict(_STEADY)
    res = simulate(sc, "ceco-pmv", SimSettings(progress=False, preview_quality=parse_quality("perfect")))
    ts = res.timeseries
    late = ts["t_s"] >= 300.0
    pmv = ts["pmv"][late]
    # the scored PMV at the plant's 1-s steps stays under the bound, stop at 350 s included, and never further
    # below it than 0.06 (3 m_min): the comfort phase sits at the edge, not in the middle of the band (measured
    # with the floor m_min 0.02: min 0.463, mean 0.479, max 0.484, 0.1425 kWh; with 0.04, shipped before
    # 4 Dec 2026: min 0.455, mean 0.460, max 0.464, 0.1434 kWh)
    assert pmv.max() <= 0.5
    assert pmv.min() >= 0.44
    assert float(np.mean(pmv)) >= 0.47
    assert res.metrics["n_fallback_baseline"] == 0 and res.metrics["n_fallback_shifted"] == 0


def test_benchmark_runs_the_persistence_twin():
    from ceco_bringup.benchmark import runner
    from ceco_bringup.benchmark.cases import load_case

    specs = runner.controllers(runner.load_baselines(), (25.0,), ("ceco", "ceco-pmv"), (0.2,))
    by_name = {c.name: c for c in specs}
    assert "ceco-pmv-persistence" in by_name and "ceco-persistence" not in by_name
    twin = by_name["ceco-pmv-persistence"]
    assert (twin.kind, twin.strategy, twin.preview) == ("strategy", "ceco-pmv", "persistence")
    case = load_case("tunnel")
    cells = runner.case_cells(case, [by_name["ceco-pmv"], twin], "x")
    previews = {(c.axes["controller"], c.spec["preview"]) for c in cells}
    # the strategy sees the case's forecasts (medium uncertainty), its twin persistence, on every seed
    assert previews == {("ceco-pmv", "uncertain:medium"), ("ceco-pmv-persistence", "persistence")}
    assert len(cells) == 2 * len(case.seeds)
    assert parse_quality("persistence").persistence


def test_settle_after_the_command_changes_no_number():
    """mpc_node publishes the command, then calls ``settle`` (the model's predictions for the next step's bias and
    PMV feedback); a controller that never calls it does that work at its next ``compute``. Same commands, the same
    bias and PMV residuals, bit for bit; a second ``settle`` does nothing."""
    zone = dict(t_int_c=32.0, t_shell_c=32.0, rh_cab=0.45, pmv_ub=np.full(N1, 3.0))
    lazy, eager = NmpcController("ceco-pmv"), NmpcController("ceco-pmv")
    for k in range(6):
        obs = observation(N1, k, t_cab=26.0 - 0.3 * k, **zone)
        c1, d1 = lazy.compute(obs)
        c2, d2 = eager.compute(obs)
        pred = eager._bias.last_pred
        eager.settle()
        assert eager._bias.last_pred != pred  # this step's prediction, made after the command
        after = (eager._bias.last_pred, eager.pmv_feedback.bias)
        eager.settle()
        assert (eager._bias.last_pred, eager.pmv_feedback.bias) == after
        assert (c1.mdot_bl_kgps, c1.t_evap_sp_c) == (c2.mdot_bl_kgps, c2.t_evap_sp_c)
        assert d1.success and d2.success and d1.message == d2.message  # the PMV, bias and back-off in the note
    assert lazy.pmv_feedback.bias == eager.pmv_feedback.bias != 0.0
    assert np.array_equal(lazy._bias.bias, eager._bias.bias)
    residuals = list(eager.pmv_feedback.residuals)
    assert list(lazy.pmv_feedback.residuals) == residuals and len(residuals) == 5 and len(set(residuals)) == 5


def test_a_step_reads_the_comfort_parameters_once_and_the_nlp_gets_them(monkeypatch):
    """ceco-pmv's comfort step computes T_mr and p_a for its measured PMV; the NLP's parameter vector takes the same
    pair (no second read: 30-60 us of a node's step), and the measured PMV is the one at that T_mr. ceco-ioch, without
    a comfort step, reads them once for its NLP."""
    zone = dict(t_int_c=32.0, t_shell_c=34.0, rh_cab=0.45, pmv_ub=np.full(N1, 3.0))
    for name in ("ceco-pmv", "ceco-ioch"):
        ctrl = NmpcController(name)
        reads = []
        inner = ctrl.comfort_parameters

        def counted(*a, _inner=inner, _reads=reads, **kw):
            out = _inner(*a, **kw)
            _reads.append(out.copy())
            return out

        monkeypatch.setattr(ctrl, "comfort_parameters", counted)
        for k in range(3):
            obs = observation(N1, k, t_cab=26.0 - 0.3 * k, **zone)
            n_before = len(reads)
            cmd, diag = ctrl.compute(obs)
            assert diag.success and len(reads) == n_before + 1, name
            p = ctrl.last_nlp().p
            assert np.all(ctrl.problem.params.get(p, "t_mr") == reads[-1][0])
            assert np.all(ctrl.problem.params.get(p, "pa") == reads[-1][1])
            if name == "ceco-pmv":  # the feedback's measured PMV is the one at that read's T_mr, to the bit
                y = ctrl.pmv_feedback.last_measured
                fn = ctrl._pmv_fn
                assert y == measured_pmv(obs, ctrl.comfort_params, math.nan, 0.45, fn, float(reads[-1][0]))
                assert y == measured_pmv(obs, ctrl.comfort_params, math.nan, 0.45, fn)  # as a fresh T_mr gives
                assert y != measured_pmv(obs, ctrl.comfort_params, math.nan, 0.45, fn, float(reads[-1][0]) + 1.0)


def test_the_compiled_pmv_equals_the_numpy_pmv_and_feeds_the_same_reads():
    """:class:`CabinPmvFunction` (the controllers' per-step PMV) is ``cabin_pmv``'s own code on CasADi symbols:
    over 500 random cabin states it agrees with the numpy evaluation to 1e-12 (relative to max(1, |PMV|)); the
    measured PMV and its sun sensitivity read through it agree with the numpy reads; NaN in gives NaN out, where the
    numpy path raises (its callers check their inputs first)."""
    from ceco_controller.comfort_feedback import pmv_solar_sensitivity
    from ceco_controller.pmv_function import CabinPmvFunction
    from ceco_core.cabin_comfort import ComfortParams, cabin_pmv, cabin_w_rad_wm2

    params = ComfortParams()
    fn = CabinPmvFunction(params)
    rng = np.random.default_rng(7)
    worst = 0.0
    lo, hi = np.array([15.0, 3.0, 0.05, 15.0, 0.0, 500.0]), np.array([45.0, 30.0, 0.17, 60.0, 40.0, 3000.0])
    for _ in range(500):  # cabin air, vent air, blower, T_mr, W_rad, p_a
        x = rng.uniform(lo, hi).tolist()
        ref = float(
            cabin_pmv(
                t_cab_c=x[0], t_vent_c=x[1], mdot_bl_kgps=x[2], t_mr_c=x[3], w_rad_wm2=x[4], pa_pa=x[5], params=params
            )
        )
        worst = max(worst, abs(fn(*x) - ref) / max(1.0, abs(ref)))
    assert worst < 1e-12
    obs = observation(N1, 3, t_cab=27.0, speed=10.0)
    for rh in (0.4, math.nan):  # measured humidity, and the paper's 1700 Pa where there is none
        a, b = measured_pmv(obs, params, 31.0, rh), measured_pmv(obs, params, 31.0, rh, fn)
        assert math.isfinite(a) and abs(a - b) < 1e-12 * max(1.0, abs(a))
    w = [cabin_w_rad_wm2(g, params) for g in (590.0, 610.0)]  # 600 W/m2 +- 10
    y = [
        cabin_pmv(t_cab_c=27.0, t_vent_c=9.0, mdot_bl_kgps=0.12, t_mr_c=33.0, w_rad_wm2=x, pa_pa=1700.0, params=params)
        for x in w
    ]
    s0 = abs(float(y[1] - y[0])) / 20.0
    s1 = pmv_solar_sensitivity(27.0, 9.0, 0.12, 33.0, 1700.0, 600.0, params, fn)
    assert s0 > 1e-4 and abs(s0 - s1) < 1e-10 * s0
    assert math.isnan(fn(27.0, 9.0, 0.12, math.nan, 10.0, 1700.0))
    with pytest.raises(ValueError):
        cabin_pmv(
            t_cab_c=27.0, t_vent_c=9.0, mdot_bl_kgps=0.12, t_mr_c=math.nan, w_rad_wm2=10.0, pa_pa=1700.0, params=params
        )


def test_the_back_offs_quantile_is_numpys_to_the_bit():
    """``linear_quantile`` (the back-off's residual quantile) equals ``numpy.quantile``'s default (linear) to the bit
    on 3000 random windows of 1-60 residuals at quantiles 0, 0.5, 0.9, 1 and random ones."""
    from ceco_controller.comfort_feedback import linear_quantile

    rng = np.random.default_rng(3)
    for k in range(3000):
        r = rng.normal(0.0, 0.1, size=int(rng.integers(1, 61)))
        if k % 7 == 0:
            r = np.round(r, 2)  # ties
        for q in (0.0, 0.5, 0.9, 1.0, float(rng.uniform())):
            want = float(np.quantile(r, q))
            got = linear_quantile(sorted(r.tolist()), q)
            assert got == want, (r, q, got, want)
    fb = _feedback(min_samples=3, window=10, quantile=0.9, lo=-1.0, hi=1.0)
    fb.residuals.extend([0.3, -0.2, 0.05, 0.11])
    assert fb.measured_backoff == float(np.clip(np.quantile([0.3, -0.2, 0.05, 0.11], 0.9), -1.0, 1.0))
