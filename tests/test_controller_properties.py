"""Property-based tests (hypothesis) of the pure controller cores: any Observation, finite or not,
gives a finite command inside the actuator bounds and no exception (issue 12 item 7, core side);
and the recoveries of issue 12 (storm, poisoned estimator) on seeded streams."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ceco_controller.baseline import BaselineController
from ceco_controller.nmpc import NmpcController, nominal_observation
from ceco_core.contracts import ACTUATOR_LIMITS, Observation

N1 = 7  # Np + 1 of the default strategies

# floats of every kind, weighted towards plausible values so that many examples reach the solver
_ANY = st.floats(allow_nan=True, allow_infinity=True, width=64)


def _mixed(lo, hi):
    return st.one_of(
        st.floats(lo, hi),
        st.floats(lo, hi),
        st.floats(lo, hi),
        _ANY,
        st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e308, 0.0]),
    )


def _series(lo, hi, n=N1):
    return st.lists(_mixed(lo, hi), min_size=n, max_size=n).map(np.array)


@st.composite
def observations(draw, n=N1):
    """Any Observation with n preview points: scalars and series of any float, plausible more often."""
    lb = draw(_series(-3.0, 0.0, n))
    return Observation(
        k=draw(st.integers(-10, 10**12)),
        t_s=draw(_mixed(0.0, 1e4)),
        t_cab_c=draw(_mixed(15.0, 60.0)),
        t_int_c=draw(_mixed(15.0, 70.0)),
        t_shell_c=draw(_mixed(15.0, 70.0)),
        t_evap_c=draw(_mixed(0.0, 50.0)),
        t_vent_c=draw(_mixed(0.0, 50.0)),
        t_amb_c=draw(_mixed(10.0, 45.0)),
        solar_wm2=draw(_mixed(0.0, 1100.0)),
        speed_mps=draw(_mixed(0.0, 40.0)),
        mdot_bl_prev_kgps=draw(_mixed(0.05, 0.17)),
        t_evap_sp_prev_c=draw(_mixed(3.0, 10.0)),
        preview_t_amb_c=draw(_series(10.0, 45.0, n)),
        preview_solar_wm2=draw(_series(0.0, 1100.0, n)),
        preview_speed_mps=draw(_series(0.0, 40.0, n)),
        preview_valid=np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n))),
        pmv_lb=lb,
        pmv_ub=draw(_series(0.0, 3.0, n)),
        met=draw(_mixed(1.0, 2.0)),
        clo=draw(_mixed(0.3, 1.0)),
        t_glass_c=draw(_mixed(15.0, 70.0)),
        rh_cab=draw(_mixed(0.1, 0.9)),
    )


def _in_bounds(cmd) -> bool:
    return (
        math.isfinite(cmd.mdot_bl_kgps)
        and math.isfinite(cmd.t_evap_sp_c)
        and ACTUATOR_LIMITS.contains(cmd.mdot_bl_kgps, cmd.t_evap_sp_c)
    )


_CTRLS: dict = {}


def _ctrl(name):
    if name not in _CTRLS:
        _CTRLS[name] = NmpcController(name)
    return _CTRLS[name]


_SETTINGS = settings(
    max_examples=60,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


@pytest.mark.parametrize("strategy", ["ceco", "ceco-c", "ceco-ioch"])
@_SETTINGS
@given(obs=observations())
def test_nmpc_any_observation_gives_a_bounded_command(strategy, obs):
    ctrl = _ctrl(strategy)
    cmd, diag = ctrl.compute(obs)
    assert _in_bounds(cmd)
    assert diag.mdot_bl_kgps == cmd.mdot_bl_kgps and diag.t_evap_sp_c == cmd.t_evap_sp_c
    assert np.all(np.isfinite(ctrl._bias.bias))  # nothing non-finite ever enters the estimator


@settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(obs=observations())
def test_baseline_any_observation_gives_a_bounded_command(obs):
    ctrl = _CTRLS.setdefault("baseline", BaselineController())
    cmd, diag = ctrl.compute(obs)
    assert _in_bounds(cmd)


@settings(max_examples=20, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(obs=observations(n=5))
def test_nmpc_wrong_preview_length_never_raises(obs):
    cmd, diag = _ctrl("ceco").compute(obs)
    assert _in_bounds(cmd) and diag.fallback == "baseline"


def _clean(k, t_cab):
    obs = nominal_observation(N1, k)
    return Observation(**{**obs.__dict__, "k": k, "t_s": 5.0 * k, "t_cab_c": t_cab})


def test_a_storm_of_malformed_observations_leaves_no_trace():
    """Issue 12 'Degraded after the storm': 200 seeded malformed observations, then clean ones: every
    clean step is NMPC control, and from the second on a converged warm SQP solve (no IPOPT retry)."""
    rng = np.random.default_rng(7)
    ctrl = NmpcController("ceco")
    bad = [math.nan, math.inf, -math.inf, 1e6, -1e6, 9e18]
    fields = (
        "t_cab_c",
        "t_int_c",
        "t_shell_c",
        "t_evap_c",
        "t_vent_c",
        "t_amb_c",
        "solar_wm2",
        "speed_mps",
        "mdot_bl_prev_kgps",
        "t_evap_sp_prev_c",
    )
    n_acc = 0
    for k in range(200):
        obs = _clean(k, 27.0).__dict__.copy()
        for f in rng.choice(fields, size=rng.integers(1, 4), replace=False):
            obs[f] = bad[rng.integers(len(bad))] if rng.random() < 0.7 else obs[f] * rng.uniform(0.5, 3.0)
        if rng.random() < 0.3:
            obs["preview_t_amb_c"] = np.where(rng.random(N1) < 0.5, 1e9, obs["preview_t_amb_c"])
        cmd, diag = ctrl.compute(Observation(**obs))
        assert _in_bounds(cmd)
        n_acc += diag.fallback == "baseline"
    assert n_acc > 50  # the storm did reach the checks
    retries = ctrl.counters.retries
    for k in range(12):
        cmd, diag = ctrl.compute(_clean(200 + k, 27.0 - 0.1 * k))
        assert diag.fallback == "" and _in_bounds(cmd)
        if k >= 1:
            assert diag.success and diag.status == "Solve_Succeeded" and "ipopt" not in diag.status
    assert ctrl.counters.retries == retries
    assert np.all(np.isfinite(ctrl._bias.bias)) and np.all(np.abs(ctrl._bias.bias) <= 3.0)


def test_a_nan_previous_command_does_not_poison_the_estimator():
    """Issue 12 'Poisoned estimator': a NaN previous command is replaced by the command the
    controller applied; the bias estimates stay finite and every later solve succeeds."""
    ctrl = NmpcController("ceco")

    def near_comfort(k):  # a cabin near comfort: commands inside the actuator range (not at a bound)
        return Observation(**{**_clean(k, 24.5).__dict__, "t_int_c": 32.0, "t_shell_c": 32.0})

    for k in range(3):
        cmd, _ = ctrl.compute(near_comfort(k))
    applied = (cmd.mdot_bl_kgps, cmd.t_evap_sp_c)
    assert 0.06 < applied[0] < 0.16 and 4.0 < applied[1] < 12.0  # inside the range: a bound would not tell
    obs = near_comfort(3).__dict__.copy()
    obs["mdot_bl_prev_kgps"] = math.nan
    obs["t_evap_sp_prev_c"] = math.inf
    cmd, diag = ctrl.compute(Observation(**obs))
    assert diag.fallback == "" and diag.success and "the command applied last used instead" in diag.message
    assert ctrl.counters.substituted_commands == 1
    # the NLP planned from the command applied last, exactly (its u_prev), the bias model predicted with it
    assert tuple(ctrl.problem.params.get(ctrl.last_nlp().p, "u_prev")) == applied
    for k in range(4, 10):
        cmd, diag = ctrl.compute(_clean(k, 27.0))
        assert diag.success and diag.fallback == "" and np.all(np.isfinite(ctrl._bias.bias))
