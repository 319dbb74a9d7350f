"""Issue 17 item 5: every ranged parameter of every node, table-driven. At each end of its declared
range, with the fewest other parameters moved that its derived range needs (state age and windows
at least Ts, the liveliness lease at most Ts, Ts a whole multiple of the plant step, previews at
least once per Ts), the node's pure core still does its job: the controller configures (builds its
NLP and solves its first step), the plant steps a control period under a command and under its
fallback law, the preview node makes an Np + 1 grid of finite values. A value just beyond either end
is refused by the declaration check with a message naming the parameter and its range; an end that
needs other parameters moved is refused on its own with a message naming the parameter it depends on."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from ceco_controller.controller_params import ControllerNodeConfig, controller_parameters
from ceco_plant_sim.plant_io import PLANT_PARAMETERS, PlantNodeConfig
from ceco_ros.params import check_value
from ceco_v2x_preview.preview_io import PREVIEW_PARAMETERS, PreviewNodeConfig

TABLES = {
    'mpc_node': (controller_parameters(), lambda v: ControllerNodeConfig.from_params(v, None)),
    'baseline_node': (controller_parameters('baseline'), lambda v: ControllerNodeConfig.from_params(v, 'baseline')),
    'plant_node': (PLANT_PARAMETERS, PlantNodeConfig.from_params),
    'preview_node': (PREVIEW_PARAMETERS, PreviewNodeConfig.from_params),
}
AGES = ('max_state_age_s', 'inputs.max_state_age_s', 'inputs.window_s')
CASES = [
    (node, spec.name, end)
    for node, (specs, _) in TABLES.items()
    for spec in specs
    if spec.float_range or spec.int_range
    for end in (0, 1)
]


def _spec(node, name):
    return next(s for s in TABLES[node][0] if s.name == name)


def _with_period(node, values: dict, ts: float) -> dict:
    """``values`` with Ts = ``ts`` and what its derived ranges then need."""
    out = dict(values, control_period_s=ts)
    out['qos.liveliness_lease_s'] = min(out['qos.liveliness_lease_s'], ts)
    for name in AGES:
        if name in out:
            out[name] = max(out[name], ts)
    if 'publish_period_s' in out:
        out['publish_period_s'] = min(out['publish_period_s'], ts)
    if 'plant_dt_s' in out and ts < out['plant_dt_s']:
        out['plant_dt_s'] = ts
    return out


def _extreme(node, name, end) -> tuple[dict, object]:
    """The parameters of the extreme ``end`` of ``name`` and the value it takes there."""
    specs, _ = TABLES[node]
    values = {s.name: s.default for s in specs}
    spec = _spec(node, name)
    value = (spec.float_range or spec.int_range)[end]
    ts_lo, ts_hi = _spec(node, 'control_period_s').float_range
    if name == 'control_period_s':
        return _with_period(node, values, value), value
    if name in AGES and value < values['control_period_s']:
        values = _with_period(node, values, ts_lo)  # the shortest Ts the node takes
        value = max(value, ts_lo)
    elif name == 'qos.liveliness_lease_s' and value > values['control_period_s']:
        values = _with_period(node, values, min(value, ts_hi))
    elif name in ('publish_period_s', 'plant_dt_s') and value > values['control_period_s']:
        values = _with_period(node, values, value)
    values[name] = value
    return values, value


@functools.cache
def _controller_works(strategy, ts, np_, timing) -> bool:
    """The controller core configures (NLP built, first step solved) for Ts and Np."""
    from ceco_controller.controller_session import ControllerSession

    specs, make = TABLES['baseline_node' if strategy == 'baseline' else 'mpc_node']
    values = _with_period(None, {s.name: s.default for s in specs}, ts)
    values.update(horizon_steps=np_, timing=timing)
    cfg = make(values)
    session = ControllerSession(cfg, lambda *_: None, lambda *_: None)
    # how the first solve went: the NMPC's nominal instance solved (the answer names a solve that was not usable),
    # or the ACC law's key-on step
    return session.configure(cfg) in ('NmpcController.warm_up', 'a key-on step') and session.ctl is not None


def _works(node, cfg) -> None:
    if node in ('mpc_node', 'baseline_node'):
        assert _controller_works(cfg.strategy, cfg.control_period_s, cfg.horizon_steps, cfg.timing)
        from ceco_controller.controller_session import ControllerSession

        ControllerSession(cfg, lambda *_: None, lambda *_: None)  # its inputs take the configuration
    elif node == 'plant_node':
        from ceco_core.contracts import AcInput
        from ceco_plant_sim.plant_loop import PlantLoop
        from ceco_v2x_preview.scenario import load_scenario

        loop = PlantLoop(load_scenario('sc03'), cfg)
        u = AcInput(mdot_bl_kgps=0.1, t_evap_sp_c=5.0)
        for _ in range(min(loop.m, 50)):
            r = loop.step(u)
        u_fb, _line = loop.fallback_command('test')
        r = loop.step(u_fb)
        assert math.isfinite(r.out.e_comp_j) and math.isfinite(loop.sp.meas['t_cab_c'])
        assert loop.n == min(loop.m, 50) + 1 and not loop.finished
    else:
        from ceco_v2x_preview.preview import make_previews
        from ceco_v2x_preview.scenario import load_scenario

        p = make_previews(load_scenario('sc03'), 60.0, cfg.control_period_s, cfg.horizon_steps + 1, cfg.quality)
        assert len(p.t_s) == cfg.horizon_steps + 1 and np.all(np.isfinite(p.t_s))
        # every sample valid and finite; none where the delay puts the forecast's issue before the drive's start
        stale = 60.0 - cfg.quality.delay_s < 0.0
        assert (not p.valid.any()) if stale else p.valid.all(), (cfg.quality.delay_s, p.valid)
        for series in (p.t_amb_c, p.solar_wm2, p.speed_mps, p.rh):
            assert np.all(np.isfinite(series[p.valid])) and np.all(np.isnan(series[~p.valid]))


@pytest.mark.parametrize(
    ('node', 'name', 'end'), CASES, ids=[f'{n}-{p}-{"lo" if e == 0 else "hi"}' for n, p, e in CASES]
)
def test_extreme_accepted_values_keep_the_node_working_and_beyond_is_refused(node, name, end):
    specs, make = TABLES[node]
    spec = _spec(node, name)
    lo, hi = spec.float_range or spec.int_range
    values, value = _extreme(node, name, end)
    assert check_value(spec, value)[1] is None
    cfg = make(values)  # accepted, derived ranges included
    _works(node, cfg)
    # on its own (the others at their defaults) an end is accepted, or refused naming what it depends on
    alone = {s.name: s.default for s in specs} | {name: (lo, hi)[end]}
    try:
        make(alone)
    except ValueError as err:
        assert str(err).startswith('invalid parameter ') and ('control_period_s' in str(err)), err
    # beyond the declared range: refused at declaration (and by ros2 param set), with the range
    step = 1 if spec.int_range else max(abs((lo, hi)[end]) * 0.01, 1e-3)
    beyond = (lo - step, hi + step)[end]
    why = check_value(spec, beyond)[1]
    assert why == f'invalid parameter {name}={beyond!r}: must lie in [{lo}, {hi}]'
    if spec.float_range:
        assert 'must be a finite number' in check_value(spec, math.nan)[1]


@pytest.mark.parametrize(
    ('node', 'measurements', 'ts', 'refused'),
    [
        ('mpc_node', 'full', 7.5, True),
        ('mpc_node', 'full', 12.0, True),
        ('mpc_node', 'full', 10.0, False),
        ('mpc_node', 'full', 0.1 * 3 * 50, False),  # 15.000000000000002: a whole multiple within the float tolerance
        ('baseline_node', 'full', 7.5, False),  # the ACC law runs at any Ts
        ('baseline_node', 'vehicle', 7.5, True),  # its estimator steps the control model
        ('baseline_node', 'vehicle', 10.0, False),
    ],
)
def test_control_period_not_a_whole_multiple_of_the_model_step_is_refused_at_start_and_on_set(
    node, measurements, ts, refused
):
    """A Ts the control model cannot step (mpc_node; baseline_node with measurements vehicle) is refused by the
    configuration (start, ``ros2 param set``) with the words of the NMPC's own check at configure
    (``model.substeps``, the one rule), instead of failing at configure after a clean start."""
    from ceco_controller import model as cm

    specs, make = TABLES[node]
    values = _with_period(node, {s.name: s.default for s in specs}, ts) | {'measurements': measurements}
    try:
        cm.substeps(cm.load_params(), ts)
        configure_says = None
    except ValueError as err:
        configure_says = str(err)
    assert (configure_says is not None and (node == 'mpc_node' or measurements == 'vehicle')) == refused
    if not refused:
        make(values)
        return
    with pytest.raises(ValueError) as start:
        make(values)
    assert str(start.value) == f'invalid parameter control_period_s={ts!r}: {configure_says}'
    cfg = make(_with_period(node, values, 5.0))  # a running node's ros2 param set: the same check, the same words
    with pytest.raises(ValueError) as on_set:
        cfg.replaced(values)
    assert str(on_set.value) == str(start.value)
