"""A command sequence replayed open loop on a scenario's plant, step by step as a closed loop applies it.

:func:`replay_commands` drives :class:`~ceco_plant_sim.scenario_plant.ScenarioPlant` (key-on, truth
environment, scored comfort at t_n, ``CabinPlant.step`` over [t_n, t_n + dt)) with one command per
plant step and returns every per-step series: the measurements and the scored comfort at t_n, the
plant outputs of the step (state at t_{n+1}, step-mean powers, step energies). It is what a recorded
run, an optimal command sequence or a symbolic model is checked against (docs/plant.md, "The model
written once").

Pure logic: no rclpy, no message types.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ceco_core.contracts import MEASUREMENTS, AcInput
from ceco_v2x_preview.scenario import Scenario, load_scenario

from .compiled_plant import PlantEvaluation
from .plant_state import PlantOutputs
from .scenario_plant import ScenarioPlant

__all__ = ["OUTPUT_FIELDS", "REPLAY_SERIES", "Replay", "replay_commands"]

OUTPUT_FIELDS = tuple(f.name for f in dataclasses.fields(PlantOutputs))
"""The plant's per-step outputs (:class:`PlantOutputs` fields; booleans recorded as 0/1)."""

REPLAY_SERIES = (
    "t_s",
    "mdot_bl_kgps",
    "t_evap_sp_c",
    "recirc_share_cmd",
    *(f"meas_{k}" for k in MEASUREMENTS),
    "pmv",
    "pmv_lb",
    "pmv_ub",
    *OUTPUT_FIELDS,
)
"""Series of a :class:`Replay`, one value per plant step n: t_n [s], the command held over the step (the
door's command NaN where it was left alone), the measurements at t_n (``meas_*``), the scored PMV at t_n
and its bounds, then the plant outputs of the step (end-of-step states, step-mean powers, step energies)."""


@dataclasses.dataclass(frozen=True)
class Replay:
    """Per-step series of one replay (arrays of equal length, see :data:`REPLAY_SERIES`)."""

    scenario: str
    """Scenario name."""
    plant_dt_s: float
    """Plant step [s]."""
    series: dict
    """Series name -> float64 array, one value per plant step."""

    def energy_j(self) -> float:
        """Electrical energy over the run [J]: compressor + blower + condenser fan."""
        s = self.series
        return float(np.sum(s["p_comp_w"] + s["p_blower_w"] + s["p_cond_fan_w"]) * self.plant_dt_s)


def replay_commands(
    scenario: Scenario | str,
    mdot_bl_kgps,
    t_evap_sp_c,
    plant_dt_s: float = 1.0,
    *,
    recirc_share=None,
    plant_overrides: dict | None = None,
    comfort_overrides: dict | None = None,
    evaluation: PlantEvaluation | None = None,
) -> Replay:
    """Apply one command per plant step to the scenario's plant from key-on; return every per-step series.

    Args:
        scenario: a :class:`Scenario` or a bundled name / YAML path.
        mdot_bl_kgps: blower flow per plant step [kg/s] (actuator range 0.05-0.17).
        t_evap_sp_c: evaporator set-point per plant step [degC] (actuator range 3-10).
        plant_dt_s: plant step [s].
        recirc_share: commanded recirculated share per plant step [0..1] (NaN: the door left alone);
            None: the door is never commanded (the plant's default share).
        plant_overrides: ``{PlantParams field: value}``, as :class:`ScenarioPlant`.
        comfort_overrides: ``{ComfortParams field: value}``, as :class:`ScenarioPlant`.
        evaluation: the compiled fast path (default) or the Python evaluation, as :class:`ScenarioPlant`.

    Raises ValueError (naming the step) for sequences of different lengths, longer than the
    scenario, or a command outside the actuator bounds.
    """
    sc = load_scenario(scenario) if isinstance(scenario, str) else scenario
    m = np.asarray(mdot_bl_kgps, dtype=float)
    t = np.asarray(t_evap_sp_c, dtype=float)
    rs = np.full(m.shape, np.nan) if recirc_share is None else np.asarray(recirc_share, dtype=float)
    if m.ndim != 1 or m.shape != t.shape or rs.shape != m.shape:
        raise ValueError(
            f"commands: mdot_bl_kgps {m.shape}, t_evap_sp_c {t.shape} and recirc_share {rs.shape} must be 1-D "
            "of equal length"
        )
    if m.size * plant_dt_s > sc.duration_s + 1e-9:
        raise ValueError(f"commands: {m.size} steps of {plant_dt_s} s exceed the scenario's {sc.duration_s} s")
    sp = ScenarioPlant(
        sc, plant_dt_s, plant_overrides=plant_overrides, comfort_overrides=comfort_overrides, evaluation=evaluation
    )
    cols: dict[str, list] = {k: [] for k in REPLAY_SERIES}
    for n in range(m.size):
        try:
            u = AcInput(mdot_bl_kgps=float(m[n]), t_evap_sp_c=float(t[n]), recirc_share=float(rs[n]))
        except ValueError as err:
            raise ValueError(f"commands: step {n}: {err}") from err
        r = sp.step(u)
        cols["t_s"].append(r.t_s)
        cols["mdot_bl_kgps"].append(u.mdot_bl_kgps)
        cols["t_evap_sp_c"].append(u.t_evap_sp_c)
        cols["recirc_share_cmd"].append(u.recirc_share)
        for k in MEASUREMENTS:
            cols[f"meas_{k}"].append(float(r.meas[k]))
        cols["pmv"].append(r.pmv)
        cols["pmv_lb"].append(r.pmv_lb)
        cols["pmv_ub"].append(r.pmv_ub)
        for k in OUTPUT_FIELDS:
            cols[k].append(float(getattr(r.out, k)))
    series = {k: np.asarray(v, dtype=np.float64) for k, v in cols.items()}
    return Replay(scenario=sc.name, plant_dt_s=float(plant_dt_s), series=series)
