"""The nodes' pure logic, without ROS: the sequence gate and lockstep buffer, watchdog, fallback
state machine, rejection counting, message field checks, the parameter tables, each node's
input handling (controller, plant, preview) and health rules. Messages are SimpleNamespace
objects with the ceco_msgs field names."""

from __future__ import annotations

import dataclasses
import math
import re
from types import SimpleNamespace as NS

import numpy as np
import pytest
from observations import KEY_ON_STATE

from ceco_controller.controller_io import (
    ControllerInputs,
    ControllerNodeConfig,
    controller_health,
    controller_parameters,
)
from ceco_core.sequencing import LockstepBuffer, SequenceGate
from ceco_core.supervision import ERROR, OK, WARN, FallbackSupervisor, Health, Rejections, Watchdog, reason_kind
from ceco_core.units import STAMP_MAX_S, sec_nanosec_from_s
from ceco_ros import checks
from ceco_ros.params import ParamSpec, check_value
from ceco_v2x_preview.preview_io import PREVIEW_PARAMETERS, PreviewInputs, PreviewNodeConfig, preview_health


def stamp(t_s: float) -> NS:
    sec, nsec = sec_nanosec_from_s(t_s)
    return NS(sec=sec, nanosec=nsec)


def state(t_s: float, n: int | None = None, stamp_s: float | None = None, **override) -> NS:
    m = NS(
        header=NS(stamp=stamp(t_s if stamp_s is None else stamp_s)),
        step_index=int(t_s) if n is None else n,
        scenario_time_s=t_s,
        **KEY_ON_STATE,
        fallback=False,
    )
    for key, value in override.items():
        setattr(m, key, value)
    return m


def weather(k: int, n: int = 7, ts: float = 5.0, **override) -> NS:
    m = NS(
        header=NS(stamp=stamp(k * ts)),
        start=stamp(k * ts),
        step_s=ts,
        step_index=k,
        t_amb_c=[35.0] * n,
        solar_wm2=[800.0] * n,
        rh=[0.4] * n,
        valid=[True] * n,
        age_s=0.0,
        quality='perfect',
    )
    for key, value in override.items():
        setattr(m, key, value)
    return m


def traffic(k: int, n: int = 7, ts: float = 5.0, **override) -> NS:
    m = NS(
        header=NS(stamp=stamp(k * ts)),
        start=stamp(k * ts),
        step_s=ts,
        step_index=k,
        speed_mps=[10.0] * n,
        valid=[True] * n,
        age_s=0.0,
        quality='perfect',
    )
    for key, value in override.items():
        setattr(m, key, value)
    return m


def command(k: int, ts: float = 5.0, stamp_s: float | None = None, **override) -> NS:
    m = NS(
        header=NS(stamp=stamp(k * ts if stamp_s is None else stamp_s)),
        step_index=k,
        control_period_s=ts,
        blower_flow_kgps=0.1,
        evap_setpoint_c=5.0,
        strategy='ceco',
        fallback=False,
        epoch=0,
        sequence=0,
        recirc_share=-1.0,
    )
    for key, value in override.items():
        setattr(m, key, value)
    return m


# ------------------------------------------------------------------------------ sequence gate
def test_gate_accepts_forward_steps_in_the_window_only():
    g = SequenceGate(ahead=10.0, confirm=3)
    assert g.offer(5.0).accepted and g.last == 5.0  # the first position, wherever it is
    assert g.offer(6.0).accepted and g.offer(16.0).accepted  # +1, then exactly +ahead
    v = g.offer(16.0)
    assert not v.accepted and reason_kind(v.reason) == 'duplicate'
    v = g.offer(12.0)
    assert not v.accepted and reason_kind(v.reason) == 'stale'
    v = g.offer(26.5)
    assert not v.accepted and reason_kind(v.reason) == 'future'
    assert g.last == 16.0
    for bad in (math.nan, math.inf, -math.inf):
        assert not g.offer(bad).accepted and g.last == 16.0


def test_gate_far_future_position_does_not_move_the_window():
    """The latch case: one state 1e6 s ahead, then the real stream goes on as if nothing happened."""
    g = SequenceGate(ahead=60.0, confirm=3)
    for t in range(20):
        assert g.offer(float(t)).accepted
    assert not g.offer(1e6 + 19.0).accepted
    assert g.last == 19.0
    assert all(g.offer(float(t)).accepted for t in range(20, 40))
    # scattered far-future and stale positions never form a chain: never adopted
    for i, bad in enumerate((1e6, 5.0, 2e6, 3.0, 9e18, 1e6 + 500.0)):
        assert not g.offer(bad).accepted, i
        assert g.offer(40.0 + i).accepted


def test_gate_follows_a_restart_and_a_confirmed_new_time_base():
    g = SequenceGate(ahead=60.0, confirm=3)
    for t in range(100, 200):
        g.offer(float(t))
    v = g.offer(0.0)  # key-on: a restarted plant or a new playback from the start
    assert v.accepted and v.reset and 'key-on' in v.reason
    assert g.offer(1.0).accepted and not g.offer(1.0).accepted
    # a playback that starts elsewhere (t = 5000): rejected twice, adopted on the third agreeing state
    assert [g.offer(t).accepted for t in (5000.0, 5001.0)] == [False, False]
    v = g.offer(5002.0)
    assert v.accepted and v.reset and g.last == 5002.0
    assert g.offer(5003.0).accepted and not g.offer(2.0).accepted
    # a backward jump that is not key-on (t = 300) also needs confirmation
    assert [g.offer(t).accepted for t in (300.0, 301.0, 302.0)] == [False, False, True]


def test_gate_new_time_base_only_after_silence():
    """Beside a live source, agreeing stale or key-on messages (a storm, a second publisher) move nothing."""
    g = SequenceGate(ahead=60.0, confirm=3, silence_s=3.0)
    wall = 0.0
    for t in range(100, 120):
        wall = t - 100.0
        assert g.offer(float(t), wall).accepted
    for i, x in enumerate((0.0, 10.0, 11.0, 12.0, 13.0, 0.0)):  # within 1 s of the last real state
        assert not g.offer(x, wall + 0.1 * i).accepted
    assert g.offer(120.0, wall + 1.0).accepted
    # the source stops; 3 s later a restart is taken
    assert not g.offer(0.0, wall + 2.5).accepted
    v = g.offer(0.0, wall + 4.1)
    assert v.accepted and v.reset


def test_gate_validates_its_settings():
    with pytest.raises(ValueError, match='ahead'):
        SequenceGate(ahead=0.0)
    with pytest.raises(ValueError, match='confirm'):
        SequenceGate(ahead=1.0, confirm=0)


# ---------------------------------------------------------------------------- lockstep buffer
def test_lockstep_buffer_pairs_a_state_with_its_two_previews():
    b = LockstepBuffer(window=4)
    assert b.put_preview('weather', 0, 'w0') is None
    assert b.put_state(0, 's0', now_s=10.0) is None
    assert b.ready() is None  # traffic 0 missing
    assert b.put_preview('traffic', 0, 't0') is None
    assert b.ready() == 0
    assert b.take(0) == ('s0', 'w0', 't0')
    assert b.pending is None and b.last_done == 0
    assert b.put_state(0, 's0 again', 11.0).startswith('stale')
    assert b.put_preview('weather', 5, 'w5').startswith('future')  # beyond 0 + 4
    assert b.put_preview('weather', 4, 'w4') is None
    with pytest.raises(KeyError):
        b.take(3)


def test_lockstep_buffer_overdue_and_superseded_states():
    b = LockstepBuffer(window=10)
    b.put_state(3, 's3', now_s=100.0)
    assert b.overdue(101.9, timeout_s=2.0) is None and b.overdue(102.1, timeout_s=2.0) == 3
    assert b.put_state(4, 's4', now_s=103.0) is None  # the plant moved on: s4 supersedes s3
    assert b.pending == 4
    assert b.put_state(3, 's3', now_s=103.5).startswith('stale')
    assert b.take(4) == ('s4', None, None)
    b.reset()
    assert b.last_done is None and b.pending is None
    # before the first step, previews of any step are kept, at most `window` of them
    for k in range(15):
        b.put_preview('weather', 100 + k, k)
    b.put_state(114, 's', 0.0)
    b.put_preview('traffic', 114, 't')
    assert b.take(114) == ('s', 14, 't')


# ------------------------------------------------------------------- watchdog, fallback, counts
def test_watchdog_and_fallback_supervisor():
    w = Watchdog(2.0)
    assert w.expired(0.0) and w.age(0.0) == math.inf  # never kicked
    w.kick(10.0)
    assert not w.expired(12.0) and w.expired(12.01) and w.age(11.5) == pytest.approx(1.5)
    with pytest.raises(ValueError):
        Watchdog(0.0)
    f = FallbackSupervisor()
    assert f.command_accepted(0, 'ceco') is None
    line = f.command_missing('step 35', 'no command')
    assert line.startswith('FALLBACK at step 35: no command') and f.in_fallback
    assert f.command_missing('step 40', 'no command') is None  # one line per fallback span
    assert f.command_accepted(9, 'ceco') == 'commands resumed at control step 9 from ceco: leaving fallback'
    assert (f.n_entered, f.n_fallback_periods, f.in_fallback) == (1, 2, False)


def test_rejections_counted_and_log_lines_throttled():
    r = Rejections(throttle_s=2.0)
    lines = [r.add('cabin/state', 'invalid', f'bad {i}', now_s=0.1 * i) for i in range(30)]  # 3 s of bursts
    assert lines[0] == 'bad 0'
    logged = [x for x in lines if x]
    assert len(logged) == 2 and logged[1] == 'bad 20 (19 similar rejections since the last line)'
    assert r.add('cabin/state', 'stale', 'old', 0.5) == 'old'  # another kind logs at once
    assert r.total == 31 and r.by_topic == {'cabin/state': 31}
    assert r.summary() == 'cabin/state: 31' and Rejections().summary() == 'none'
    assert [reason_kind(x) for x in ('stale: 1', 'future: 2', 'duplicate: 3', 't=nan is bad: x')] == [
        'stale',
        'future',
        'duplicate',
        'invalid',
    ]


def test_health_levels_and_values():
    h = Health().set('a_ms', 1.23456).set('flag', True).set('none', None)
    assert (h.level, h.message) == (OK, 'OK')
    h.warn('w').error('e').warn('w2')
    assert h.level == ERROR and h.message == 'w; e; w2'
    assert h.values == {'a_ms': '1.235', 'flag': 'true', 'none': 'n/a'}


# ------------------------------------------------------------------------------ field checks
@pytest.mark.parametrize(
    'field, value, expected',
    [
        ('t_cab_c', math.nan, 't_cab_c=nan is not finite'),
        ('t_glass_c', math.inf, 't_glass_c=inf is not finite (NaN means: not set)'),  # NaN: no glazing sensor
        ('rh', -math.inf, 'rh=-inf is not finite (NaN means: not set)'),
        ('rh_cab', math.inf, 'rh_cab=inf is not finite'),
        ('rh_cab', 1.5, 'rh_cab=1.5 is outside the plausible range [0, 1]'),
        ('t_vent_c', 1e300, 't_vent_c=1e+300 is outside'),
        ('speed_mps', -1.0, 'speed_mps=-1.0 is outside'),
        ('mdot_bl_kgps', math.nan, 'mdot_bl_kgps=nan is not finite'),  # the previous command (estimator)
        ('t_evap_sp_c', 2.0, 't_evap_sp_c=2.0 is outside'),
        ('scenario_time_s', 9e18, 'scenario_time_s=9e+18 is outside'),  # preview_node's crash
        ('scenario_time_s', -1.0, 'scenario_time_s=-1.0 is outside'),
        ('co2_cab_ppm', math.nan, 'co2_cab_ppm=nan is not finite'),  # the plant always knows its CO2
        ('co2_cab_ppm', -5.0, 'co2_cab_ppm=-5.0 is outside'),
        ('co2_sensor_ppm', math.inf, 'co2_sensor_ppm=inf is not finite (NaN means: not set)'),
        ('recirc_share', 1.5, 'recirc_share=1.5 is outside the plausible range [0, 1]'),
        ('recirc_share_cmd', -0.1, 'recirc_share_cmd=-0.1 is outside'),
    ],
)
def test_check_state_names_the_field(field, value, expected):
    assert checks.check_state(state(10.0)) is None
    assert checks.check_state(state(10.0, **{field: value})).startswith(expected)


@pytest.mark.parametrize(
    'strategy, law', [('ceco-pmv', ''), ('ceco-ioch', ''), ('baseline', ''), ('baseline', 'baseline_pmv.yaml')]
)
def test_a_car_without_glazing_and_humidity_sensors_is_controlled(strategy, law):
    """A CabinState whose glazing temperature, cabin and ambient humidity are NaN (a car without those sensors)
    passes the field check, and the controller commands every control step from its own law, inside the actuator
    bounds, without a step error or a rejected message (before, every such state was refused as not finite: the
    node never commanded). The core takes them as not measured (ceco_core.observation_check); the PI on the PMV
    (baseline_pmv.yaml) measures it as ceco-pmv does, with the interior for the glazing and the paper's 1700 Pa
    for the humidity, and regulates (it held its command as at a sensor fault, for good)."""
    from ceco_controller.controller_session import ControllerSession
    from ceco_controller.model import package_config_path
    from ceco_core.contracts import (
        MDOT_BL_MAX_KGPS,
        MDOT_BL_MIN_KGPS,
        RECIRC_SHARE_MAX,
        RECIRC_SHARE_MIN,
        T_EVAP_SP_MAX_C,
        T_EVAP_SP_MIN_C,
    )

    missing = {'t_glass_c': math.nan, 'rh_cab': math.nan, 'rh': math.nan}
    assert checks.check_state(state(10.0, **missing)) is None
    table = controller_parameters('baseline' if strategy == 'baseline' else None)
    config = str(package_config_path(law)) if law else ''
    cfg = ControllerNodeConfig.from_params(
        {s.name: s.default for s in table} | {'strategy': strategy, 'controller_config': config}
    )
    logs: list = []
    session = ControllerSession(cfg, lambda level, text: logs.append((level, text)), lambda *_: None)
    assert session.configure(cfg)
    results = []
    for k in range(6):
        wall = 0.1 * k
        results += session.on_preview('weather', weather(k), wall, True)
        results += session.on_preview('traffic', traffic(k), wall, True)
        results += session.on_state(state(5.0 * k, **missing), wall, 5.0 * k, True)
    assert [r.k for r in results] == list(range(6)), (results, logs)
    for r in results:
        assert MDOT_BL_MIN_KGPS <= r.command.mdot_bl_kgps <= MDOT_BL_MAX_KGPS, r
        assert T_EVAP_SP_MIN_C <= r.command.t_evap_sp_c <= T_EVAP_SP_MAX_C, r
        share = r.command.recirc_share
        assert math.isnan(share) or RECIRC_SHARE_MIN <= share <= RECIRC_SHARE_MAX, r
        assert not r.fallback and r.diagnostics.status != 'sensor_fault', (r.k, r.diagnostics.status, logs)
    if law:  # the law regulates the PMV: its diagnostics carry a finite measured PMV
        for r in results:
            pmv = float(r.diagnostics.message.split('pmv_measured=')[1].split()[0])
            assert math.isfinite(pmv), r.diagnostics.message
    assert session.record.counts['step_errors'] == 0, logs
    assert session.inputs.rejections.summary() == 'none', session.inputs.rejections.summary()


def test_mpc_node_runs_the_named_variant_ceco_pmv_aq(tmp_path):
    """README, "Which controller to use": mpc_node's ``strategy:=ceco-pmv-aq`` is ceco-pmv with the CO2-holding door.
    It commands the door (a share in 0..1 each step) where ceco-pmv leaves it to the plant (NaN), its commands equal
    those of ceco-pmv with ``door_control: co2_hold`` in a copy of the controller file (the long way), and its
    AcCommand names it and passes the plant's check. An unknown name is refused, naming the values."""
    import yaml

    import ceco_ros.conversions as conversions
    from ceco_controller.controller_session import ControllerSession
    from ceco_controller.model import package_config_path

    doc = yaml.safe_load(package_config_path('controller.yaml').read_text())
    doc['strategies']['ceco-pmv']['door_control'] = 'co2_hold'
    aq = tmp_path / 'controller_aq.yaml'
    aq.write_text(yaml.safe_dump(doc))
    commands = {}
    for name, strategy, path in (
        ('ceco-pmv', 'ceco-pmv', ''),
        ('named', 'ceco-pmv-aq', ''),
        ('long way', 'ceco-pmv', str(aq)),
    ):
        cfg = _ctrl_cfg(strategy=strategy, controller_config=path)
        session = ControllerSession(cfg, lambda *_: None, lambda *_: None)
        assert session.configure(cfg)
        results = []
        for k in range(3):
            results += session.on_preview('weather', weather(k), 0.1 * k, True)
            results += session.on_preview('traffic', traffic(k), 0.1 * k, True)
            results += session.on_state(state(5.0 * k, co2_sensor_ppm=900.0), 0.1 * k, 5.0 * k, True)
        assert [r.k for r in results] == [0, 1, 2] and not any(r.fallback for r in results)
        commands[name] = [(r.command.mdot_bl_kgps, r.command.t_evap_sp_c, r.command.recirc_share) for r in results]
        msg = conversions.command_msg(results[-1].command, 2, stamp(10.0), 5.0, cfg.strategy, False)
        assert msg.strategy == strategy and checks.check_command(msg, 5.0) is None
    assert all(math.isnan(c[2]) for c in commands['ceco-pmv']), commands
    assert all(0.0 <= c[2] <= 1.0 for c in commands['named']), commands
    assert commands['named'] == commands['long way']
    with pytest.raises(ValueError, match='must be one of ceco, ceco-e, ceco-c, ceco-ioch, ceco-pmv, ceco-pmv-aq'):
        _ctrl_cfg(strategy='ceco-pmv-co2')


def test_check_stamps():
    assert checks.check_stamp('s', NS(sec=0, nanosec=10**9)).startswith('s.nanosec=1000000000')
    assert checks.check_stamp('s', NS(sec=-2_000_000_000, nanosec=0)).startswith('s.sec=-2000000000')  # 1906
    assert checks.check_stamp('s', NS(sec=STAMP_MAX_S, nanosec=0)) is None  # 2038
    st = state(10.0, stamp_s=11.0)
    assert 'does not match the scenario time 10' in checks.check_stamp_equals('header.stamp', st.header.stamp, 10.0)
    assert checks.check_stamp_age('h', stamp(100.0), now_s=105.0, max_age_s=10.0, max_ahead_s=1.0) is None
    assert 'old' in checks.check_stamp_age('h', stamp(100.0), 111.0, 10.0, 1.0)
    assert 'ahead of the clock' in checks.check_stamp_age('h', stamp(100.0), 98.0, 10.0, 1.0)


def test_check_command_every_field():
    assert checks.check_command(command(3), 5.0) is None
    # the door: -1 (the default) or NaN leave it to the plant, 0..1 command it; anything else is refused
    for ok in (-1.0, math.nan, 0.0, 0.5, 1.0):
        assert checks.check_command(command(3, recirc_share=ok), 5.0) is None, ok
    assert checks.check_state(state(10.0, co2_sensor_ppm=math.nan)) is None  # no sensor, or a failed one
    cases = {
        'recirc_share': (-0.5, 1.2, math.inf, -math.inf),
        'control_period_s': (0.0, -5.0, math.nan, 5.1),
        'blower_flow_kgps': (math.nan, 0.5, 0.0, 1e300),
        'evap_setpoint_c': (-math.inf, 11.0),
        'strategy': ('turbo', 'plant-fallback', ''),
    }
    for field, values in cases.items():
        for v in values:
            assert checks.check_command(command(3, **{field: v}), 5.0), (field, v)
    bad_stamp = command(3)
    bad_stamp.header.stamp = NS(sec=1, nanosec=2**32 - 1)
    assert 'nanosec' in checks.check_command(bad_stamp, 5.0)


def test_check_preview_every_field():
    assert checks.check_preview(weather(2), 'weather', 7, 5.0) is None
    assert checks.check_preview(traffic(2), 'traffic', 7, 5.0) is None
    nan7 = [math.nan] * 7
    assert checks.check_preview(weather(2, t_amb_c=nan7, valid=[False] * 7), 'weather', 7, 5.0) is None
    bad = {
        't_amb_c': [35.0] * 3,
        'solar_wm2': [math.inf] + [800.0] * 6,
        'rh': [math.nan] * 7,
        'valid': [True] * 8,
        'step_s': 0.0,
        'age_s': math.nan,
    }
    for field, v in bad.items():
        assert checks.check_preview(weather(2, **{field: v}), 'weather', 7, 5.0), field
    assert 'outside' in checks.check_preview(weather(2, t_amb_c=[1e6] * 7), 'weather', 7, 5.0)
    assert 'age_s' in checks.check_preview(traffic(2, age_s=-5.0), 'traffic', 7, 5.0)
    assert checks.check_preview(traffic(2, age_s=-1.0), 'traffic', 7, 5.0) is None  # none received
    assert 'different times' in checks.check_preview_pair(weather(2), traffic(3))
    # one fault in one sample of one array, at a valid and at an invalid sample: the check refuses exactly the
    # faults that matter and names the array
    valid = [True, True, False, True, True, True, True]
    for kind, make in (('weather', weather), ('traffic', traffic)):
        for name in checks.PREVIEW_ARRAYS[kind]:
            lo, hi = checks.PREVIEW_RANGES[name]
            for fault, needle in (
                (math.inf, 'infinite'),
                (math.nan, 'NaN'),
                (lo - 1.0, 'outside'),
                (hi + 1.0, 'outside'),
            ):
                for i in (1, 2):  # sample 2 is not valid: only an infinite value there is refused
                    values = list(getattr(make(2), name))
                    values[i] = fault
                    why = checks.check_preview(make(2, **{name: values, 'valid': valid}), kind, 7, 5.0)
                    if i == 2 and needle != 'infinite':
                        assert why is None, (name, fault, i, why)
                    else:
                        assert why and why.startswith(name) and needle in why, (name, fault, i, why)


def test_honest_plant_states_pass_the_checks():
    """The plausibility ranges accept every state the plant produces on SC03 (600 s, ACC law)."""
    from ceco_core.acc_law import AccLaw
    from ceco_core.contracts import AcInput
    from ceco_plant_sim.scenario_plant import ScenarioPlant
    from ceco_v2x_preview.scenario import load_scenario

    sc = load_scenario('sc03')
    sp, law = ScenarioPlant(sc, 1.0), AccLaw()
    u = sp.cmd
    for n in range(600):
        env = sc.env_at(float(n))
        msg = state(
            float(n),
            **sp.meas,
            t_amb_c=env.t_amb_c,
            solar_wm2=env.solar_wm2,
            rh=env.rh,
            speed_mps=env.speed_mps,
            mdot_bl_kgps=u.mdot_bl_kgps,
            t_evap_sp_c=u.t_evap_sp_c,
        )
        assert checks.check_state(msg) is None, (n, checks.check_state(msg))
        if n % 5 == 0:
            a = law.step(sp.meas['t_cab_c'], 5.0)
            u = AcInput(mdot_bl_kgps=a.mdot_bl_kgps, t_evap_sp_c=a.t_evap_sp_c)
        sp.step(u)


# -------------------------------------------------------------------------- parameter tables
def test_parameter_tables_defaults_are_valid_and_named_once():
    from ceco_plant_sim.plant_io import PLANT_PARAMETERS

    for table in (controller_parameters(), controller_parameters('baseline'), PLANT_PARAMETERS, PREVIEW_PARAMETERS):
        names = [s.name for s in table]
        assert len(names) == len(set(names))
        for spec in table:
            assert check_value(spec, spec.default)[1] is None, spec.name
            assert '[' in spec.description or spec.choices or isinstance(spec.default, (str, bool)), spec.name
    spec = ParamSpec('x_s', 1.0, 'x [s]', float_range=(0.0, 2.0))
    assert check_value(spec, 2) == (2.0, None)
    assert 'must lie in' in check_value(spec, 3.0)[1] and 'finite' in check_value(spec, math.nan)[1]
    assert 'one of' in check_value(ParamSpec('t', 'a', 'd', choices=('a', 'b')), 'c')[1]


def _ctrl_cfg(**kw) -> ControllerNodeConfig:
    values = {s.name: s.default for s in controller_parameters()}
    values.update(kw)
    return ControllerNodeConfig.from_params(values)


def test_controller_config_validation_and_runtime_changes():
    cfg = _ctrl_cfg()
    assert (cfg.strategy, cfg.window_steps) == ('ceco-ioch', 12)
    with pytest.raises(ValueError, match="strategy='ceco-turbo': unknown strategy"):
        _ctrl_cfg(strategy='ceco-turbo')
    assert cfg.replaced({'preview_timeout_s': 0.5}).preview_timeout_s == 0.5
    with pytest.raises(ValueError, match='preview_timeout_s'):
        cfg.replaced({'preview_timeout_s': -1.0})


def test_a_controller_config_with_a_key_nothing_reads_fails_configure(tmp_path):
    """mpc_node's `controller_config` goes through the same loader: a file with `strategies:` misspelt ran on the
    defaults; now configure raises a ValueError naming the file and the key, which mpc_node logs as `configure
    failed: ...` and answers FAILURE (the node stays unconfigured, docs/ros.md), no crash loop."""
    from ceco_controller.controller_session import ControllerSession
    from ceco_controller.model import package_config_path

    typo = tmp_path / 'typo.yaml'
    typo.write_text(package_config_path('controller.yaml').read_text().replace('\nstrategies:\n', '\nstrategy:\n'))
    cfg = _ctrl_cfg(strategy='ceco-pmv', controller_config=str(typo))
    session = ControllerSession(cfg, lambda *_: None, lambda *_: None)
    with pytest.raises(ValueError, match=rf"^{re.escape(str(typo))}: unknown top-level key\(s\) 'strategy': "):
        session.configure(cfg)


def test_node_configs_share_names_timing_and_positive_rules():
    """Every node's config maps its dotted parameter names to fields, refuses an unknown timing and a
    non-positive period (ceco_ros.params.NodeConfig), and replaced() validates and keeps the rest."""
    preview = PreviewNodeConfig.from_params({s.name: s.default for s in PREVIEW_PARAMETERS})
    for cfg, period in ((_ctrl_cfg(), 'window_s'), (_plant_cfg(), 'control_period_s'), (preview, 'window_s')):
        new = cfg.replaced({'inputs.log_throttle_s': 7.5, 'diagnostics.period_s': 0.25})
        assert (new.log_throttle_s, new.diagnostics_period_s, new.timing) == (7.5, 0.25, cfg.timing)
        assert (cfg.log_throttle_s, cfg.diagnostics_period_s) == (2.0, 1.0)  # frozen: the original is kept
        with pytest.raises(ValueError, match="invalid parameter timing='sometimes': must be one of"):
            cfg.replaced({'timing': 'sometimes'})
        bad = {'inputs.window_s': math.nan} if period == 'window_s' else {'control_period_s': 0.0}
        with pytest.raises(ValueError, match=f'invalid parameter {period}='):
            cfg.replaced(bad)
    with pytest.raises(ValueError, match=r'invalid parameter window_s=nan: must be finite and > 0'):
        _ctrl_cfg(**{'inputs.window_s': math.nan})
    assert _plant_cfg().replaced({'lockstep.min_command_subscribers': 2}).min_command_subscribers == 2
    assert _ctrl_cfg().replaced({'lockstep.min_command_subscribers': 2}).min_command_subscribers == 2


# ------------------------------------------------------------------------- controller inputs
class Recorder:
    def __init__(self):
        self.lines, self.resets = [], 0

    def log(self, level, text):
        self.lines.append((level, text))

    def reset(self):
        self.resets += 1


def test_controller_lockstep_latch_case_recovers():
    """A state 1e6 s ahead is rejected without moving anything: the next steps are computed."""
    rec = Recorder()
    ci = ControllerInputs(_ctrl_cfg(), rec.log, rec.reset)
    done = []
    for k in range(4):
        if k == 2:
            assert not ci.offer_state(state(1e6 + 10.0, n=1_000_010), 0.0, 0.0)
        for n in range(5 * k, 5 * k + 5):
            assert ci.offer_state(state(float(n)), wall_s=float(n), clock_s=0.0)
            if n == 5 * k:  # the preview node answers the state of step k
                assert ci.offer_preview('weather', weather(k), n) and ci.offer_preview('traffic', traffic(k), n)
            si = ci.ready()
            if si is not None:
                done.append((si.k, si.weather is not None))
    assert done == [(0, True), (1, True), (2, True), (3, True)]
    assert ci.rejections.by_topic == {'cabin/state': 1} and rec.resets == 0
    assert any('future' in t for _, t in rec.lines)


def test_controller_restart_resets_and_rejects_inconsistent_previews():
    rec = Recorder()
    ci = ControllerInputs(_ctrl_cfg(), rec.log, rec.reset)
    for n in range(50, 56):
        ci.offer_state(state(float(n)), float(n), 0.0)
    assert not ci.offer_preview('weather', weather(10, start=stamp(49.0)), 1.0)  # start is not t_10
    assert not ci.offer_preview('traffic', traffic(10, speed_mps=[math.nan] * 7), 1.0)
    assert ci.rejections.by_topic == {'v2x/weather_preview': 1, 'v2x/traffic_preview': 1}
    ci.offer_state(state(0.0), 60.0, 0.0)  # plant restarted: key-on
    assert rec.resets == 1 and ci.gate.last == 0.0
    assert ci.offer_preview('weather', weather(0), 61.0) and ci.offer_preview('traffic', traffic(0), 61.0)
    si = ci.ready()
    assert si is not None and si.k == 0 and si.weather is not None and ci.ready() is None
    # a state without previews comes out after the preview timeout, marked
    ci.offer_state(state(5.0), 100.0, 0.0)
    assert ci.overdue(101.0) is None
    si = ci.overdue(102.5)
    assert si.k == 1 and si.weather is None and 'no weather and traffic preview within 2.0 s' == si.note


def test_controller_realtime_inputs():
    rec = Recorder()
    ci = ControllerInputs(_ctrl_cfg(timing='realtime'), rec.log, rec.reset)
    si, why = ci.realtime_step(100.0)
    assert si is None and 'no valid cabin/state' in why
    ci.offer_state(state(43.0, stamp_s=1000.0), wall_s=0.0, clock_s=1000.2)
    ci.offer_state(state(44.0, stamp_s=1500.0), wall_s=0.0, clock_s=1000.2)  # stamp 500 s ahead: rejected
    ci.offer_state(state(1e6, stamp_s=1000.5), wall_s=0.0, clock_s=1000.6)  # far future time: rejected
    assert ci.gate.last == 43.0 and ci.rejections.total == 2
    si, _ = ci.realtime_step(1001.0)
    assert si.k == 8 and si.weather is None and 'no valid weather and traffic preview' in si.note
    ci.offer_preview('weather', weather(1_000_000, start=stamp(5e6)), 0.0)  # wedged-preview case: rejected
    ci.offer_preview('weather', weather(8, start=stamp(40.0)), 0.0)
    ci.offer_preview('traffic', traffic(8, start=stamp(40.0)), 0.0)
    # one command per control step: a tick on a state of step 8 again is due for step 9's first state
    assert ci.realtime_step(1003.0) == (None, '') and not ci.due()
    ci.offer_state(state(44.0, stamp_s=1004.0), wall_s=1.0, clock_s=1004.0)
    assert not ci.due()  # 44 s is still step 8
    ci.offer_state(state(45.0, stamp_s=1005.0), wall_s=2.0, clock_s=1005.0)
    assert ci.due()
    si, _ = ci.realtime_step(1005.1)
    assert si.k == 9 and si.weather is not None and si.note == '' and not ci.due()
    assert ci.rejections.by_topic['v2x/weather_preview'] == 1
    ci.offer_state(state(50.0, stamp_s=1000.0), wall_s=3.0, clock_s=1000.1)
    si, why = ci.realtime_step(1011.0)  # the state is now 11 s old
    assert si is None and '11.0 s old' in why


def test_controller_health_levels():
    cfg = _ctrl_cfg()
    common = dict(
        cfg=cfg, counts={'steps': 3}, ages_s={'state': 0.1}, rejections=Rejections(), new_rejections=0, events={}
    )
    assert controller_health(lifecycle='inactive', last=None, **common).level == WARN
    ok = controller_health(lifecycle='active', last={'k': 3, 'step_time_ms': 4.0, 'fallback': ''}, **common)
    assert ok.level == OK and ok.values['deadline_ms'] == '5000' and ok.values['last_step'] == '3'
    slow = controller_health(lifecycle='active', last={'k': 3, 'step_time_ms': 3000.0, 'fallback': ''}, **common)
    assert slow.level == WARN and 'above 50% of the step deadline (5000 ms)' in slow.message
    budget = controller_health(
        lifecycle='active', last={'k': 3, 'step_time_ms': 10.8, 'fallback': ''}, deadline_s=0.002, **common
    )  # the NMPC's own step budget
    assert budget.level == ERROR and 'beyond the step deadline (2 ms)' in budget.message
    assert budget.values['deadline_ms'] == '2'
    late = controller_health(lifecycle='active', last={'k': 3, 'step_time_ms': 6000.0, 'fallback': ''}, **common)
    assert late.level == ERROR
    fb = controller_health(
        lifecycle='active',
        last={'k': 3, 'step_time_ms': 4.0, 'fallback': 'baseline', 'reason': 'solve failed'},
        **common,
    )
    assert fb.level == ERROR and 'production ACC law applied (solve failed)' in fb.message
    r = Rejections()
    r.add('cabin/state', 'invalid', 'x', 0.0)
    rej = controller_health(
        lifecycle='active',
        last={'k': 3, 'step_time_ms': 4.0, 'fallback': ''},
        **dict(common, rejections=r, new_rejections=1),
    )
    assert rej.level == WARN and rej.values['rejected cabin/state'] == '1'


# ----------------------------------------------------------------------------- plant policy
def _plant_cfg(**kw):
    from ceco_plant_sim.plant_io import PLANT_PARAMETERS, PlantNodeConfig

    values = {s.name: s.default for s in PLANT_PARAMETERS}
    values.update(kw)
    return PlantNodeConfig.from_params(values)


def test_plant_command_policy_lockstep_and_realtime():
    from ceco_plant_sim.plant_io import CommandPolicy

    rec = Recorder()
    strict = CommandPolicy(_plant_cfg(), rec.log)  # the default: sequenced commands only (issue 17 item 6)
    assert not strict.accept(command(3), 3, 0.0)  # epoch 0: refused as foreign, says what to set
    assert strict.rejections.by_kind == {('hvac/command', 'foreign'): 1}
    assert 'set AcCommand.epoch (random, non-zero' in rec.lines[-1][1] and 'sequence = 1, 2' in rec.lines[-1][1]
    assert strict.accept(command(3, epoch=0xCEC0, sequence=1), 3, 0.0) and strict.source.epoch == 0xCEC0
    rec = Recorder()
    p = CommandPolicy(_plant_cfg(**{'commands.require_sequence': False}), rec.log)  # opted out
    assert p.accept(command(3), 3, 0.0)
    assert not p.accept(command(200_003), 3, 0.0) and not p.accept(command(2), 3, 0.0)
    assert not p.accept(command(3, stamp_s=14.0), 3, 0.0)  # stamp is not t_3
    assert not p.accept(command(3, control_period_s=0.0), 3, 0.0)
    assert p.accept(command(3, fallback=True), 3, 0.0) and p.n_controller_fallback == 1
    assert p.rejections.total == 4 and p.rejections.by_kind == {
        ('hvac/command', 'future'): 1,
        ('hvac/command', 'stale'): 1,
        ('hvac/command', 'invalid'): 2,
    }
    # the binding to an unsequenced source (said once), then the rejections; the second invalid
    # one within the throttle period
    assert len(rec.lines) == 4 and 'without epoch/sequence' in rec.lines[0][1]
    rt = CommandPolicy(
        _plant_cfg(timing='realtime', plant_dt_s=0.5, control_period_s=2.0, **{'commands.require_sequence': False}),
        rec.log,
    )
    for n in range(40):  # states of plant steps 0..39 at clock 1000 + n/2
        rt.published(stamp(1000.0 + 0.5 * n), 0.5 * n)
    assert rt.accept(command(9, ts=2.0, stamp_s=1000.0 + 0.5 * 37), 9, 0.0)  # t = 18.5 s: step 9
    assert not rt.accept(command(10, ts=2.0, stamp_s=1000.0 + 0.5 * 37), 9, 0.0)  # index not the stamp's step
    assert not rt.accept(command(9, ts=2.0, stamp_s=2038.0), 9, 0.0)  # a stamp the plant never sent
    assert not rt.accept(command(0, ts=2.0, stamp_s=1000.0), 9, 0.0)  # the ring forgot it: too old
    assert not rt.accept(command(4, ts=2.0, stamp_s=1000.0 + 0.5 * 19), 9, 0.0)  # 5 steps behind (limit 2)


def test_plant_loop_lockstep_energy_end_and_fallback_law():
    from ceco_core.acc_law import AccLaw
    from ceco_core.contracts import AcInput
    from ceco_plant_sim.plant_loop import PlantLoop
    from ceco_plant_sim.scenario_plant import ScenarioPlant
    from ceco_v2x_preview.scenario import load_scenario

    sc = load_scenario('sc03')
    loop, ref = PlantLoop(sc, _plant_cfg(duration_s=12.0)), ScenarioPlant(sc, 1.0)
    assert (loop.m, loop.n_steps, loop.k) == (5, 12, 0)
    u = AcInput(mdot_bl_kgps=0.12, t_evap_sp_c=4.0)
    e_comp = e_blower = 0.0
    for n in range(12):
        assert not loop.finished and loop.n == n and loop.k == n // 5
        r, r_ref = loop.step(u), ref.step(u)
        e_comp, e_blower = e_comp + r_ref.out.e_comp_j, e_blower + r_ref.out.e_blower_j
        assert r.meas == r_ref.meas and r.pmv == r_ref.pmv  # the simulator's own core, bit for bit
    assert loop.finished and loop.n == 12 and (loop.e_comp_j, loop.e_blower_j) == (e_comp, e_blower) and e_comp > 0
    assert loop.summary() == f'scenario complete: 12 plant steps, E_comp {e_comp:.0f} J, E_blower {e_blower:.0f} J'
    with pytest.raises(RuntimeError, match='finished'):
        loop.step(u)

    # no command: the ACC law from its reset state drives, the warning once per fallback
    loop, acc = PlantLoop(sc, _plant_cfg()), AccLaw()
    cmds = []
    for i in range(3):
        u_fb, line = loop.fallback_command('no command for control step 0')
        a = acc.step(loop.sp.meas['t_cab_c'], 5.0)
        assert (u_fb.mdot_bl_kgps, u_fb.t_evap_sp_c) == (a.mdot_bl_kgps, a.t_evap_sp_c)
        assert (line is not None) == (i == 0)
        cmds.append(u_fb)
        for _ in range(loop.m):
            loop.step(u_fb)
    assert line is None and loop.fallback.n_fallback_periods == 3 and loop.fallback.n_entered == 1
    from ceco_core.contracts import MDOT_BL_MAX_KGPS, T_EVAP_SP_MIN_C

    # a hot cabin at key-on (sc03: about 43 degC): full cooling in every fallback period
    assert set(cmds) == {AcInput(mdot_bl_kgps=MDOT_BL_MAX_KGPS, t_evap_sp_c=T_EVAP_SP_MIN_C)}
    u_fb, first = PlantLoop(sc, _plant_cfg()).fallback_command('why')
    assert first == 'FALLBACK at step 0 (t=0.0 s): why; applying the production ACC law until commands resume'


def test_plant_loop_realtime_input_choice():
    from ceco_core.contracts import AcInput
    from ceco_plant_sim.plant_loop import PlantLoop
    from ceco_v2x_preview.scenario import load_scenario

    loop = PlantLoop(load_scenario('sc03'), _plant_cfg(timing='realtime'))  # Ts 5 s, dt 1 s: stale after 6 s
    u = AcInput(mdot_bl_kgps=0.1, t_evap_sp_c=5.0)

    def tick(now_s):
        got = loop.realtime_input(now_s)
        loop.step(got[0])
        return got

    u0, fb, line = tick(0.0)  # nothing yet: the ACC law, with the warning
    assert fb and line.startswith('FALLBACK at step 0') and 'latest none yet, limit 6.0 s' in line
    assert loop.accept_command(u, 0, 'ceco', 0.5) == 'commands resumed at control step 0 from ceco: leaving fallback'
    assert tick(1.0) == (u0, True, None)  # in fallback, a fresh command waits for the control step boundary
    for t in (2.0, 3.0, 4.0):
        assert tick(t)[1:] == (True, None)
    assert tick(5.0) == (u, False, None)  # boundary: the fresh command drives
    assert tick(6.0) == (u, False, None)  # 5.5 s old: within one control period plus one plant step (6 s)
    u_fb, fb, line = tick(7.0)  # 6.5 s old: one plant step after command 1 was due, the ACC law at once
    assert fb and 'latest 6.5 s old' in line and u_fb != u
    assert loop.accept_command(u, 1, 'ceco', 7.5) is not None
    loop.liveliness_changed(0, 1, 7.6)  # the controller's process died: even a young command is stale
    u_fb, fb, line = tick(8.0)  # back to the law at the next tick
    assert fb and "the controller's liveliness was lost" in line
    # a liveliness loss is also a deactivated or shut-down node of a living process: the line claims no one cause
    assert 'its process is gone or frozen, or its node was deactivated or shut down' in line
    assert tick(9.0)[1:] == (True, None)  # the law drives until a command is accepted
    assert loop.accept_command(u, 2, 'ceco', 9.5) is not None  # a new command (a restarted controller)
    assert loop.n == 10 and tick(10.0) == (u, False, None)  # taken at the boundary
    assert loop.fallback.n_entered == 3 and loop.fallback.n_fallback_periods == 3


def test_control_step_grid_of_plant_times():
    """The control step of a time n * dt, with its float rounding (0.01 * 30 = 0.30000000000000004,
    0.3 / 0.1 = 2.9999999999999996): the same step as the plant's integer count n // m, for every
    plant step and control period the parameter tables allow here."""
    from ceco_core.control_grid import control_step_index, control_step_of

    assert int(0.01 * 30 // 0.1) == 2  # the floor division the nodes used: one step behind
    assert control_step_of(0.01 * 30, 0.1) == 3
    for dt, ts in ((0.01, 0.1), (0.1, 0.3), (0.2, 1.0), (0.5, 2.0), (1.0, 5.0), (0.05, 0.15)):
        m = round(ts / dt)
        for n in range(0, 40 * m):
            t = n * dt
            assert control_step_of(t, ts) == n // m, (dt, ts, n)
            assert control_step_index(t, ts) == (n // m if n % m == 0 else None), (dt, ts, n)
    assert control_step_of(14.999, 5.0) == 2 and control_step_of(15.0, 5.0) == 3


def test_whole_and_floor_steps_of_decimal_times():
    """The one test of "a whole number of steps" (a run's length, Ts over the plant step or the model step): decimal
    times whose quotient carries float rounding are whole (0.3 / 0.1 = 2.9999999999999996), others are not; the
    floor counts a time just below a step boundary by rounding as that step."""
    from ceco_core.control_grid import floor_steps, whole_steps

    assert whole_steps(0.3, 0.1) == 3 and whole_steps(600.0, 1.0) == 600 and whole_steps(15.0, 5.0) == 3
    assert whole_steps(123.7, 1.0) is None and whole_steps(7.0, 5.0) is None and whole_steps(0.1, 1.0) is None
    assert whole_steps(5.0 + 1e-12, 5.0) == 1 and whole_steps(5.0 + 1e-7, 5.0) is None
    assert floor_steps(20.7, 1.0) == 20 and floor_steps(0.3, 0.1) == 3 and floor_steps(0.99, 1.0) == 0


def test_plant_health():
    from ceco_plant_sim.plant_io import CommandPolicy, plant_health

    cfg = _plant_cfg()
    f = FallbackSupervisor()
    p = CommandPolicy(cfg, lambda *_: None)
    h = plant_health(
        cfg=cfg,
        started=True,
        finished=False,
        n=10,
        t_s=10.0,
        supervisor=f,
        command_age_s=0.1,
        policy=p,
        new_rejections=0,
        events={},
    )
    assert h.level == OK
    f.command_missing('step 10', 'no command for control step 2')
    h = plant_health(
        cfg=cfg,
        started=True,
        finished=False,
        n=10,
        t_s=10.0,
        supervisor=f,
        command_age_s=6.0,
        policy=p,
        new_rejections=0,
        events={'incompatible_qos': 1},
    )
    assert h.level == ERROR and 'fallback: the production ACC law drives (no command for control step 2)' in h.message
    assert h.values['in_fallback'] == 'true'
    # a second lockstep plant in the domain (one /clock per domain): an error that says what to do
    common = dict(started=True, finished=False, n=10, t_s=10.0, command_age_s=0.1, new_rejections=0, events={})
    ok = plant_health(cfg=cfg, supervisor=FallbackSupervisor(), policy=p, clock_publishers=1, **common)
    assert ok.level == OK and ok.values['clock_publishers'] == '1'
    two = plant_health(cfg=cfg, supervisor=FallbackSupervisor(), policy=p, clock_publishers=2, **common)
    assert two.level == ERROR and '2 publishers on /clock in this ROS domain' in two.message
    assert 'ROS_DOMAIN_ID of its own' in two.message
    rt = _plant_cfg(timing='realtime')  # a real-time plant publishes no /clock and does not report it
    assert 'clock_publishers' not in plant_health(cfg=rt, supervisor=FallbackSupervisor(), policy=p, **common).values


# --------------------------------------------------------------------------- preview inputs
def test_preview_inputs_reject_crash_and_wedge_cases():
    values = {s.name: s.default for s in PREVIEW_PARAMETERS}
    cfg = PreviewNodeConfig.from_params(values)
    rec = Recorder()
    pi = PreviewInputs(cfg, rec.log)
    for t in range(20):
        assert pi.offer_state(state(float(t)), float(t), 0.0) is not None
    assert pi.offer_state(state(9e18, stamp_s=0.0), 20.0, 0.0) is None  # the crash case
    assert pi.offer_state(state(1e6 + 19.0, stamp_s=1e6 + 19.0), 20.0, 0.0) is None  # the wedge case
    assert pi.offer_state(state(20.0), 21.0, 0.0) is not None and pi.gate.last == 20.0
    assert pi.rejections.total == 2
    assert pi.offer_state(state(0.0), 22.0, 0.0) is None  # key-on while the plant speaks: no
    v = pi.offer_state(state(0.0), 30.0, 0.0)  # after 9 s of silence: a restart
    assert v.reset and pi.n_resets == 1
    h = preview_health(
        cfg=cfg, inputs=pi, last_k=0, n_published=5, n_failed=0, last_error='', wall_s=22.0, new_rejections=0
    )
    assert h.level == OK
    with pytest.raises(ValueError, match='even number'):
        PreviewNodeConfig.from_params(dict(values, **{'faults.missing_spans_s': [1.0, 2.0, 3.0]}))


# ------------------------------------------------------------------------ node controller
def test_node_controller_builds_steps_and_resets():
    """mpc_node's controller side without ROS: the simulator's observation and core, the previous command."""
    from ceco_controller.controller_io import StepInputs
    from ceco_controller.step_adapter import NodeController
    from ceco_core.acc_law import AccLaw

    with pytest.raises(ValueError, match="invalid parameter scenario='no_such_scenario'"):
        NodeController(_ctrl_cfg(strategy='baseline', scenario='no_such_scenario'))
    cfg = _ctrl_cfg(strategy='baseline')
    ctl = NodeController(cfg)
    assert ctl.step_budget_s is None and ctl.prev_cmd is None and ctl.scenario.name == 'sc03'
    law = AccLaw()
    for k in range(3):
        st = state(5.0 * k, n=5 * k, t_cab_c=45.0 - k)
        cmd, diag, note = ctl.step(StepInputs(k, st), cfg)
        assert note == 'no previews' and not diag.fallback and ctl.prev_cmd is cmd
        # the same law on the same observation (key-on command from the state, then its own)
        a = law.step(st.t_cab_c, cfg.control_period_s)
        assert (cmd.mdot_bl_kgps, cmd.t_evap_sp_c) == (a.mdot_bl_kgps, a.t_evap_sp_c)
    ctl.reset()
    assert ctl.prev_cmd is None
    again, _, _ = ctl.step(StepInputs(0, state(0.0, n=0)), cfg)  # from a fresh law: the first command again
    first = AccLaw().step(45.0, cfg.control_period_s)
    assert (again.mdot_bl_kgps, again.t_evap_sp_c) == (first.mdot_bl_kgps, first.t_evap_sp_c)
    ctl.settle()  # the ACC law has nothing to do after its command
    ncfg = _ctrl_cfg(strategy='ceco')
    nmpc = NodeController(ncfg)
    assert nmpc.warm_up == 'NmpcController.warm_up' and 0 < nmpc.step_budget_s < cfg.control_period_s
    # the NMPC's model predictions for its next step wait until the node has sent the command (settle)
    _, diag, _ = nmpc.step(StepInputs(0, state(0.0, n=0)), ncfg)
    assert diag.success and nmpc.core._pending is not None and nmpc.core._bias.last_pred is None
    nmpc.settle()
    assert nmpc.core._pending is None and nmpc.core._bias.last_pred is not None


def test_session_settle_failure_is_logged_and_counted_not_raised():
    """The work after the command runs outside the step's own guard: a failure there is logged and counted as a
    step error (as a failing step is), the node's callback does not raise, and the next settle has nothing left."""
    from ceco_controller.controller_io import StepInputs
    from ceco_controller.controller_session import ControllerSession

    logs = []
    cfg = _ctrl_cfg(strategy='ceco')
    session = ControllerSession(cfg, lambda level, text: logs.append((level, text)), lambda *_: None)
    session.settle(0)  # not configured: nothing to do
    session.configure(cfg)
    _, diag, _ = session.ctl.step(StepInputs(0, state(0.0, n=0)), cfg)
    assert diag.success and session.ctl.core._pending is not None
    obs, ex, cmd = session.ctl.core._pending
    session.ctl.core._pending = (obs, {}, cmd)  # previews without t_amb: the prediction cannot be made
    session.settle(7)
    assert session.record.counts['step_errors'] == 1 and session.record.last['k'] == 7
    assert logs and logs[-1][0] == 'error' and logs[-1][1].startswith('step 7: after the command: KeyError')
    assert session.ctl.core._pending is None
    session.settle(8)
    assert session.record.counts['step_errors'] == 1


# --------------------------------------------------------------------------------- warm-up
def test_warm_up_leaves_no_state_behind():
    """configure's throw-away first solve: the next steps equal a fresh controller's, bit for bit."""
    from ceco_controller import factory
    from ceco_controller.controller_io import warm_up
    from ceco_controller.observation import observation
    from ceco_core.contracts import AcInput
    from ceco_v2x_preview.preview import PreviewQuality, make_previews
    from ceco_v2x_preview.scenario import load_scenario

    sc = load_scenario('sc03')
    fresh = factory.make_controller('ceco-ioch', sc, 5.0, 6)
    warm = factory.make_controller('ceco-ioch', sc, 5.0, 6)
    warm_up(warm, sc, 5.0, 6)
    meas = {
        't_cab_c': 40.0,
        't_int_c': 48.0,
        't_shell_c': 50.0,
        't_glass_c': 50.0,
        't_evap_c': 20.0,
        't_vent_c': 22.0,
        'rh_cab': 0.3,
    }
    for k in range(3):
        obs = observation(
            k,
            5.0 * k,
            meas,
            sc.env_at(5.0 * k),
            AcInput(0.12, 6.0),
            make_previews(sc, 5.0 * k, 5.0, 7, PreviewQuality()),
            sc,
        )
        (a, _), (b, _) = fresh.compute(obs), warm.compute(obs)
        assert (a.mdot_bl_kgps, a.t_evap_sp_c) == (b.mdot_bl_kgps, b.t_evap_sp_c)
    assert np.isfinite(a.mdot_bl_kgps)


def test_the_observation_carries_the_ambient_humidity_from_the_state_as_from_the_simulator():
    """The doors' enthalpy economiser reads the ambient RH: the simulator's environment (``Environment.rh``) and
    mpc_node's CabinState (its ``rh`` field, converted by ``ceco_ros.conversions``) give the same ``rh_amb``; an
    environment whose RH is not known (NaN) gives NaN (the economiser then judges by dry bulb)."""
    from types import SimpleNamespace

    import ceco_ros.conversions as conversions
    from ceco_controller.observation import observation
    from ceco_core.contracts import AcInput
    from ceco_v2x_preview.preview import PreviewQuality, make_previews
    from ceco_v2x_preview.scenario import load_scenario

    sc = load_scenario('udds_humid')
    env = sc.env_at(10.0)
    pv = make_previews(sc, 10.0, 5.0, 7, PreviewQuality())
    from ceco_core.contracts import MEASUREMENTS

    meas = dict.fromkeys(MEASUREMENTS, 30.0) | {'rh_cab': 0.35, 'co2_cab_ppm': 600.0, 'co2_sensor_ppm': 610.0}
    meas['recirc_share'] = 0.8
    sim = observation(2, 10.0, meas, env, AcInput(0.12, 6.0), pv, sc)
    assert sim.rh_amb == env.rh == 0.65
    msg = conversions.state_msg(2, 10.0, conversions.stamp_from_s(10.0), meas, env, AcInput(0.12, 6.0), False)
    node = observation(2, 10.0, conversions.state_measurements(msg), msg, AcInput(0.12, 6.0), pv, sc)
    assert node.rh_amb == sim.rh_amb
    unknown = SimpleNamespace(t_amb_c=env.t_amb_c, solar_wm2=env.solar_wm2, speed_mps=env.speed_mps, rh=math.nan)
    assert math.isnan(observation(2, 10.0, meas, unknown, AcInput(0.12, 6.0), pv, sc).rh_amb)


@pytest.mark.parametrize(
    'path, table',
    [
        ('ceco_controller/config/mpc_node.yaml', controller_parameters()),
        ('ceco_controller/config/baseline_node.yaml', controller_parameters('baseline')),
        ('ceco_plant_sim/config/plant_node.yaml', 'plant'),
        ('ceco_v2x_preview/config/preview_node.yaml', PREVIEW_PARAMETERS),
    ],
)
def test_parameter_files_hold_declared_parameters_at_their_defaults(path, table):
    """The installed parameter files name only declared parameters, at the table's defaults."""
    import pathlib

    import yaml

    if table == 'plant':
        from ceco_plant_sim.plant_io import PLANT_PARAMETERS as table
    root = pathlib.Path(__file__).resolve().parents[1]
    doc = yaml.safe_load((root / path).read_text())
    (values,) = [v['ros__parameters'] for v in doc.values()]
    specs = {s.name: s for s in table}
    assert set(values) <= set(specs), set(values) - set(specs)
    for name, value in values.items():
        assert value == specs[name].default, name


def test_parameter_tables_in_docs_are_current():
    """docs/ros.md holds the tables tools/param_tables.py generates from the ParamSpec tables."""
    import importlib.util
    import pathlib

    root = pathlib.Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location('param_tables', root / 'tools' / 'param_tables.py')
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    doc = (root / 'docs' / 'ros.md').read_text()
    assert mod.rewrite(doc) == doc, 'run: python tools/param_tables.py --write'


# --- issue 17 item 5: every parameter range keeps the node doing its job -----------------------
def _commands_per_period(cfg, seconds: float = 60.0, dt: float = 1.0, tick_phase_s: float = 0.9) -> int:
    """A real-time controller's input logic fed a live plant (a state every dt, stamped with the
    clock, 20 ms of transport) and live previews, its timer every Ts at ``tick_phase_s``: the control
    steps it hands out (each would be one command)."""
    rec = Recorder()
    ci = ControllerInputs(cfg, rec.log, rec.reset)
    ts, steps, t, n = cfg.control_period_s, set(), 0.0, 0
    next_tick = tick_phase_s
    while t < seconds:
        t = n * dt
        ci.offer_state(state(t, stamp_s=1000.0 + t), wall_s=t + 0.02, clock_s=1000.0 + t + 0.02)
        k = int(t // ts)
        ci.offer_preview('weather', weather(k, ts=ts, start=stamp(k * ts)), t + 0.02)
        ci.offer_preview('traffic', traffic(k, ts=ts, start=stamp(k * ts)), t + 0.02)
        if ci.due():
            si, _ = ci.realtime_step(1000.0 + t + 0.02)
            steps.add(si.k)
        while next_tick < t + dt:
            si, _ = ci.realtime_step(1000.0 + next_tick)
            if si is not None:
                steps.add(si.k)
            next_tick += ts
        n += 1
    return len(steps)


def test_state_age_at_its_smallest_allowed_value_keeps_the_controller_commanding():
    """max_state_age_s 0.011 s (allowed before) gave 0 commands in 20 s; its floor is now Ts, at which
    the controller commands every control period, and below which configuration is refused."""
    with pytest.raises(ValueError, match=r'max_state_age_s=0\.011: must be at least control_period_s=5\.0'):
        _ctrl_cfg(timing='realtime', max_state_age_s=0.011)
    cfg = _ctrl_cfg(timing='realtime', max_state_age_s=5.0)
    assert _commands_per_period(cfg, 60.0) >= 11  # 12 control steps in 60 s (the first may wait for a tick)
    # the refused value would have starved it: the logic with the check bypassed
    starved = dataclasses.replace(cfg, max_state_age_s=0.011)
    assert _commands_per_period(starved, 60.0) == 0


@pytest.mark.parametrize(
    ('table', 'name', 'value', 'rule'),
    [
        ('controller', 'max_state_age_s', 4.9, 'at least control_period_s'),
        ('controller', 'inputs.window_s', 4.9, 'at least control_period_s'),
        ('controller', 'qos.liveliness_lease_s', 5.1, 'at most control_period_s'),
        ('preview', 'inputs.max_state_age_s', 4.9, 'at least control_period_s'),
        ('preview', 'inputs.window_s', 4.9, 'at least control_period_s'),
        ('preview', 'publish_period_s', 5.1, 'at most control_period_s'),
        ('plant', 'qos.liveliness_lease_s', 5.1, 'at most control_period_s'),
        ('plant', 'fallback.command_timeout_periods', 0.9, 'must lie in'),
    ],
)
def test_ranges_derived_from_the_control_period_are_enforced(table, name, value, rule):
    """Each range derived from another parameter (Ts): the value just past it is refused with the
    parameter's name and the rule, the value at it is accepted."""
    from ceco_plant_sim.plant_io import PLANT_PARAMETERS

    specs = {'controller': controller_parameters(), 'preview': PREVIEW_PARAMETERS, 'plant': PLANT_PARAMETERS}[table]
    spec = next(s for s in specs if s.name == name)
    values = {s.name: s.default for s in specs}

    def build(v):
        _, why = check_value(spec, v)
        if why:
            raise ValueError(why)
        vals = dict(values, **{name: v})
        if table == 'controller':
            return ControllerNodeConfig.from_params(vals)
        if table == 'preview':
            return PreviewNodeConfig.from_params(vals)
        return _plant_cfg(**{name: v})

    with pytest.raises(ValueError, match=rf'{re.escape(name)}.*{rule}'):
        build(value)
    build(5.0 if 'periods' not in name else 1.0)  # at the derived bound: accepted


def test_held_sample_waits_for_subscribers_and_sends_each_step_once():
    from ceco_core.sequencing import HeldSample

    hold = HeldSample()
    assert hold.offer('k0', short_of_subscribers=False) == ['k0'] and hold.msg is None  # matched: sent now
    assert hold.offer('k1', short_of_subscribers=True) == [] and hold.msg == 'k1'  # waits
    assert hold.release(may_send=False) == [] and hold.msg == 'k1'  # inactive or still short
    assert hold.offer('k2', short_of_subscribers=True) == [] and hold.msg == 'k2'  # the newer replaces it
    assert hold.release(may_send=True) == ['k2'] and hold.release(may_send=True) == []  # sent once
    hold.offer('k3', short_of_subscribers=True, now_s=10.0)
    hold.offer('k4', short_of_subscribers=True, now_s=15.0)
    assert hold.since_s == 10.0  # waiting since the first unsent sample (the hold warning's age)
    hold.clear()  # a new activation forgets it
    assert hold.release(may_send=True) == [] and hold.since_s is None
    hold.offer('k5', short_of_subscribers=True, now_s=20.0)
    assert hold.offer('k6', short_of_subscribers=False, now_s=21.0) == ['k6'] and hold.since_s is None  # k5 replaced


def test_held_previews_of_every_step_wait_in_order_up_to_the_history_depth():
    """preview_node's hold keeps each step's previews: an external controller that does not wait for them lets
    the plant run on before the recorder matched, and a run of the external test recorded the previews of steps 2
    and 3 of 4 (the newer replaced the older). Past ``keep`` the oldest goes; ``keep`` below 1 is refused."""
    from ceco_core.sequencing import HeldSample

    hold = HeldSample(keep=3)
    assert [hold.offer(k, short_of_subscribers=True, now_s=float(k)) for k in range(2)] == [[], []]
    assert hold.msg == 0 and hold.since_s == 0.0  # the held-previews line names the oldest step and its wait
    assert hold.release(may_send=False) == [] and hold.waiting == [0, 1]
    assert hold.offer(2, short_of_subscribers=False) == [0, 1, 2] and hold.msg is None  # matched: all, in order
    for k in range(3, 8):
        hold.offer(k, short_of_subscribers=True, now_s=float(k))
    assert hold.release(may_send=True) == [5, 6, 7] and hold.release(may_send=True) == []  # the newest 3
    hold.offer(8, short_of_subscribers=True)
    assert hold.offer(9, short_of_subscribers=False) == [8, 9]  # matched with one waiting: both, in order
    with pytest.raises(ValueError, match='keep: 0 samples; at least 1'):
        HeldSample(keep=0)


def test_held_previews_line_names_the_step_the_wait_and_each_topics_readers():
    from ceco_v2x_preview.preview_io import held_previews

    line = held_previews(0, 5.04, {'v2x/weather_preview': 1, 'v2x/traffic_preview': 0}, 2)
    assert line.startswith('previews of step 0 held for 5.0 s: matched readers v2x/weather_preview 1/2, ')
    assert 'v2x/traffic_preview 0/2' in line and 'lockstep.min_preview_subscribers' in line
    assert held_previews(3, 6.0, {}, 1, last_k=3).startswith('previews of step 3 held for 6.0 s')
    assert held_previews(0, 6.0, {}, 1, last_k=2).startswith('previews of steps 0-2 held for 6.0 s')


def test_publisher_qos_matches_the_liveliness_probes():
    """The command and preview publishers' QoS (mpc_node, preview_node and tools/bench_startup.py's peer take it
    from interfaces) match both the data readers and the liveliness probes at the default lease; a publisher
    without a lease (QOS_COMMAND, what the startup bench's peer used) does not match a probe (issue 19)."""
    from rclpy.qos import QoSCompatibility, qos_check_compatible

    from ceco_ros import interfaces
    from ceco_ros.params import LIVELINESS_LEASE_S

    probe = interfaces.liveliness_probe_qos(LIVELINESS_LEASE_S)
    for timing in ('lockstep', 'realtime'):
        cmd, pv = interfaces.command_publisher_qos(timing), interfaces.preview_publisher_qos(timing)
        assert qos_check_compatible(cmd, probe)[0] == QoSCompatibility.OK
        assert qos_check_compatible(pv, probe)[0] == QoSCompatibility.OK
        assert qos_check_compatible(cmd, interfaces.command_qos(timing))[0] != QoSCompatibility.ERROR
        assert qos_check_compatible(pv, interfaces.QOS_PREVIEW)[0] != QoSCompatibility.ERROR
        assert cmd.liveliness_lease_duration.nanoseconds == int(LIVELINESS_LEASE_S * 1e9)
    compat, why = qos_check_compatible(interfaces.QOS_COMMAND, probe)
    assert compat == QoSCompatibility.ERROR and 'liveliness' in why
    # a lease longer than the probe's does not match it either (the probe sees a dead publisher late)
    assert qos_check_compatible(interfaces.command_publisher_qos('lockstep', 2.0), probe)[0] == QoSCompatibility.ERROR


def test_diagnostics_message_carries_the_plan_value_for_value():
    """The predicted PMV (an Np x 1 column, flattened), cabin temperature and IOCH slacks go out value for value and
    in order (NaN and inf too); a missing plan is an empty field; the scalars beside them are the step's."""
    from builtin_interfaces.msg import Time

    from ceco_core.contracts import Diagnostics
    from ceco_ros.conversions import diagnostics_msg

    pmv = np.array([[0.4], [0.45], [math.nan], [0.5]])
    d = Diagnostics(k=3, t_s=15.0, status='ok', success=True, pred_pmv=pmv, pred_t_cab_c=[24.0, math.inf], eps=None)
    m = diagnostics_msg(d, Time(sec=15), 'ceco-pmv', 5.0)
    np.testing.assert_array_equal(np.asarray(m.predicted_pmv), [0.4, 0.45, math.nan, 0.5])
    assert list(m.predicted_t_cab_c) == [24.0, math.inf] and len(m.eps) == 0
    assert m.step_index == 3 and m.prediction_step_s == 5.0 and m.strategy == 'ceco-pmv' and m.success
    with_eps = diagnostics_msg(dataclasses.replace(d, eps=np.array([0.0, 0.2])), Time(sec=15), 'ceco-pmv', 5.0)
    assert list(with_eps.eps) == [0.0, 0.2]
