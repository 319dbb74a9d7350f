"""Cabin + A/C plant: the "truth" model the controllers are tested against.

A lumped thermal network of the cabin (air with its humidity ratio, interior
mass, shell, glazing) coupled to an A/C loop (blower, evaporator wall with
condensation, electric scroll compressor held by the A/C ECU's PI on the
evaporator wall temperature, condenser cooled by fan + ram air, refrigerant
cycle from CoolProp properties). It has more states and effects than the
control-oriented model of the method paper (eqs. 1-3: T_cab, T_evap, T_ain),
so a controller built on that model meets real mismatch.

States (all integrated together by classical RK4 at the fixed sub-step
``PlantParams.substep_s``; the refrigerant loop is algebraic and solved by
Newton at every stage, see :mod:`ceco_plant_sim.refrigerant`):

=========================  ======================================  =======
name                       meaning                                  unit
=========================  ======================================  =======
t_cab_c                    cabin air temperature                    degC
t_int_c                    interior mass (seats, dashboard, trim)   degC
t_shell_c                  shell (roof, doors, pillars, floor)      degC
t_glass_c                  glazing                                  degC
t_evap_c                   evaporator wall (fins + tubes)           degC
t_duct_c                   HVAC case + ducts after the evaporator   degC
w_cab_kgkg                 cabin humidity ratio                     kg/kg dry air
comp_pi_integral_rpm       integral part of the compressor PI       rpm
recirc_share               fresh/recirculation door position        0..1
co2_cab_kgkg               cabin CO2                                kg/kg dry air
=========================  ======================================  =======

Equations, units, references and the parameter table: ``docs/plant.md``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import fields

from ceco_core.contracts import AcInput
from ceco_core.contracts import check_finite as _check_finite
from ceco_plant_sim.plant_equations import (
    NO_GUESS,
    Env,
    Guess,
    Input,
    NewtonCycle,
    PlantEquations,
    State,
    blower_power_w,
    compressor_model,
    condenser_eps_c_wpk,
)
from ceco_plant_sim.plant_params import PlantParams
from ceco_plant_sim.plant_state import PlantOutputs, PlantState, validate_environment
from ceco_plant_sim.refrigerant import CycleSolution, cycle_tables, solve_cycle

__all__ = [
    "PlantState",
    "PlantOutputs",
    "CabinPlant",
    "validate_environment",
    "condenser_eps_c_wpk",
    "steady_cycle_at_load",
]

_compressor_model = compressor_model  # the name tests/test_refrigerant.py imports


def _tables(p: PlantParams):
    return cycle_tables(p.refrigerant, float(p.superheat_k), float(p.subcool_k))


def steady_cycle_at_load(
    params: PlantParams, q_evap_w: float, t_wall_c: float, t_amb_c: float, speed_mps: float
) -> tuple[float, CycleSolution]:
    """Compressor speed and cycle state that deliver ``q_evap_w`` at a fixed evaporator wall temperature.

    Used for the efficiency-versus-vehicle-speed map (fixed cooling load):
    bisection on the compressor speed (60 halvings) between 1 rpm and
    ``comp_speed_max_rpm``. Raises ValueError if the load exceeds the
    capacity at maximum speed. Returns (speed_rpm, CycleSolution).
    """
    p = params.validate()
    tab = _tables(p)
    comp = _compressor_model(p)
    epsc = condenser_eps_c_wpk(p, speed_mps)

    def q_at(n):
        s = solve_cycle(
            tab,
            comp,
            n,
            t_wall_c,
            p.ua_evap_ref_wpk,
            t_amb_c,
            epsc,
            p.te_mop_c,
            tol_k=p.cycle_tol_k,
            max_iter=p.cycle_max_iter,
            pr_min=p.pr_min,
        )
        return s.q_evap_ref_w, s

    q_max, _ = q_at(p.comp_speed_max_rpm)
    if q_evap_w > q_max:
        raise ValueError(f"q_evap_w: {q_evap_w:.0f} W exceeds the capacity {q_max:.0f} W at maximum speed")
    lo, hi = 1.0, p.comp_speed_max_rpm
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if q_at(mid)[0] < q_evap_w:
            lo = mid
        else:
            hi = mid
    n = 0.5 * (lo + hi)
    return n, q_at(n)[1]


class CabinPlant:
    """The cabin + A/C plant. ``step(command, env, dt_s)`` advances time with the command held.

    The numeric evaluation of :class:`~ceco_plant_sim.plant_equations.PlantEquations` (the equations
    written once; docs/plant.md).

    Args:
        params: the plant's :class:`PlantParams` (validated here).
        state: the initial :class:`PlantState`, e.g.
            ``PlantState.from_initial(scenario.initial, params, env)``.
    """

    def __init__(self, params: PlantParams, state: PlantState) -> None:
        if not isinstance(params, PlantParams):
            raise ValueError(f"params: must be PlantParams, got {type(params).__name__}")
        if not isinstance(state, PlantState):
            raise ValueError(f"state: must be PlantState, got {type(state).__name__}")
        self.params = params.validate()
        self._x = State._make(state.validate().as_tuple())
        self._tab = _tables(params)
        self._eq = PlantEquations(self.params, NewtonCycle(self.params, self._tab))
        self._guess = NO_GUESS
        self._t_s = 0.0
        self._last: PlantOutputs | None = None

    # ------------------------------------------------------------------ API
    @property
    def state(self) -> PlantState:
        """Current state (a new frozen PlantState)."""
        return PlantState(*self._x)

    @property
    def t_s(self) -> float:
        """Simulated time since construction [s] (sum of dt_s)."""
        return self._t_s

    @property
    def tables_source(self) -> str:
        """Where the refrigerant property tables come from (the shipped file or a CoolProp build)."""
        return self._tab.source

    def outputs(self) -> PlantOutputs:
        """Outputs of the last step; RuntimeError before the first step."""
        if self._last is None:
            raise RuntimeError("outputs: no step taken yet (call step() first)")
        return self._last

    def step(self, command: AcInput, env, dt_s: float) -> PlantOutputs:
        """Advance the plant by ``dt_s`` seconds with ``command`` and ``env`` held; return the outputs.

        The interval is split into ceil(dt_s / substep_s) equal RK4 sub-steps,
        so dt_s = 1 and dt_s = 5 integrate the same way when substep_s
        divides 1 s. Raises ValueError for a bad command, environment or dt_s.
        """
        if not isinstance(command, AcInput):
            raise ValueError(f"command: must be AcInput, got {type(command).__name__}")
        command.validate()
        dt = _check_finite("dt_s", dt_s)
        if dt <= 0.0:
            raise ValueError(f"dt_s: must be > 0, got {dt}")
        if dt > 3600.0:
            raise ValueError(f"dt_s: must be <= 3600 s, got {dt}")
        env_v = Env._make(validate_environment(env))
        u = self.equation_input(command)
        # the warm start is advanced by the RK4 stages only; the end-of-step report does not touch it, so
        # splitting an interval into more calls of step() reproduces the same sub-step sequence bit for bit
        x, acc, guess, _ = self._eq.step(self._x, u, env_v, dt, self._guess)
        return self.commit(x, guess, dt, lambda: PlantOutputs(**self._eq.outputs(x, u, env_v, dt, acc, guess)[0]))

    def commit(self, x_next, guess, dt_s: float, outputs: Callable[[], PlantOutputs]) -> PlantOutputs:
        """Take a step's result as the plant's new state (the numeric :meth:`step` and the compiled fast path).

        ``x_next``: the state after ``dt_s`` [s] (RuntimeError naming the first non-finite one, the plant
        unchanged); ``guess``: the refrigerant warm start after the step; ``outputs()``: its report.
        """
        x = State._make(float(v) for v in x_next)
        for i, v in enumerate(x):
            if not math.isfinite(v):
                raise RuntimeError(f"plant state {fields(PlantState)[i].name} became non-finite")
        out = outputs()
        self._x = x
        self._guess = Guess._make(guess)
        self._t_s += dt_s
        self._last = out
        return out

    @property
    def state_vector(self) -> State:
        """Current state as the equations' named tuple (no PlantState built)."""
        return self._x

    @property
    def warm_start(self) -> Guess:
        """The refrigerant solve's warm start carried to the next step."""
        return self._guess

    def snapshot(self, command: AcInput, env) -> PlantOutputs:
        """Instantaneous outputs at the current state for ``command`` and ``env``, without advancing time.

        Same fields as :meth:`step`; powers are instantaneous values (not step
        means), energies are 0 and ``cop`` is the instantaneous ratio. Useful
        for the measurements at t = 0 (e.g. the vent temperature before the
        first step). Does not change the plant (state, time, warm start).
        """
        if not isinstance(command, AcInput):
            raise ValueError(f"command: must be AcInput, got {type(command).__name__}")
        command.validate()
        env_v = Env._make(validate_environment(env))
        u = self.equation_input(command)
        flows = self._eq.rhs(self._x, u, blower_power_w(self.params, u.mdot_bl_kgps), env_v, self._guess)[1]
        return PlantOutputs(**self._eq.outputs(self._x, u, env_v, 0.0, flows, self._guess)[0])

    def equation_input(self, command: AcInput) -> Input:
        """The equations' input of a validated command: a door left alone (NaN) holds ``recirc_fraction``."""
        r = float(command.recirc_share)
        return Input(
            float(command.mdot_bl_kgps),
            float(command.t_evap_sp_c),
            self.params.recirc_fraction if math.isnan(r) else r,
        )
