"""The plant side of a closed-loop run on a scenario: key-on and the per-plant-step sequence.

Written once and called by both the in-process simulator
(``ceco_controller.closed_loop.simulate``) and ``plant_node``, so that a DDS run
equals the simulator bit for bit.

Timing (docs/architecture.md): plant step n covers [t_n, t_n + dt) with
t_n = n * dt. :meth:`ScenarioPlant.step` evaluates, in this order, the truth
environment at t_n, the occupant's PMV bounds at t_n, the occupant's comfort at
t_n (scored PMV, draught, fog margin, ISO 7730 validity) from the measurements at
t_n and the command held over the step
(``ceco_core.cabin_comfort.evaluate_cabin_comfort``, with the cabin's own vapour
pressure), then ``CabinPlant.step`` over dt; the outputs become the measurements
at t_{n+1}.

Key-on: the measurements come from the scenario's initial state, with the vent
air at the evaporator wall temperature (no flow before key-on), and the previous
command is the pull-down command (``KEY_ON_COMMAND``: full blower
``MDOT_BL_MAX_KGPS`` = 0.17 kg/s, coldest set-point ``T_EVAP_SP_MIN_C`` = 3 degC;
docs/plant.md).

Pure logic: no rclpy, no message types.
"""

from __future__ import annotations

import dataclasses
import math

from ceco_core.cabin_comfort import ComfortParams, OccupantComfort, comfort_params_for, evaluate_cabin_comfort
from ceco_core.co2_sensor import Co2Sensor
from ceco_core.codegen import CompileError
from ceco_core.contracts import MDOT_BL_MAX_KGPS, MEASUREMENTS, T_EVAP_SP_MIN_C, AcInput
from ceco_core.control_grid import floor_steps, whole_steps
from ceco_core.overrides import with_overrides
from ceco_core.scenario_types import Environment
from ceco_v2x_preview.scenario import Scenario

from .compiled_plant import COMFORT_NAMES, OUTPUT_NAMES, PlantEvaluation, compiled_step, fallback_warning
from .plant import CabinPlant, PlantOutputs, PlantState
from .plant_equations import Env
from .plant_ops import PlantStepError, cycle_failure_message
from .plant_params import PlantParams
from .plant_state import validate_environment

__all__ = [
    "MEASUREMENTS",
    "KEY_ON_COMMAND",
    "SCORED_PA_OVERRIDE",
    "comfort_params_for",
    "steps_per_control",
    "n_plant_steps",
    "check_overrides",
    "scenario_plant_params",
    "PlantStepRecord",
    "ScenarioPlant",
    "PlantStepError",
]


KEY_ON_COMMAND = AcInput(mdot_bl_kgps=MDOT_BL_MAX_KGPS, t_evap_sp_c=T_EVAP_SP_MIN_C)
"""The command taken as "previous" at key-on: pull-down (0.17 kg/s, 3 degC)."""


SCORED_PA_OVERRIDE = "pa_pa"
"""Comfort-override key (not a ComfortParams field): score the PMV with this fixed cabin water vapour
pressure [Pa] instead of the plant's moisture balance, as the method paper does (1700 Pa). The dew point
and fog margin keep the plant's humidity."""


def _split_comfort_overrides(comfort_overrides) -> tuple[dict, float | None]:
    co = dict(comfort_overrides or {})
    pa = co.pop(SCORED_PA_OVERRIDE, None)
    if pa is not None and (
        isinstance(pa, bool) or not isinstance(pa, (int, float)) or not math.isfinite(pa) or not 0.0 <= pa <= 10000.0
    ):
        raise ValueError(
            f"comfort override {SCORED_PA_OVERRIDE} (scored cabin vapour pressure) must be a number "
            f"in [0, 10000] Pa or None, got {pa!r}"
        )
    return co, (None if pa is None else float(pa))


def check_overrides(plant_overrides=None, comfort_overrides=None) -> None:
    """Raise ValueError naming the field if the overrides of a sensitivity run are not usable.

    ``plant_overrides``: ``{PlantParams field: value}``; ``comfort_overrides``: ``{ComfortParams field or
    dotted part field (e.g. "air.jet_body_fraction"): value}`` plus :data:`SCORED_PA_OVERRIDE`. Checked
    against the defaults (a scenario's comfort parameters differ only in met, clo and the sun geometry).
    """
    with_overrides(PlantParams(), plant_overrides, owner="PlantParams")
    co, _ = _split_comfort_overrides(comfort_overrides)
    with_overrides(ComfortParams(), co, owner="ComfortParams")


def scenario_plant_params(scenario: Scenario, params: PlantParams | None = None, plant_overrides=None) -> PlantParams:
    """The plant parameters of a scenario's car.

    ``params`` (default :class:`PlantParams`) with the scenario's occupants and ambient CO2, then
    ``plant_overrides`` (``{PlantParams field: value}``, a sensitivity run).
    """
    pp = dataclasses.replace(
        params or PlantParams(),
        n_occupants=int(scenario.occupants),
        co2_amb_ppm=float(scenario.air_quality.co2_amb_ppm),
    )
    return with_overrides(pp, plant_overrides, owner="PlantParams")


def steps_per_control(control_period_s: float, plant_dt_s: float) -> int:
    """Plant steps per control period Ts / dt [-]; ValueError unless Ts is a whole multiple (>= 1) of dt."""
    m = whole_steps(control_period_s, plant_dt_s)
    if m is None or m < 1:
        raise ValueError(
            f"control period {control_period_s} s must be a whole multiple of the plant step {plant_dt_s} s"
        )
    return m


def n_plant_steps(duration_s: float, plant_dt_s: float) -> int:
    """Plant steps in a run of ``duration_s`` [s] (floor, with 1e-9 tolerance for float grids)."""
    return floor_steps(duration_s, plant_dt_s)


def _measurements(out: PlantOutputs, co2_sensor_ppm: float) -> dict:
    meas = {k: getattr(out, k) for k in MEASUREMENTS if k != "co2_sensor_ppm"}
    meas["co2_sensor_ppm"] = co2_sensor_ppm
    return meas


@dataclasses.dataclass(frozen=True)
class PlantStepRecord:
    """What one plant step produced (everything the simulator records and plant_node publishes)."""

    n: int
    """Plant step index [-]."""
    t_s: float
    """Step start t_n = n * dt [s]."""
    meas: dict
    """Measurements at t_n (keys :data:`MEASUREMENTS`)."""
    u: AcInput
    """Command held over [t_n, t_n + dt)."""
    env: Environment
    """Truth environment at t_n (``Scenario.env_at``)."""
    pmv: float
    """Modified PMV at t_n [-]."""
    ppd: float
    """PPD of that PMV [%]."""
    pmv_lb: float
    """Lower PMV comfort bound at t_n [-]."""
    pmv_ub: float
    """Upper PMV comfort bound at t_n [-]."""
    comfort: OccupantComfort
    """Every comfort series at t_n (floats): PMV inputs at the occupant, draught, fog margin, validity."""
    out: PlantOutputs
    """Plant outputs of the step (powers, energies, state at t_{n+1})."""
    recirc_share_cmd: float = math.nan
    """The door command the plant applied over the step [0..1] (its default where ``u`` left the door alone)."""


class ScenarioPlant:
    """The cabin + A/C plant driven by a scenario's truth environment, from key-on.

    ``meas`` holds the measurements at t_n and ``cmd`` the last command applied
    (``KEY_ON_COMMAND`` before the first step).
    """

    def __init__(
        self,
        scenario: Scenario,
        plant_dt_s: float,
        params: PlantParams | None = None,
        *,
        plant_overrides: dict | None = None,
        comfort_overrides: dict | None = None,
        evaluation: PlantEvaluation | None = None,
    ):
        """Key-on state of ``scenario``.

        Args:
            scenario: the scenario (truth environment, bounds, initial state, occupant).
            plant_dt_s: plant step [s].
            params: plant parameters (default :class:`PlantParams`).
            plant_overrides: ``{PlantParams field: value}`` applied to ``params`` (sensitivity runs).
            comfort_overrides: ``{ComfortParams field or "part.field": value}`` applied to the scored PMV's
                parameters (``ceco_core.overrides.with_overrides``), and optionally
                :data:`SCORED_PA_OVERRIDE` (a fixed vapour pressure for the scored PMV).
            evaluation: how the step is evaluated (:class:`PlantEvaluation`; default the compiled fast
                path, the Python evaluation with one logged warning where it cannot be built).
        """
        if not (math.isfinite(plant_dt_s) and plant_dt_s > 0):
            raise ValueError(f"plant_dt_s must be finite and > 0, got {plant_dt_s!r}")
        self.scenario = scenario
        self.dt_s = plant_dt_s
        pp = scenario_plant_params(scenario, params, plant_overrides)
        co, self.scored_pa_pa = _split_comfort_overrides(comfort_overrides)
        # the plant's glazing transmittance and shell conductance: one value for physics and comfort
        self.comfort = with_overrides(
            comfort_params_for(scenario, glazing_tau=pp.tau_glass, u_shell_in_wm2k=pp.u_shell_in_wm2k),
            co,
            owner="ComfortParams",
        )
        self.plant = CabinPlant(
            pp, PlantState.from_initial(dataclasses.asdict(scenario.initial), pp, scenario.env_at(0.0))
        )
        st = self.plant.state
        aq = scenario.air_quality
        self.co2_sensor = (
            Co2Sensor(scenario.initial.co2_cab_ppm, scenario.seed, fail_s=aq.co2_sensor_fail_s)
            if aq.co2_sensor == "ndir"
            else None
        )
        """The car's cabin CO2 sensor (None: not fitted; its reading is then NaN)."""
        self.meas = {
            "t_cab_c": st.t_cab_c,
            "t_int_c": st.t_int_c,
            "t_shell_c": st.t_shell_c,
            "t_evap_c": st.t_evap_c,
            "t_vent_c": st.t_evap_c,
            "t_glass_c": st.t_glass_c,
            "rh_cab": scenario.initial.rh_cab,
            "co2_cab_ppm": scenario.initial.co2_cab_ppm,
            "co2_sensor_ppm": self._co2_reading(0.0, scenario.initial.co2_cab_ppm),
            "recirc_share": st.recirc_share,
        }
        self.cmd = KEY_ON_COMMAND
        self.n = 0
        self.evaluation = (evaluation or PlantEvaluation()).validate()
        self._fast = None
        if self.evaluation.evaluation == "compiled":
            try:
                self._fast = compiled_step(
                    pp, self.comfort, plant_dt_s, self.scored_pa_pa is not None, self.evaluation
                )[0]
            except CompileError as exc:
                fallback_warning(exc)

    @property
    def compiled(self) -> bool:
        """True if the steps run the compiled fast path (False: the Python evaluation)."""
        return self._fast is not None

    @property
    def t_s(self) -> float:
        """Time of the current measurements t_n = n * dt [s]."""
        return self.n * self.dt_s

    def step(self, u: AcInput) -> PlantStepRecord:
        """One plant step with ``u`` held over [t_n, t_n + dt) (sequence in the module docstring)."""
        meas, t = self.meas, self.t_s
        env = self.scenario.env_at(t)
        lb, ub = self.scenario.pmv_bounds(t)
        if self._fast is not None:
            c, out = self._step_compiled(u, env, meas)
        else:
            c, out = self._step_python(u, env, meas)
        rec = PlantStepRecord(
            n=self.n,
            t_s=t,
            meas=meas,
            u=u,
            env=env,
            pmv=float(c.pmv),
            ppd=float(c.ppd),
            pmv_lb=lb,
            pmv_ub=ub,
            comfort=c,
            out=out,
            recirc_share_cmd=self.plant.equation_input(u).recirc_share,
        )
        self.cmd = u
        self.n += 1
        self.meas = _measurements(out, self._co2_reading(self.t_s, out.co2_cab_ppm))
        return rec

    def _step_python(self, u: AcInput, env: Environment, meas: dict) -> tuple[OccupantComfort, PlantOutputs]:
        c = evaluate_cabin_comfort(
            t_cab_c=meas["t_cab_c"],
            t_vent_c=meas["t_vent_c"],
            t_int_c=meas["t_int_c"],
            t_shell_c=meas["t_shell_c"],
            t_glass_c=meas["t_glass_c"],
            rh_cab=meas["rh_cab"],
            mdot_bl_kgps=u.mdot_bl_kgps,
            solar_wm2=env.solar_wm2,
            params=self.comfort,
            pa_pa=self.scored_pa_pa,
        )
        c = OccupantComfort(
            **{
                f.name: (bool(getattr(c, f.name)) if f.name == "iso7730_valid" else float(getattr(c, f.name)))
                for f in dataclasses.fields(c)
            }
        )
        return c, self.plant.step(u, env, self.dt_s)

    def _step_compiled(self, u: AcInput, env: Environment, meas: dict) -> tuple[OccupantComfort, PlantOutputs]:
        """The step through the compiled code (:mod:`ceco_plant_sim.compiled_plant`): the same checks and errors."""
        if not isinstance(u, AcInput):
            raise ValueError(f"command: must be AcInput, got {type(u).__name__}")
        u.validate()
        env_v = Env._make(validate_environment(env))
        plant, fast = self.plant, self._fast
        assert fast is not None
        x1, g1, out, cv, ok = fast.step(
            plant.state_vector,
            plant.warm_start,
            plant.equation_input(u),
            env_v,
            float(meas["t_vent_c"]),
            float(meas["rh_cab"]),
            0.0 if self.scored_pa_pa is None else self.scored_pa_pa,
        )
        if not ok:
            raise PlantStepError(
                cycle_failure_message(plant.params.cycle_max_iter, f"compiled plant, step {self.n}, t = {self.t_s:g} s")
            )
        c = OccupantComfort(
            **{k: (v == 1.0 if k == "iso7730_valid" else v) for k, v in zip(COMFORT_NAMES, cv, strict=True)}
        )

        def outputs() -> PlantOutputs:
            o = dict(zip(OUTPUT_NAMES, out, strict=True))
            o["capacity_limited"] = o["capacity_limited"] == 1.0
            o["mop_active"] = o["mop_active"] == 1.0
            o["cycle_iterations"] = int(o["cycle_iterations"])
            return PlantOutputs(**o)

        return c, plant.commit(x1, g1, self.dt_s, outputs)

    def _co2_reading(self, t_s: float, co2_cab_ppm: float) -> float:
        """The CO2 sensor's reading at ``t_s`` [s] with the cabin at ``co2_cab_ppm`` [ppm]; NaN without a sensor."""
        return math.nan if self.co2_sensor is None else self.co2_sensor.read(t_s, co2_cab_ppm)
