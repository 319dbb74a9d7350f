"""The plant as CasADi Functions: the exact model (a compiled fast path's source) and the smooth one (an optimum's).

:class:`PlantModel` evaluates the plant's equations (:class:`~ceco_plant_sim.plant_equations.PlantEquations`,
the same code the simulator runs) symbolically and hands out named layouts and CasADi Functions:

* ``PlantModel.exact(params, plant_dt_s)``: exact branches, the refrigerant cycle by the plant's own
  Newton solve (every evaluation unrolled to ``cycle_max_iter`` and masked once done, with its
  stopping rule) and the inverter-power secant; its warm start is carried as three extra values
  (the ``warm`` layout) from stage to stage and step to step. Evaluated numerically it gives the
  simulator's numbers (docs/plant.md: measured differences).
* ``PlantModel.smooth(params, plant_dt_s, settings, table)``: every kink and switch smoothed
  (:class:`~ceco_plant_sim.plant_ops.SmoothSettings`) and the refrigerant cycle and power limit from
  the smooth table of the plant's solver (:class:`~ceco_plant_sim.smooth_cycle.SmoothCycleTable`):
  C-infinity inside the table's box, for a whole-drive optimal control problem.

Functions (``x``: :attr:`PlantModel.state`, ``u``: :attr:`PlantModel.input`, ``env``:
:attr:`PlantModel.env`; the exact model adds ``warm`` in and out):

* ``rhs(x, u, env) -> (xdot, flows)``: the continuous right-hand side [unit/s] and the flows
  (:attr:`PlantModel.flows`: powers [W], water flows [kg/s]);
* ``step(x, u, env) -> (x_next, energy, y)``: one plant step of ``plant_dt_s`` (the simulator's RK4
  sub-steps), the energies and water of the step (:attr:`PlantModel.energy` [J], [kg]; electrical
  energy = compressor + blower + condenser fan) and the algebraic outputs at its end
  (:attr:`PlantModel.y`, e.g. the vent air temperature the next step's comfort is scored with);
* ``algebraic(x, u, env) -> y``: the algebraic outputs at one instant (:attr:`PlantModel.y`);
* :meth:`PlantModel.scored_pmv`: the PMV the benchmark scores (``ceco_core.cabin_comfort``, the same
  code as :class:`~ceco_plant_sim.scenario_plant.ScenarioPlant`) from the state, the measured vent air
  temperature, the command and the environment;
* ``table_margin(x, env)`` (smooth model): how far inside the smooth cycle table's grid box the
  drive is (< 0: outside, where the table is clamped);
* :meth:`PlantModel.replay`: the scenario's drive replayed through ``step`` with the scoring timing of
  ``ScenarioPlant`` (a numeric check of the model against the plant).

Pure logic: no rclpy, no message types.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import casadi
import numpy as np

from ceco_core.air_quality import AQ_SIGNALS, AqSignals, co2_ppm_from_kgkg, fog_margin_k
from ceco_core.cabin_comfort import ComfortParams, cabin_mrt_c, cabin_pmv, cabin_w_rad_wm2
from ceco_core.psychro import vapour_pressure_from_humidity_ratio_pa, vapour_pressure_pa

from .plant_equations import (
    ALG_NAMES,
    ENV_NAMES,
    FLOW_NAMES,
    INPUT_NAMES,
    STATE_NAMES,
    Env,
    Guess,
    Input,
    NewtonCycle,
    PlantEquations,
    State,
    blower_power_w,
    cabin_relative_humidity,
    cabin_vapour_kgkg,
    condenser_eps_c_wpk,
)
from .plant_ops import ExactOps, SmoothOps, SmoothSettings
from .plant_params import PlantParams
from .refrigerant import cycle_tables

__all__ = ["Layout", "PlantModel", "ENERGY_NAMES", "WARM_NAMES", "CONTROL_INPUTS"]

ENERGY_NAMES = (
    "e_comp_j",
    "e_blower_j",
    "e_cond_fan_j",
    "e_total_j",
    "q_evap_j",
    "q_latent_j",
    "q_evap_ref_j",
    "m_water_in_kg",
    "m_water_out_kg",
    "m_condensate_kg",
    "m_co2_in_kg",
    "m_co2_out_kg",
    "m_co2_gen_kg",
)
"""What one step accumulates: compressor, blower and condenser-fan electrical energy and their sum [J],
evaporator heat from the air, its latent part and the refrigerant's [J], water into and out of the
cabin air and condensed [kg], CO2 into and out of the cabin air and exhaled [kg]."""

CONTROL_INPUTS = ("mdot_bl_kgps", "t_evap_sp_c")
"""The inputs of a model built without the door (``door_input=False``): the door's command is then the
plant's default share ``PlantParams.recirc_fraction`` (the two-input problems of before issue 21)."""

WARM_NAMES = ("t_evap_sat_c", "t_cond_c", "valid")
"""The exact model's warm start of the refrigerant solve (:class:`~ceco_plant_sim.plant_equations.Guess`)."""

_UNITS = {
    "t_cab_c": "degC",
    "t_int_c": "degC",
    "t_shell_c": "degC",
    "t_glass_c": "degC",
    "t_evap_c": "degC",
    "t_duct_c": "degC",
    "w_cab_kgkg": "kg/kg",
    "comp_pi_integral_rpm": "rpm",
    "recirc_share": "-",
    "co2_cab_kgkg": "kg/kg",
    "mdot_bl_kgps": "kg/s",
    "t_evap_sp_c": "degC",
    "t_amb_c": "degC",
    "solar_wm2": "W/m2",
    "speed_mps": "m/s",
    "rh": "-",
}


@dataclasses.dataclass(frozen=True)
class Layout:
    """Named slots of a CasADi vector (index by name, never by offset)."""

    names: tuple[str, ...]
    """Slot names in vector order."""

    @property
    def size(self) -> int:
        """Number of slots."""
        return len(self.names)

    def index(self, name: str) -> int:
        """Position of ``name``; KeyError naming the layout's slots otherwise."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"{name!r} is not one of {self.names}") from None

    def unit(self, name: str) -> str:
        """Unit of slot ``name`` (from its suffix, or the table of this module)."""
        return _UNITS.get(name, name.rsplit("_", 1)[-1] if "_" in name else "-")

    def vector(self, values) -> np.ndarray:
        """A float vector from a mapping or an object with the slot names as keys/attributes."""
        get = values.__getitem__ if isinstance(values, Mapping) else lambda k: getattr(values, k)
        return np.array([float(get(k)) for k in self.names], dtype=float)

    def named(self, vec) -> dict[str, float]:
        """``{name: value}`` of a numeric vector in this layout."""
        v = np.asarray(vec, dtype=float).ravel()
        if v.size != self.size:
            raise ValueError(f"vector of {v.size} values for a layout of {self.size}: {self.names}")
        return dict(zip(self.names, v.tolist(), strict=True))


def _split(sym, cls):
    return cls(*casadi.vertsplit(sym, 1))


class PlantModel:
    """The plant's equations as CasADi Functions with named layouts (build with :meth:`exact` or :meth:`smooth`)."""

    state = Layout(STATE_NAMES)
    """State layout (the PlantState fields)."""
    input = Layout(CONTROL_INPUTS)
    """Input layout: the AcInput fields with the door (``door_input=True``), else :data:`CONTROL_INPUTS`
    (set per model)."""
    env = Layout(ENV_NAMES)
    """Environment layout."""
    flows = Layout(FLOW_NAMES)
    """Flows of ``rhs`` [W], [kg/s]."""
    energy = Layout(ENERGY_NAMES)
    """Energies and water of one ``step`` [J], [kg]."""
    y = Layout(ALG_NAMES)
    """Algebraic outputs ``y`` of ``algebraic`` and ``step``."""
    warm = Layout(WARM_NAMES)
    """Warm start of the exact model's refrigerant solve (not part of the smooth model)."""
    aq = Layout(AQ_SIGNALS)
    """The air-quality constraint signals of ``air_quality``: cabin CO2 [ppm], fog margin [K]."""

    def __init__(
        self,
        params: PlantParams,
        plant_dt_s: float,
        equations: PlantEquations,
        evaluation: str,
        door_input: bool = False,
    ) -> None:
        if not (isinstance(plant_dt_s, (int, float)) and 0.0 < plant_dt_s <= 3600.0):
            raise ValueError(f"plant_dt_s: must be in (0, 3600] s, got {plant_dt_s!r}")
        self.door_input = bool(door_input)
        """True: the door's command is the input ``recirc_share``; False: it is held at ``recirc_fraction``."""
        self.input = Layout(INPUT_NAMES if self.door_input else CONTROL_INPUTS)
        self.params = params
        """The plant parameters."""
        self.plant_dt_s = float(plant_dt_s)
        """The step of ``step`` [s]."""
        self.evaluation = evaluation
        """``exact`` or ``smooth``."""
        self._eq = equations
        self._build()

    @classmethod
    def exact(cls, params: PlantParams | None = None, plant_dt_s: float = 1.0, door_input: bool = False) -> PlantModel:
        """The exact-branch model: the simulator's equations and refrigerant solve, symbolically.

        ``door_input``: the door's command is the third input ``recirc_share`` (True) or held at
        ``params.recirc_fraction`` (False, the default: the inputs of before issue 21).
        """
        p = (params or PlantParams()).validate()
        tab = cycle_tables(p.refrigerant, float(p.superheat_k), float(p.subcool_k))
        return cls(p, plant_dt_s, PlantEquations(p, NewtonCycle(p, tab), ExactOps()), "exact", door_input)

    @classmethod
    def smooth(
        cls,
        params: PlantParams | None = None,
        plant_dt_s: float = 1.0,
        settings: SmoothSettings | None = None,
        table=None,
        door_input: bool = False,
    ) -> PlantModel:
        """The smooth model: smoothed kinks and switches, the refrigerant cycle from its smooth table.

        ``table``: a :class:`~ceco_plant_sim.smooth_cycle.SmoothCycleTable` of these parameters;
        default :func:`~ceco_plant_sim.smooth_cycle.smooth_cycle_table` (the shipped file when it
        holds them, else built from the solver). ``door_input``: as :meth:`exact`.
        """
        from .smooth_cycle import SmoothCycle, smooth_cycle_table

        p = (params or PlantParams()).validate()
        tab = table if table is not None else smooth_cycle_table(p)
        tab.check_params(p)
        return cls(p, plant_dt_s, PlantEquations(p, SmoothCycle(p, tab), SmoothOps(settings)), "smooth", door_input)

    def _equation_input(self, us) -> Input:
        """The equations' :class:`Input` of a model input vector ``us`` (the door's default put in when absent)."""
        parts = casadi.vertsplit(us, 1)
        door = parts[2] if self.door_input else float(self.params.recirc_fraction)
        return Input(parts[0], parts[1], door)

    # ------------------------------------------------------------------ build
    def _build(self) -> None:
        eq = self._eq
        exact = self.evaluation == "exact"
        xs = casadi.SX.sym("x", self.state.size)
        us = casadi.SX.sym("u", self.input.size)
        es = casadi.SX.sym("env", self.env.size)
        ws = casadi.SX.sym("warm", self.warm.size)
        x, u, env = _split(xs, State), self._equation_input(us), _split(es, Env)
        guess = Guess(*casadi.vertsplit(ws, 1)) if exact else Guess(0.0, 0.0, 0.0)
        p_bl = blower_power_w(self.params, u.mdot_bl_kgps)
        ins, names_in = [xs, us, es], ["x", "u", "env"]
        if exact:
            ins, names_in = [*ins, ws], [*names_in, "warm"]

        def out(name, exprs, names):
            outs = [
                casadi.vertcat(*[casadi.SX(v) if isinstance(v, (bool, int, float)) else v for v in e]) for e in exprs
            ]
            return casadi.Function(name, ins, outs, names_in, names)

        dx, flows, alg, g_rhs, ok_rhs = eq.rhs(x, u, p_bl, env, guess)
        rhs_out, rhs_names = [dx, flows], ["xdot", "flows"]
        if exact:
            rhs_out, rhs_names = [*rhs_out, g_rhs, [ok_rhs]], [*rhs_names, "warm_next", "ok"]
        self.rhs = out("rhs", rhs_out, rhs_names)
        """Continuous right-hand side: (x, u, env[, warm]) -> (xdot, flows[, warm_next, ok])."""
        self.algebraic = out("algebraic", [alg], ["y"])
        """Algebraic outputs at one instant: (x, u, env[, warm]) -> y (:attr:`y` layout)."""

        x1, acc, g1, ok = eq.step(x, u, env, self.plant_dt_s, guess)
        y1 = eq.rhs(x1, u, p_bl, env, g1)[2]  # the end-of-step report: the warm start after the step
        e_bl = p_bl * self.plant_dt_s
        energy = (
            acc.p_comp_w,
            e_bl,
            acc.p_cond_fan_w,
            acc.p_comp_w + e_bl + acc.p_cond_fan_w,
            acc.q_evap_w,
            acc.q_latent_w,
            acc.q_evap_ref_w,
            acc.mdot_water_in_kgps,
            acc.mdot_water_out_kgps,
            acc.mdot_condensate_kgps,
            acc.mdot_co2_in_kgps,
            acc.mdot_co2_out_kgps,
            acc.mdot_co2_gen_kgps,
        )
        step_out, step_names = [x1, energy, y1], ["x_next", "energy", "y"]
        if exact:
            step_out, step_names = [*step_out, g1, [ok]], [*step_names, "warm_next", "ok"]
        self.step = out("step", step_out, step_names)
        """One plant step: (x, u, env[, warm]) -> (x_next, energy, y[, warm_next, ok])."""
        pw = vapour_pressure_from_humidity_ratio_pa(
            cabin_vapour_kgkg(self.params, x.t_cab_c, x.w_cab_kgkg, eq.ops), self.params.p_atm_pa
        )
        aq = AqSignals(co2_ppm_from_kgkg(x.co2_cab_kgkg), fog_margin_k(x.t_glass_c, pw))
        self.air_quality = casadi.Function("air_quality", [xs], [casadi.vertcat(*aq)], ["x"], ["aq"])
        """The air-quality constraint signals of a state: x -> aq (:attr:`aq` layout: cabin CO2 [ppm], fog
        margin [K] = glazing minus cabin dew point); ``ceco_core.air_quality.aq_violation`` gives g <= 0."""
        self.table_margin: casadi.Function | None = None
        """Smooth model: (x, env) -> the smooth cycle table's margin at the evaporator wall, ambient and
        condenser epsc of (x, env) (scaled distance inside the grid box; < 0: outside, the splines
        clamp). None for the exact model (no table)."""
        if not exact:
            tab = eq.cycle.table
            speed_mid = 0.5 * (tab.box()[0][0] + tab.box()[0][1])  # the speed stays inside by construction
            epsc = condenser_eps_c_wpk(self.params, env.speed_mps, eq.ops)
            margin = tab.margin(speed_mid, x.t_evap_c, env.t_amb_c, epsc)
            self.table_margin = casadi.Function("table_margin", [xs, es], [margin], ["x", "env"], ["margin"])

    # ------------------------------------------------------------------ comfort
    def scored_pmv(self, comfort: ComfortParams, pa_pa: float | None = None) -> casadi.Function:
        """The scored PMV as ``ScenarioPlant`` computes it: Function (x, t_vent_c, u, env) -> pmv.

        ``t_vent_c`` is the measured vent air temperature (the previous step's ``y`` ``t_vent_c``; at
        key-on the evaporator wall temperature); the blower flow is the command held over the step.
        The cabin vapour pressure comes from the state's humidity ratio (or the fixed ``pa_pa`` [Pa],
        the comfort override ``SCORED_PA_OVERRIDE``). Same functions as the plant's scoring
        (``ceco_core.cabin_comfort``), evaluated symbolically.
        """
        comfort.validate()
        xs = casadi.SX.sym("x", self.state.size)
        tv = casadi.SX.sym("t_vent_c")
        us = casadi.SX.sym("u", self.input.size)
        es = casadi.SX.sym("env", self.env.size)
        x, u, env = _split(xs, State), self._equation_input(us), _split(es, Env)
        if pa_pa is None:
            rh = cabin_relative_humidity(self.params, x.t_cab_c, x.w_cab_kgkg, self._eq.ops)
            pa = vapour_pressure_pa(x.t_cab_c, rh)
        else:
            pa = float(pa_pa)
        t_mr = cabin_mrt_c(
            t_cab_c=x.t_cab_c, t_int_c=x.t_int_c, t_shell_c=x.t_shell_c, t_glass_c=x.t_glass_c, params=comfort
        )
        y = cabin_pmv(
            t_cab_c=x.t_cab_c,
            t_vent_c=tv,
            mdot_bl_kgps=u.mdot_bl_kgps,
            t_mr_c=t_mr,
            w_rad_wm2=cabin_w_rad_wm2(env.solar_wm2, comfort),
            pa_pa=pa,
            params=comfort,
        )
        return casadi.Function("scored_pmv", [xs, tv, us, es], [y], ["x", "t_vent_c", "u", "env"], ["pmv"])

    # ------------------------------------------------------------------ numeric use
    def command_vector(self, command) -> np.ndarray:
        """A command (an AcInput, a mapping or an object with the input names) as an :attr:`input` vector.

        A door left alone (``recirc_share`` NaN or absent) is the plant's default share, as the simulator
        applies it.
        """
        get = command.get if isinstance(command, Mapping) else lambda k, d=None: getattr(command, k, d)
        out = []
        for k in self.input.names:
            v = float(get(k, np.nan))
            if k == "recirc_share" and np.isnan(v):
                v = float(self.params.recirc_fraction)
            out.append(v)
        return np.array(out, dtype=float)

    def rollout(self, n_steps: int) -> casadi.Function:
        """``step`` chained over ``n_steps`` (CasADi ``mapaccum``), cached per length.

        Smooth: (x0, U[nu x N], E[4 x N]) -> (X[nx x N], energy[13 x N], Y[10 x N]), column n the state at
        t_{n+1}, the step's energies and its end outputs. Exact: (x0, U, E, warm0) -> (X, energy, Y,
        warm[3 x N], ok[1 x N]).
        """
        if not (isinstance(n_steps, int) and n_steps >= 1):
            raise ValueError(f"n_steps: must be an int >= 1, got {n_steps!r}")
        key = f"_rollout_{n_steps}"
        if key not in self.__dict__:
            acc = [0, 3] if self.evaluation == "exact" else [0]
            self.__dict__[key] = self.step.mapaccum(f"rollout_{n_steps}", n_steps, acc, acc)
        return self.__dict__[key]

    def replay(
        self,
        x0,
        commands,
        envs,
        comfort: ComfortParams | None = None,
        pa_pa: float | None = None,
    ) -> dict[str, np.ndarray]:
        """Evaluate the model along a drive numerically, with ``ScenarioPlant``'s scoring timing.

        Args:
            x0: key-on state (a :attr:`state` vector, a PlantState or a mapping).
            commands: per step the command: an N x nu array (:attr:`input` order) or AcInputs (a door
                left alone, NaN, is the plant's default share).
            envs: per step the truth environment at t_n: an N x 4 array (:attr:`env` order) or
                objects with those fields.
            comfort: the scored comfort parameters (``ScenarioPlant.comfort``); None: no PMV.
            pa_pa: fixed scored vapour pressure [Pa] (the comfort override), None: the cabin's.

        Returns per-step arrays: ``x`` (N+1 x nx, the state at t_0..t_N), ``energy`` (N x 13),
        ``y`` (N x 10, end of each step), ``pmv`` (N, at t_n with the vent air measured at t_n: the
        evaporator wall at key-on, then the previous step's end), for the exact model ``ok``, for the
        smooth model ``table_margin`` (N, at t_n; < 0 where the drive left the cycle table's box).
        RuntimeError if the drive leaves the finite numbers.
        """
        x = np.asarray(x0, dtype=float) if isinstance(x0, (np.ndarray, list, tuple)) else self.state.vector(x0)
        u = np.array(
            [c if isinstance(c, (tuple, list, np.ndarray)) else self.command_vector(c) for c in commands], float
        )
        e = np.array([v if isinstance(v, (tuple, list, np.ndarray)) else self.env.vector(v) for v in envs], float)
        if u.ndim != 2 or e.shape != (u.shape[0], self.env.size) or u.shape[1] != self.input.size:
            raise ValueError(
                f"commands {u.shape} and envs {e.shape} must be N x {self.input.size} and N x {self.env.size}"
            )
        n = u.shape[0]
        args = [x, u.T, e.T] + ([np.zeros(self.warm.size)] if self.evaluation == "exact" else [])
        res = self.rollout(n)(*args)
        xs = np.asarray(res[0], dtype=float).T
        if not np.all(np.isfinite(xs)):
            raise RuntimeError(
                f"{self.evaluation} model: non-finite state from step {int(np.argmax(~np.isfinite(xs).all(1)))}"
            )
        out = {
            "x": np.vstack([x, xs]),
            "energy": np.asarray(res[1], dtype=float).T,
            "y": np.asarray(res[2], dtype=float).T,
        }
        if comfort is not None:
            t_vent = np.concatenate([[x[self.state.index("t_evap_c")]], out["y"][:-1, self.y.index("t_vent_c")]])
            pmv_f = self.scored_pmv(comfort, pa_pa).map(n)
            out["pmv"] = np.asarray(pmv_f(out["x"][:-1].T, t_vent[None, :], u.T, e.T), dtype=float).ravel()
        if self.evaluation == "exact":
            out["ok"] = np.asarray(res[4], dtype=float).ravel() == 1.0
        if self.table_margin is not None:
            out["table_margin"] = np.asarray(self.table_margin.map(n)(out["x"][:-1].T, e.T), dtype=float).ravel()
        return out

    def scenario_drive(self, scenario, n_steps: int | None = None, *, plant_overrides=None, comfort_overrides=None):
        """Key-on state, truth environment and scored comfort of a scenario (or its name), as ScenarioPlant has them.

        Returns (x0 [nx], envs [N x 4] at t_n = n plant_dt_s, ComfortParams, fixed scored vapour pressure
        [Pa] or None). ``n_steps`` defaults to the scenario's duration. The model's parameters must
        be the scenario plant's (``plant_overrides`` applied to the defaults; ValueError otherwise).
        """
        from ceco_v2x_preview.scenario import load_scenario

        from .compiled_plant import PlantEvaluation
        from .scenario_plant import ScenarioPlant, n_plant_steps

        sc = load_scenario(scenario) if isinstance(scenario, str) else scenario
        sp = ScenarioPlant(  # not stepped: no compiled step to build
            sc,
            self.plant_dt_s,
            plant_overrides=plant_overrides,
            comfort_overrides=comfort_overrides,
            evaluation=PlantEvaluation("python"),
        )
        if sp.plant.params != self.params:
            raise ValueError("scenario_drive: the scenario plant's parameters differ from this model's")
        n = n_plant_steps(sp.scenario.duration_s, self.plant_dt_s) if n_steps is None else int(n_steps)
        envs = np.array([self.env.vector(sp.scenario.env_at(k * self.plant_dt_s)) for k in range(n)])
        return self.state.vector(sp.plant.state), envs, sp.comfort, sp.scored_pa_pa
