"""The whole-drive optimum ("oracle"): the least energy at a bounded discomfort with perfect knowledge.

An optimal control problem over the whole drive of a scenario (docs/oracle.md): the true weather,
speed, comfort band and key-on state are known; the decisions are the blower flow and the evaporator
set-point per control period Ts (held between, as every controller's), within the actuator bounds of
every controller, and, where the controllers it bounds may move the recirculation door
(``OracleSettings.door_logic``), the door's recirculated share too, with the scenario's air-quality
limits (cabin CO2, fog margin) as constraints at every interval's end. The objective is the benchmark's
energy (compressor + blower + condenser fan, ``PlantModel.energy`` ``e_total_j``); the benchmark's discomfort
(``ceco_core.kpis.discomfort_pmvh``, the fixed band's distance of the scored PMV integrated over the drive) is
a constraint ``<= level`` (epsilon-constraint), written exactly with one slack per plant step
(``s_n >= pmv_n - 0.5``, ``s_n >= -0.5 - pmv_n``, ``s_n >= 0``, ``sum s_n dt / 3600 <= level``). The plant is the smooth
symbolic model written once (``ceco_plant_sim.plant_model.PlantModel.smooth``): multiple shooting on the
control intervals (each interval is Ts / dt chained plant steps), IPOPT with exact first derivatives and a
limited-memory Hessian, started from a replayed production-law run and warm-started from level to level.

The optimal command sequence is then replayed open loop on the numeric plant through the simulator
(:func:`ceco_controller.closed_loop.simulate` with a :class:`ScheduleController`) and scored with
``ceco_core.kpis.compute_kpis`` exactly like every benchmark run: the oracle's points are those
replayed KPIs, never the NLP's own values (both are reported).

An NLP solver finds a local optimum: the oracle is an achievable point, not a proven global bound.

Pure logic: no rclpy.
"""

from __future__ import annotations

import collections
import dataclasses
import logging
import math
import os
import threading
import time
from collections.abc import Sequence
from typing import Any

import casadi
import numpy as np

from ceco_core.codegen import (
    Compiled,
    CompileError,
    check_compile_settings,
    codegen_cache_dir,
    compile_cached,
    generate_functions,
)
from ceco_core.contracts import ACTUATOR_LIMITS, PLANT_STEP_S, RECIRC_SHARE_MAX, RECIRC_SHARE_MIN, AcInput, Diagnostics
from ceco_core.kpis import COMFORT_BAND_PMV, compute_kpis
from ceco_core.mathops import smooth_min
from ceco_core.metrics import PMV_SCALE_LIMIT

from .solvers import IterationCallback

__all__ = [
    "COMPILED_MODES",
    "DOOR_INPUT_NAMES",
    "INPUT_NAMES",
    "LevelResult",
    "OracleProblem",
    "OracleSettings",
    "OracleStopped",
    "STALLED",
    "STALL_LEVEL_RTOL",
    "ScheduleController",
    "StallRule",
    "compiled_step",
    "edge_arrival_s",
    "oracle_cache_dir",
    "solve_front",
    "solve_levels",
    "solve_levels_holding_edge",
]

INPUT_NAMES = ("mdot_bl_kgps", "t_evap_sp_c")
"""The decisions per control period, by name (``PlantModel.input`` order is looked up, never assumed)."""
DOOR_INPUT_NAMES = (*INPUT_NAMES, "recirc_share")
"""The decisions with the door free (``OracleSettings.door_logic`` given): the recirculated share [-] too."""

J_PER_KWH = 3.6e6

COMPILED_MODES = ("auto", "yes", "no")
"""``OracleSettings.compiled``: compiled C where it can be built (else the virtual machine), compiled or an
error, CasADi's virtual machine."""

_LOG = logging.getLogger(__name__)

WALL_TIME_PER_DRIVE_S = 1.5
"""The default IPOPT wall-time limit per level [s] per second of drive (``OracleSettings.max_wall_time_s``)."""
WALL_TIME_MIN_S = 900.0
"""The default IPOPT wall-time limit per level is never below this [s] (short drives on a loaded machine)."""

_STATE_SCALE = {"w_cab_kgkg": 0.01, "comp_pi_integral_rpm": 1000.0, "recirc_share": 1.0, "co2_cab_kgkg": 0.001}
"""Nominal magnitudes of the states that are not temperatures [unit] (the NLP's variables are x / scale)."""


def _is_time_and_cap(v, lo: float) -> bool:
    """``v`` is (t_from >= 0 [s], cap in (lo, +0.5] [PMV]), both finite numbers (no flags)."""
    return (
        isinstance(v, tuple)
        and len(v) == 2
        and all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v)
        and v[0] >= 0
        and lo < v[1] <= COMFORT_BAND_PMV[1]
    )


@dataclasses.dataclass(frozen=True)
class OracleSettings:
    """Settings of the whole-drive optimum."""

    control_period_s: float | None = None
    """Control period Ts [s] of the decisions; None: the case's (or the scenario's)."""
    plant_dt_s: float = PLANT_STEP_S
    """Plant step [s] (the simulator's)."""
    max_iter: int = 400
    """IPOPT iterations per level (per form: the lifted form's attempt has ``lifted_max_iter``)."""
    lifted_max_iter: int = 300
    """IPOPT iterations of the lifted form's attempt at a level before it is solved again with the energy
    summed (``lift_energy``; :func:`solve_levels`). Measured in the full benchmark with the oracle (68 levels,
    docs/oracle.md "Lifted energy"): every level the lifted form solved took <= 245 iterations; the three it did
    not solve ran to the 400 of ``max_iter`` (280-450 s each) before the summed form took over, next to the
    optimum without meeting the tolerance (udds-hot's and hotsoak-pulldown's least levels, traced: the
    discomfort within 0.03 % of the level, the primal infeasibility jumping between 1e-6 and 0.6)."""
    stall_iter: int = 50
    """The lifted form's attempt at a level stops as stalled (status :data:`STALLED`) once its objective has stayed
    within ``stall_rtol`` of itself for ``stall_iter`` iterations (:class:`StallRule`). Its least violating
    iterate of those is replayed on the plant and kept as the level's point, uncertified, when the replay meets
    the level within :data:`STALL_LEVEL_RTOL`; else the summed form takes the level, as after ``lifted_max_iter``.
    0: never. The summed form, the last attempt, is never stopped so: its solves of the stalled levels hover
    as long before they converge (udds-hot's least level: within 0.02 % of its optimum from iteration 60 to
    200, solved at 231; docs/oracle.md "Stalled attempts")."""
    stall_rtol: float = 3e-5
    """Relative range of the objective under which ``stall_iter`` iterations count as flat."""
    max_wall_time_s: float | None = None
    """IPOPT wall-time limit per level [s] (a level that hits it is 'not solved' unless acceptable); None: the
    larger of :data:`WALL_TIME_MIN_S` and :data:`WALL_TIME_PER_DRIVE_S` per second of drive (900 s up to a
    600-s drive, 2054 s on udds-hot's 1369 s: the cost of an iteration grows with the drive's length, and a
    flat 900 s left udds-hot's least level fewer iterations than sc03's)."""
    tol: float = 1e-6
    """IPOPT tolerance."""
    pmv_clip_k: float = 20.0
    """Sharpness [1/PMV] of the smooth clip at the PMV scale limit (log-sum-exp; error <= ln 2 / k at the
    clip only, where the plant's PMV reaches the scale's end: the pull-down's first seconds)."""
    lbfgs_history: int = 50
    """Pairs of the limited-memory Hessian approximation (IPOPT's ``limited_memory_max_history``; its default 6
    left the least-discomfort level of sc03's first 300 s unsolved after 400 iterations, 50 solved it in 65)."""
    expand: bool = False
    """Expand the NLP into one SX graph. Off: the MX form maps the interval's SX function (built in seconds
    where the expansion of a whole drive took 150-240 s; the same cost per iteration since the cycle table's
    ``TableCall``)."""
    guess_setpoint_c: float | None = None
    """The production law's cabin set-point of the initial guess [degC]; None: its default."""
    compiled: str = "auto"
    """How the plant steps of the NLP are evaluated (docs/oracle.md "Compiled plant steps"): ``auto`` as
    compiled C (generated from the one-step interval's SX Function with its derivatives, compiled once and
    cached on disk) where a C compiler works and the cache can be written, else CasADi's virtual machine (one
    log line says which and why); ``yes`` compiled or a :class:`~ceco_core.codegen.CompileError`; ``no`` the
    virtual machine. The same NLP either way (values bit for bit, derivatives within 1e-12 relative), but on a
    whole drive IPOPT's iterates drift apart: the solutions agree within its tolerance, not to the digit."""
    compiler: str | None = None
    """C compiler of the compiled plant steps (a name on PATH or a path); None: $CC, gcc, cc."""
    compile_flags: tuple[str, ...] = ("-O1",)
    """Compiler flags (part of the cache key; ``-O1``: the constraint Jacobian 3-4 times faster than the virtual
    machine for 13-19 s of compilation; ``-O2`` no faster; ``-O0`` 1.3-1.6 times)."""
    cache_dir: str | None = None
    """Directory of the compiled objects; None: :func:`oracle_cache_dir` ($CECO_CACHE_DIR/oracle, else
    $XDG_CACHE_HOME/ceco/oracle, else ~/.cache/ceco/oracle)."""
    door_logic: tuple = ()
    """The production door logic (``ceco_core.recirc_law.RecircSettings`` items, as a benchmark case's
    ``baseline_door``). Empty: the door is no decision, the plant holds its default share (the oracle of the
    cases whose controllers leave the door alone). Given: the recirculated share is the third decision, the
    scenario's CO2 limit and fog bound are constraints, and the initial guess is the production law run
    with this door logic (the oracle gets the permissions of the controllers it bounds, no more)."""
    co2_margin_ppm: float = 10.0
    """Margin [ppm] the NLP keeps below the scenario's CO2 limit (the replay on the numeric plant is scored
    against the limit itself; the smooth model's states differ from the plant's by a little)."""
    fog_margin_extra_k: float = 0.1
    """Margin [K] the NLP keeps above the scenario's fog bound (the same reason)."""
    hold_edge_from_s: float | None = None
    """From this time [s after key-on] on, the scored PMV of every plant step stays inside the comfort band (its
    slack bounded to 0, so -0.5 <= PMV <= +0.5): the bound of a controller that, once the pull-down has come to
    the band's upper edge, never goes back above it (:func:`solve_levels_holding_edge`, docs/oracle.md "The
    oracle that holds the edge"). None: no such constraint (the benchmark's oracle, which may cross the edge
    where the integrated discomfort allows)."""
    band_mean_pmv: tuple[float, float] | None = None
    """(t_from [s after key-on], cap [PMV]): the mean scored PMV of the plant steps from t_from on is at most cap (one
    constraint row). With t_from the band phase's start and cap a controller's band-phase mean PMV (KPI
    ``pmv_mean_band``), the bound of a controller that keeps that controller's margin under the edge on average
    (``tools/edge_headroom.py --with-margin``). None: no such constraint."""
    band_cap_pmv: tuple[float, float] | None = None
    """(t_from [s after key-on], cap [PMV]): the scored PMV of every plant step from t_from on is at most cap. With cap
    a controller's band-phase mean PMV, the bound of a controller that keeps that margin at every step, not only on
    average (``band_mean_pmv``): it may not move its PMV between the times when cooling is cheap and dear
    (``tools/edge_headroom.py --pointwise``). None: no such constraint."""
    terminal_max: tuple = ()
    """((state name, value), ...): the plant's state at the drive's end is at most these values (``STATE_NAMES`` of
    ``ceco_plant_sim.plant_model``, its units: e.g. ``("t_int_c", 36.3)`` [degC]). With a controller's end state, the
    bound of a controller that leaves the car as cool as that one: the whole-drive optimum may otherwise spend, in
    its last minute, the cold stored in the cabin's masses, which is worth nothing once the drive ends but which no
    controller that does not know the drive's end can spend (``tools/edge_headroom.py --terminal``, docs/oracle.md
    "The drive's end"). Empty: no such constraint (the benchmark's oracle)."""
    lift_energy: bool = True
    """Each control interval's energy as a variable of the NLP, tied to the plant steps by one equality row
    (the objective then is their sum, linear). The same optimum; IPOPT's objective and gradient no longer run
    the drive's plant steps (the constraint Jacobian it needs anyway carries their derivatives): off, they
    were 31 % of an iteration on sc03-paper (docs/oracle.md "Lifted energy"). False: the energy summed in
    the objective (the form of before, kept as the reference of ``tools/bench_oracle.py --forms``)."""

    def validate(self) -> OracleSettings:
        """Raise ValueError naming the field if a setting is not usable; return self."""
        if self.control_period_s is not None and not (
            math.isfinite(self.control_period_s) and self.control_period_s > 0
        ):
            raise ValueError(f"OracleSettings.control_period_s: must be finite and > 0, got {self.control_period_s}")
        if not (math.isfinite(self.plant_dt_s) and self.plant_dt_s > 0):
            raise ValueError(f"OracleSettings.plant_dt_s: must be finite and > 0, got {self.plant_dt_s}")
        if not (isinstance(self.lbfgs_history, int) and self.lbfgs_history >= 1):
            raise ValueError(f"OracleSettings.lbfgs_history: must be an int >= 1, got {self.lbfgs_history!r}")
        for name in ("max_iter", "lifted_max_iter"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, int) and v >= 1):
                raise ValueError(f"OracleSettings.{name}: must be an int >= 1, got {v!r}")
        if isinstance(self.stall_iter, bool) or not (isinstance(self.stall_iter, int) and self.stall_iter >= 0):
            raise ValueError(f"OracleSettings.stall_iter: must be an int >= 0 (0: off), got {self.stall_iter!r}")
        if isinstance(self.stall_rtol, bool) or not (
            isinstance(self.stall_rtol, (int, float)) and math.isfinite(self.stall_rtol) and 0 < self.stall_rtol < 1
        ):
            raise ValueError(f"OracleSettings.stall_rtol: must be in (0, 1), got {self.stall_rtol!r}")
        for name in ("max_wall_time_s", "tol", "pmv_clip_k"):
            v = getattr(self, name)
            if name == "max_wall_time_s" and v is None:
                continue
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"OracleSettings.{name}: must be finite and > 0, got {v}")
        h = self.hold_edge_from_s
        bad_h = isinstance(h, bool) or not isinstance(h, (int, float)) or not (math.isfinite(h) and h >= 0)
        if h is not None and bad_h:
            raise ValueError(f"OracleSettings.hold_edge_from_s: must be None or finite and >= 0 [s], got {h!r}")
        for name, lo in (("band_mean_pmv", 0.0), ("band_cap_pmv", COMFORT_BAND_PMV[0])):
            v = getattr(self, name)
            if v is not None and not _is_time_and_cap(v, lo):
                raise ValueError(
                    f"OracleSettings.{name}: must be None or (t_from >= 0 [s], cap in ({lo:g}, "
                    f"{COMFORT_BAND_PMV[1]:g}] [PMV]), got {v!r}"
                )
        tm = self.terminal_max
        if not (
            isinstance(tm, tuple)
            and all(
                isinstance(it, tuple)
                and len(it) == 2
                and isinstance(it[0], str)
                and isinstance(it[1], (int, float))
                and not isinstance(it[1], bool)
                and math.isfinite(it[1])
                for it in tm
            )
        ):
            raise ValueError(
                f"OracleSettings.terminal_max: must be a tuple of (state name, finite value) pairs, got {tm!r}"
            )
        if not isinstance(self.lift_energy, bool):
            raise ValueError(f"OracleSettings.lift_energy: must be True or False, got {self.lift_energy!r}")
        if self.compiled not in COMPILED_MODES:
            raise ValueError(f"OracleSettings.compiled: must be one of {COMPILED_MODES}, got {self.compiled!r}")
        if self.compiled == "yes" and self.expand:
            raise ValueError(
                "OracleSettings.compiled: 'yes' needs expand False (a compiled call cannot be expanded to SX)"
            )
        check_compile_settings("OracleSettings", self.compiler, self.compile_flags, self.cache_dir, "compile_flags")
        for name in ("co2_margin_ppm", "fog_margin_extra_k"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v >= 0):
                raise ValueError(f"OracleSettings.{name}: must be finite and >= 0, got {v!r}")
        if self.door_logic:
            from ceco_core.recirc_law import RecircSettings

            try:
                door = RecircSettings(**dict(self.door_logic)).validate()
            except (TypeError, ValueError) as exc:
                raise ValueError(f"OracleSettings.door_logic: {exc}") from None
            if door.door_mode == "none":
                raise ValueError("OracleSettings.door_logic: door_mode 'none' commands no door; leave door_logic empty")
        return self


def oracle_cache_dir(path: str | None = None) -> str:
    """Directory of the oracle's compiled objects: ``path``, else ``ceco_core.codegen.codegen_cache_dir()/oracle``."""
    return str(path) if path else os.path.join(codegen_cache_dir(), "oracle")


class ScheduleController:
    """Applies a fixed command per control step (the oracle's open-loop replay in the simulator)."""

    def __init__(self, commands: np.ndarray, names: Sequence[str] = INPUT_NAMES) -> None:
        c = np.asarray(commands, dtype=float)
        self.names = tuple(names)
        """The columns' names (:data:`INPUT_NAMES` or :data:`DOOR_INPUT_NAMES`)."""
        if self.names not in (INPUT_NAMES, DOOR_INPUT_NAMES):
            raise ValueError(f"ScheduleController: names must be {INPUT_NAMES} or {DOOR_INPUT_NAMES}, got {self.names}")
        if c.ndim != 2 or c.shape[1] != len(self.names) or not np.all(np.isfinite(c)):
            raise ValueError(f"ScheduleController: commands must be a finite K x {len(self.names)} array")
        self.commands = c
        """Per control step the command, columns :attr:`names`."""

    def compute(self, obs):
        """The command of control step ``obs.k`` (ValueError past the schedule's end)."""
        if obs.k >= len(self.commands):
            raise ValueError(f"ScheduleController: control step {obs.k} is past the schedule's {len(self.commands)}")
        row = dict(zip(self.names, self.commands[obs.k].tolist(), strict=True))
        cmd = AcInput(**row)
        return cmd, Diagnostics(k=obs.k, t_s=obs.t_s, status="schedule", success=True)


@dataclasses.dataclass
class LevelResult:
    """One discomfort level: the NLP's solution, its replay on the plant and the replay's KPIs."""

    level_pmvh: float
    """The discomfort bound [PMV h]."""
    status: str
    """IPOPT's return status (or the reason the level was not attempted); ``<status>; replay: the simulation
    stopped: ...`` when the plant could not replay the NLP's point (then no point)."""
    success: bool
    """The level has a point: IPOPT reported success (or an acceptable point), or a stalled attempt's point met the
    level (:attr:`certified` False); the replay ran."""
    iterations: int
    """IPOPT iterations (of both attempts when the level was solved again in the summed form)."""
    wall_time_s: float
    """Wall time of the solve [s] (of both attempts, likewise)."""
    form: str = "lifted"
    """The NLP's form that gave the result: ``lifted`` (the energy lifted, :attr:`OracleSettings.lift_energy`),
    ``summed`` (the setting off) or ``lifted, then summed`` (the lifted solve failed; the level was solved again
    in the summed form from the same start)."""
    input_names: tuple = INPUT_NAMES
    """The columns of :attr:`commands` (:data:`INPUT_NAMES`, or :data:`DOOR_INPUT_NAMES` with the door free)."""
    commands: np.ndarray | None = None
    """Per control step the optimal command, columns :attr:`input_names`."""
    nlp_energy_kwh: float | None = None
    """The NLP's energy (smooth model) [kWh]."""
    nlp_discomfort_pmvh: float | None = None
    """The NLP's discomfort (smooth model: the band distance of its PMV) [PMV h]."""
    nlp_pmv: np.ndarray | None = None
    """The NLP's scored PMV per plant step (smooth model), for the replay's comparison."""
    kpis: dict | None = None
    """``compute_kpis`` of the replay on the numeric plant (the oracle's point)."""
    run: object | None = None
    """The replay's :class:`~ceco_controller.closed_loop.RunResult`."""
    certified: bool = False
    """IPOPT certified the point (``Solve_Succeeded`` or ``Solved_To_Acceptable_Level``). A level can have a point
    without (:attr:`success` True, status :data:`STALLED`): the lifted attempt stalled and its least violating
    iterate, replayed on the plant, met the level within :data:`STALL_LEVEL_RTOL`."""
    evaluation: str = ""
    """How the NLP's plant steps were evaluated (:attr:`OracleProblem.evaluation`): on a whole drive the compiled
    and the virtual machine's solves differ beyond the last digits (docs/oracle.md "Compiled plant steps")."""


STALLED = "Stalled"
"""The status of an attempt :class:`StallRule` stopped (IPOPT's own is ``User_Requested_Stop``)."""

STALL_LEVEL_RTOL = 0.005
"""A stalled attempt's point is kept when its replayed discomfort is at most the level times (1 + this): the
replays of the full benchmark's certified levels land at most 0.05 % above theirs (mild-day's 0.0571 PMV h)."""


class StallRule:
    """When an IPOPT attempt has stalled: its objective flat over a window of iterations.

    Fed the objective of every iterate (:meth:`update`). Stalled at iterate i >= ``window`` when over iterates
    i - window .. i the objective's range is below ``rtol`` times |f_i|. Calibrated on the IPOPT histories of
    the full benchmark's lifted attempts (docs/oracle.md "Stalled attempts"): with 50 iterations, the levels the
    lifted form solves never stay flatter than 1.2e-4 over a window (highway-to-city's least level, in the 50
    iterations before it converged), the three it did not solve are flatter than 3e-5 from iteration 134, 201
    and 205 on (udds-hot, hot-commute-1p, hotsoak-pulldown; at their flattest 1.8e-6..2.6e-5). ``window`` 0:
    never stalled.
    """

    def __init__(self, window: int, rtol: float) -> None:
        self.window = int(window)
        self.rtol = float(rtol)
        self.reset()

    def reset(self) -> None:
        """Forget the history (a new attempt)."""
        self.objective: list[float] = []
        self.stopped_at: int | None = None

    def update(self, objective: float) -> bool:
        """Record one iterate's objective; True when the attempt has stalled (and at every later call)."""
        self.objective.append(float(objective))
        i, w = len(self.objective) - 1, self.window
        if self.stopped_at is None and w and i >= w:
            win = self.objective[i - w :]
            if max(win) - min(win) < self.rtol * abs(self.objective[i]):
                self.stopped_at = i
        return self.stopped_at is not None


class _IterationWatch(IterationCallback):
    """IPOPT's iteration callback: feeds a :class:`StallRule` and asks IPOPT to stop when it says stalled.

    Keeps the last ``window + 1`` iterates with their constraint violation (max-norm, unscaled, against the NLP's
    bounds) for :meth:`best`.
    """

    def __init__(self, rule: StallRule, n_x: int, lbg: np.ndarray, ubg: np.ndarray) -> None:
        casadi.Callback.__init__(self)
        self.rule = rule
        self.sizes = {"x": n_x, "f": 1, "g": lbg.size}
        self._lbg, self._ubg = lbg, ubg
        self._recent: collections.deque = collections.deque(maxlen=rule.window + 1)
        self.construct("oracle_stall_watch", {})

    def reset(self) -> None:
        """A new attempt: the rule and the kept iterates forgotten."""
        self.rule.reset()
        self._recent.clear()

    def best(self) -> np.ndarray | None:
        """Of the last ``window + 1`` iterates (a stalled attempt's flat window) the least violating (None: none)."""
        return min(self._recent, key=lambda vx: vx[0])[1] if self._recent else None

    def eval(self, arg):
        g = np.asarray(arg[2], dtype=float).ravel()
        viol = float(np.max(np.maximum(np.maximum(self._lbg - g, g - self._ubg), 0.0), initial=0.0))
        self._recent.append((viol, np.asarray(arg[0], dtype=float).ravel().copy()))
        return [1 if self.rule.update(float(arg[1])) else 0]


class OracleProblem:
    """The whole-drive OCP of one scenario, built once and solved at any discomfort level."""

    def __init__(self, scenario, settings: OracleSettings | None = None) -> None:
        from ceco_plant_sim.plant_model import PlantModel
        from ceco_plant_sim.scenario_plant import n_plant_steps, scenario_plant_params

        self.settings = s = (settings or OracleSettings()).validate()
        self.scenario = scenario
        ts = scenario.control.timing(s.control_period_s)[0]
        ratio = ts / s.plant_dt_s
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError(f"oracle: Ts {ts} s must be a whole multiple of the plant step {s.plant_dt_s} s")
        self.control_period_s = ts
        self.steps_per_control = m = int(round(ratio))
        n = n_plant_steps(scenario.duration_s, s.plant_dt_s)
        self.n_control = k = -(-n // m)
        """Number of control intervals (the last one may be cut short by the drive's end)."""
        self.n_steps = n
        self.max_wall_time_s = float(
            s.max_wall_time_s
            if s.max_wall_time_s is not None
            else max(WALL_TIME_MIN_S, WALL_TIME_PER_DRIVE_S * n * s.plant_dt_s)
        )
        """IPOPT's wall-time limit per level [s] (the setting, or its default for this drive's length)."""
        self.door = bool(s.door_logic)
        """The door is a decision (``settings.door_logic`` given)."""
        self.input_names = DOOR_INPUT_NAMES if self.door else INPUT_NAMES
        """The decisions' names per control period (the columns of every command array of this problem)."""
        self.limits = scenario.air_quality.limits
        """The scenario's air-quality limits (``ceco_core.air_quality.AirQualityLimits``)."""
        # the scenario's plant: its occupants and ambient CO2 are parameters of the plant
        params = scenario_plant_params(scenario)
        self.model = pm = PlantModel.smooth(params, plant_dt_s=s.plant_dt_s, door_input=self.door)
        x0, envs, comfort, pa = pm.scenario_drive(scenario, n)
        self.x0, self.envs, self.comfort, self.pa_pa = x0, envs, comfort, pa
        self._iu = [pm.input.index(nm) for nm in self.input_names]
        self._scale = np.array([_STATE_SCALE.get(nm, 10.0) for nm in pm.state.names])
        self.evaluation = ""
        """How the NLP's plant steps are evaluated: ``compiled (<object>)`` or ``virtual machine (<why>)``."""
        self.compiled: Compiled | None = None
        """The compiled object's cache lookup (None: the virtual machine)."""
        self._build(k, m, n)

    # ------------------------------------------------------------------ build
    def _interval(self, m: int, name: str = "oracle_interval") -> casadi.Function:
        """One control interval: (x, u, t_vent_in, E[4 x m], mask[m]) -> (x_next, energy [J], pmv[m], t_vent_out)."""
        pm = self.model
        x = casadi.SX.sym("x", pm.state.size)
        u = casadi.SX.sym("u", pm.input.size)
        tv = casadi.SX.sym("tv")
        e = casadi.SX.sym("E", pm.env.size, m)
        mask = casadi.SX.sym("mask", m)
        pmv_f = pm.scored_pmv(self.comfort, self.pa_pa)
        i_e, i_tv = pm.energy.index("e_total_j"), pm.y.index("t_vent_c")
        xk, tvk, energy, pmvs = x, tv, 0, []
        for j in range(m):
            pmvs.append(pmv_f(xk, tvk, u, e[:, j]))
            x1, en, y = pm.step(xk, u, e[:, j])
            # a step past the drive's end (mask 0) leaves the state and adds nothing
            xk = casadi.if_else(mask[j] > 0.5, x1, xk)
            tvk = casadi.if_else(mask[j] > 0.5, y[i_tv], tvk)
            energy = energy + mask[j] * en[i_e]
        return casadi.Function(
            name, [x, u, tv, e, mask], [xk, energy, casadi.vertcat(*pmvs), tvk], _INTERVAL_IN, _INTERVAL_OUT, _DIFF_OPTS
        )

    def _interval_function(self, m: int) -> casadi.Function:
        """The interval the NLP maps: compiled plant steps chained in MX, or the SX Function (virtual machine).

        Sets :attr:`evaluation` (which, and why) and :attr:`compiled` (the cache lookup, or None).
        """
        s = self.settings
        self.compiled = None
        if s.compiled == "no" or s.expand:
            why = "compiled 'no'" if s.compiled == "no" else "expand: a compiled call cannot be expanded"
            self.evaluation = f"virtual machine ({why})"
            return self._interval(m)
        try:
            step, self.compiled = compiled_step(self._interval(1, _STEP_NAME), s)
        except CompileError as exc:
            if s.compiled == "yes":
                raise CompileError(f"oracle: compiled 'yes' but the plant steps cannot be compiled: {exc}") from exc
            self.evaluation = f"virtual machine (no compiled plant steps: {exc})"
            _LOG.warning("oracle: %s", self.evaluation)
            return self._interval(m)
        c = self.compiled
        self.evaluation = f"compiled ({c.path})"
        _LOG.info("oracle: plant steps %s, %s in %.1f s", self.evaluation, "built" if c.built else "cached", c.seconds)
        return _chained(step, m)

    def _build(self, k: int, m: int, n: int) -> None:
        s, pm = self.settings, self.model
        nx, nu = pm.state.size, pm.input.size
        self.interval_function = self._interval_function(m)
        """The control interval the NLP maps over the drive (compiled steps chained in MX, or the SX Function)."""
        f = self.interval_function.map(k)
        envs = np.zeros((k * m, pm.env.size))
        envs[:n] = self.envs
        envs[n:] = self.envs[-1]
        mask = np.zeros(k * m)
        mask[:n] = 1.0
        self._mask = mask
        e_par = casadi.DM(envs.T)  # 4 x (k m): the map hands interval i the columns i m .. i m + m - 1
        scale = casadi.DM(self._scale)
        xs = casadi.MX.sym("xs", nx, k + 1)
        us = casadi.MX.sym("u", nu, k)
        tv = casadi.MX.sym("tv", 1, k)
        sl = casadi.MX.sym("s", 1, k * m)
        level = casadi.MX.sym("level")
        x = xs * casadi.repmat(scale, 1, k + 1)
        x_next, energy, pmv, tv_out = f(x[:, :k], us, tv, e_par, casadi.DM(mask.reshape(k, m).T))
        pmv = casadi.reshape(pmv, 1, k * m)
        lo, hi = COMFORT_BAND_PMV
        pc = smooth_min(pmv, PMV_SCALE_LIMIT, s.pmv_clip_k)
        mask_row = casadi.DM(mask).T
        dt_h = s.plant_dt_s / 3600.0
        g = [
            casadi.vec((x_next - x[:, 1:]) / casadi.repmat(scale, 1, k)),
            casadi.vec(tv_out[:, : k - 1] - tv[:, 1:]),
        ]
        n_dyn = nx * k + (k - 1)
        # the lifted energy: one variable per interval [J / energy_scale_j], one row tying it to the plant steps
        self.energy_scale_j = m * s.plant_dt_s * 1000.0
        """Scale of the lifted energy variables [J]: one kW over a control interval."""
        en = casadi.MX.sym("en", 1, k if s.lift_energy else 0)
        self.lifted_rows = slice(n_dyn, n_dyn + en.numel())
        """The lifted energy's rows in the constraint vector (they follow the dynamics'; empty in the summed form)."""
        if s.lift_energy:
            g.append(casadi.vec(energy / self.energy_scale_j - en))
            n_dyn += k
        g += [
            casadi.vec(sl - (pc - hi) * mask_row),
            casadi.vec(sl - (lo - pmv) * mask_row),
            casadi.sum2(sl) * dt_h - level,
        ]
        self._lbg = np.concatenate([np.zeros(n_dyn), np.zeros(2 * k * m), [-np.inf]])
        self._ubg = np.concatenate([np.zeros(n_dyn), np.full(2 * k * m, np.inf), [0.0]])
        # the PMV of plant step i (the state at t_i = i dt) held from hold_edge_from_s on: inside the band (its slack
        # bounded to 0, below)
        t_step = np.arange(n) * s.plant_dt_s
        held = np.zeros(n, dtype=bool) if s.hold_edge_from_s is None else t_step >= s.hold_edge_from_s - 1e-9
        if s.band_mean_pmv is not None:
            # the mean PMV from t_from on at most the cap: one row
            idx = [int(i) for i in np.flatnonzero(t_step >= s.band_mean_pmv[0] - 1e-9)]
            if idx:
                g.append(casadi.sum2(pc[:, idx]) / len(idx))
                self._lbg = np.concatenate([self._lbg, [-np.inf]])
                self._ubg = np.concatenate([self._ubg, [s.band_mean_pmv[1]]])
        if s.band_cap_pmv is not None:
            # the PMV of every plant step from t_from on at most the cap: one row per step
            idx = [int(i) for i in np.flatnonzero(t_step >= s.band_cap_pmv[0] - 1e-9)]
            if idx:
                g.append(casadi.vec(pc[:, idx]))
                self._lbg = np.concatenate([self._lbg, np.full(len(idx), -np.inf)])
                self._ubg = np.concatenate([self._ubg, np.full(len(idx), s.band_cap_pmv[1])])
        if self.door:
            # the air-quality limits at every interval's end, with the settings' margins [ppm / 1000, K]
            # (aq_violation's g <= 0; CO2 moves with a time constant of minutes: the ends of the control
            # intervals sample it densely)
            aq = pm.air_quality.map(k)(x[:, 1:])
            g += [
                casadi.vec((aq[0, :] - (self.limits.co2_limit_ppm - s.co2_margin_ppm)) / 1000.0),
                casadi.vec(self.limits.fog_margin_min_k + s.fog_margin_extra_k - aq[1, :]),
            ]
            self._lbg = np.concatenate([self._lbg, np.full(2 * k, -np.inf)])
            self._ubg = np.concatenate([self._ubg, np.zeros(2 * k)])
        self._w = [casadi.vec(xs), casadi.vec(us), casadi.vec(tv), casadi.vec(sl), casadi.vec(en)]
        self._sizes = [nx * (k + 1), nu * k, k, k * m, en.numel()]
        w = casadi.vertcat(*self._w)
        model_energy = casadi.sum2(energy) / J_PER_KWH
        obj = casadi.sum2(en) * (self.energy_scale_j / J_PER_KWH) if s.lift_energy else model_energy
        dist = casadi.fmax(0, casadi.fmax(casadi.fmin(pmv, PMV_SCALE_LIMIT) - hi, lo - pmv)) * mask_row
        self._nlp_eval = casadi.Function("oracle_eval", [w], [model_energy, casadi.sum2(dist) * dt_h, pmv, energy])
        nlp = {"x": w, "f": obj, "g": casadi.vertcat(*g), "p": level}
        opts: dict[str, Any] = {
            "ipopt.hessian_approximation": "limited-memory",
            "expand": s.expand,
            "ipopt.print_level": 0,
            "ipopt.sb": "yes",
            "print_time": False,
            "ipopt.max_iter": s.lifted_max_iter if s.lift_energy else s.max_iter,
            "ipopt.max_wall_time": self.max_wall_time_s,
            "ipopt.tol": s.tol,
            "ipopt.acceptable_tol": 1e-4,
            "ipopt.mu_strategy": "adaptive",
            "ipopt.nlp_scaling_method": "gradient-based",
            "ipopt.limited_memory_max_history": s.lbfgs_history,
        }
        self.stall = StallRule(s.stall_iter if s.lift_energy else 0, s.stall_rtol)
        """The stall rule of this form's attempts (reset at every :meth:`solve`; off in the summed form)."""
        self._watch = _IterationWatch(self.stall, w.numel(), self._lbg, self._ubg) if self.stall.window else None
        if self._watch is not None:
            opts["iteration_callback"] = self._watch
        self.solver = casadi.nlpsol("oracle", "ipopt", nlp, opts)
        # bounds: key-on state fixed, actuators as every controller, slacks >= 0
        lbx = [np.full((nx, k + 1), -np.inf), np.zeros((nu, k)), np.full(k, -np.inf), np.zeros(k * m)]
        ubx = [np.full((nx, k + 1), np.inf), np.zeros((nu, k)), np.full(k, np.inf), np.full(k * m, np.inf)]
        lbx.append(np.full(en.numel(), -np.inf))
        ubx.append(np.full(en.numel(), np.inf))
        lbx[0][:, 0] = ubx[0][:, 0] = self.x0 / self._scale
        for name, value in s.terminal_max:  # the state at the drive's end (the steps past it leave it as it is)
            if name not in pm.state.names:
                raise ValueError(f"OracleSettings.terminal_max: unknown state {name!r}: one of {pm.state.names}")
            j = pm.state.index(name)
            ubx[0][j, k] = value / self._scale[j]
        lim = ACTUATOR_LIMITS
        bounds = {
            "mdot_bl_kgps": (lim.mdot_bl_min_kgps, lim.mdot_bl_max_kgps),
            "t_evap_sp_c": (lim.t_evap_sp_min_c, lim.t_evap_sp_max_c),
            "recirc_share": (RECIRC_SHARE_MIN, RECIRC_SHARE_MAX),
        }
        for j, nm in enumerate(pm.input.names):
            lbx[1][j, :], ubx[1][j, :] = bounds[nm]
        tv0 = self.x0[pm.state.index("t_evap_c")]
        lbx[2][0] = ubx[2][0] = tv0  # the vent air measured at key-on: the evaporator wall
        ubx[3][:n][held] = 0.0  # the held steps inside the band: their slack is 0
        self._lbx = np.concatenate([b.ravel(order="F") for b in lbx])
        self._ubx = np.concatenate([b.ravel(order="F") for b in ubx])

    # ------------------------------------------------------------------ guess
    def guess_from_commands(self, commands: np.ndarray) -> np.ndarray:
        """The NLP's variables along a command sequence (per control step, :attr:`input_names`) on the smooth model."""
        pm, k, m = self.model, self.n_control, self.steps_per_control
        c = np.asarray(commands, dtype=float)
        u = np.zeros((k, pm.input.size))
        u[:, self._iu] = c[:k]
        per_step = np.repeat(u, m, axis=0)[: self.n_steps]
        r = pm.replay(self.x0, per_step, self.envs, comfort=self.comfort, pa_pa=self.pa_pa)
        xs = r["x"][[min(i * m, self.n_steps) for i in range(k + 1)]]
        tv_all = np.concatenate([[self.x0[pm.state.index("t_evap_c")]], r["y"][:, pm.y.index("t_vent_c")]])
        tv = tv_all[[i * m for i in range(k)]]
        lo, hi = COMFORT_BAND_PMV
        s = np.zeros(k * m)
        s[: self.n_steps] = np.maximum(0.0, np.maximum(np.minimum(r["pmv"], PMV_SCALE_LIMIT) - hi, lo - r["pmv"]))
        # the lifted energies (if any): the intervals' energy along these states and commands
        return self.lifted_start(np.concatenate([(xs / self._scale).T.ravel(order="F"), u.T.ravel(order="F"), tv, s]))

    def commands_of(self, w: np.ndarray) -> np.ndarray:
        """Per control step the command (columns :attr:`input_names`) in the NLP's variables ``w``."""
        o, nu = self._sizes[0], self.model.input.size
        u = np.asarray(w[o : o + self._sizes[1]], dtype=float).reshape(self.n_control, nu)
        return np.clip(u[:, self._iu], self._lbx[o : o + nu][self._iu], self._ubx[o : o + nu][self._iu])

    def pmv_of(self, w: np.ndarray) -> np.ndarray:
        """The NLP's scored PMV per plant step (smooth model) in the variables ``w``."""
        return np.asarray(self._nlp_eval(w)[2], dtype=float).ravel()[: self.n_steps]

    def evaluate(self, w: np.ndarray) -> tuple[float, float]:
        """(energy [kWh], discomfort [PMV h]) of the NLP's variables ``w`` on the smooth model.

        The discomfort is the band distance of its PMV, as ``ceco_core.kpis`` (the slacks may exceed it where
        the bound is slack).
        """
        obj, dis, _, _ = self._nlp_eval(w)
        return float(obj), float(dis)

    def summed_start(self, w: np.ndarray, lam: tuple | None) -> tuple[np.ndarray, tuple | None]:
        """A start of this (lifted) problem as one of the summed form: the lifted energies and their rows dropped."""
        k = self._sizes[4]
        if not k:
            return w, lam
        if lam is not None:
            rows = self.lifted_rows
            lam = (lam[0][:-k], np.concatenate([lam[1][: rows.start], lam[1][rows.stop :]]))
        return w[:-k], lam

    def lifted_start(self, w_summed: np.ndarray) -> np.ndarray:
        """A solution of the summed form as a (primal) start of this lifted problem: the energies appended."""
        k = self._sizes[4]
        w = np.concatenate([np.asarray(w_summed, dtype=float), np.zeros(k)])
        if k:
            w[-k:] = np.asarray(self._nlp_eval(w)[3], dtype=float).ravel() / self.energy_scale_j
        return w

    # ------------------------------------------------------------------ solve
    def solve(self, level_pmvh: float, w0: np.ndarray, lam: tuple | None = None):
        """Solve at one level from ``w0`` (and multipliers ``lam`` = (lam_x, lam_g) for a warm start).

        Returns (status, success, iterations, wall time [s], w, (lam_x, lam_g)); status is IPOPT's, or
        :data:`STALLED` where :attr:`stall` stopped the attempt (not a success; w then is the least violating
        iterate of the flat window).
        """
        if not (math.isfinite(level_pmvh) and level_pmvh > 0):
            raise ValueError(f"oracle: discomfort level must be finite and > 0 PMV h, got {level_pmvh}")
        args: dict[str, Any] = {
            "x0": w0,
            "lbx": self._lbx,
            "ubx": self._ubx,
            "lbg": self._lbg,
            "ubg": self._ubg,
            "p": level_pmvh,
        }
        if lam is not None:
            args["lam_x0"], args["lam_g0"] = lam
        if self._watch is not None:
            self._watch.reset()
        t0 = time.perf_counter()
        sol = self.solver(**args)
        wall = time.perf_counter() - t0
        st = self.solver.stats()
        status = str(st.get("return_status", "unknown"))
        ok = bool(st.get("success")) or status == "Solved_To_Acceptable_Level"
        w = np.asarray(sol["x"], dtype=float).ravel()
        best = self._watch.best() if self._watch is not None else None
        if status == "User_Requested_Stop" and self.stall.stopped_at is not None and best is not None:
            status, w = STALLED, best
        lam_out = (np.asarray(sol["lam_x"]).ravel(), np.asarray(sol["lam_g"]).ravel())
        return status, ok, int(st.get("iter_count", 0)), wall, w, lam_out


_INTERVAL_IN = ["x", "u", "tv", "E", "mask"]
_INTERVAL_OUT = ["x_next", "energy_j", "pmv", "tv_out"]
_DIFF_OPTS = {"is_diff_in": [True, True, True, False, False]}
"""The drive's data (E, mask) are constants of the NLP: no derivative through them. Else the MX map's Jacobian,
which seeds every input of the interval, met NaN on the key-on interval: at standstill the derivative with
respect to the vehicle speed is not finite (0 x inf)."""
_STEP_NAME = "ceco_oracle_step"
"""The one-step interval's name in the generated C (``jac_ceco_oracle_step``, ``adj1_ceco_oracle_step``)."""

_LOADED: dict[str, casadi.Function] = {}
_LOCK = threading.Lock()


def compiled_step(step: casadi.Function, settings: OracleSettings | None = None) -> tuple[casadi.Function, Compiled]:
    """The one-step interval ``step`` (SX) as compiled C: (the loaded Function, the cache lookup).

    C is generated for ``step``, its Jacobian ``jac_<name>`` and its one reverse direction ``adj1_<name>``:
    offered these, CasADi 3.8.2 builds the mapped constraint Jacobian's 24-32 forward or reverse directions
    from the Jacobian and the gradient from ``adj1`` (docs/oracle.md "Compiled plant steps"). Compiled by
    :func:`ceco_core.codegen.compile_cached` into ``oracle_cache_dir(settings.cache_dir)``, named by the
    SHA-256 of the generated C with the flags, the compiler and the CasADi version: a changed plant, comfort,
    parameter or step gives a new object, a stale one is never loaded, concurrent builders rename atomically.
    Loaded once per process and object with ``casadi.external``. Raises
    :class:`~ceco_core.codegen.CompileError` (no compiler, a failed compile, a cache that cannot be written).
    """
    s = (settings or OracleSettings()).validate()

    def generate(tmp: str) -> str:
        return generate_functions([step, step.jacobian(), step.reverse(1)], tmp, _STEP_NAME)

    cache = oracle_cache_dir(s.cache_dir)
    try:  # a cache that cannot be written is known before the compile, not after it
        os.makedirs(cache, exist_ok=True)
        if not os.access(cache, os.W_OK):
            raise PermissionError(f"not writable: {cache}")
    except OSError as exc:
        raise CompileError(f"cache directory {cache}: {exc}") from exc
    with _LOCK:
        c = compile_cached(_STEP_NAME, None, generate, s.compile_flags, cache, s.compiler)
        if c.path not in _LOADED:
            _LOADED[c.path] = casadi.external(step.name(), c.path)
        return _LOADED[c.path], c


def _chained(step: casadi.Function, m: int) -> casadi.Function:
    """The control interval as ``m`` chained calls of the one-step interval (MX), as ``OracleProblem._interval(m)``.

    The same arithmetic as the m-step SX Function step by step (its values bit for bit: the state, the vent air
    and the PMV pass from step to step; the energies are summed in the same order); its Jacobian by the chain
    rule over the steps' Jacobians (within 1e-13 relative of the SX forward mode, tests/test_oracle.py). One
    compiled object then serves every control period (18 s of gcc -O1 where the 5-step interval took 74 s).
    """
    x = casadi.MX.sym("x", step.size1_in(0))
    u = casadi.MX.sym("u", step.size1_in(1))
    tv = casadi.MX.sym("tv")
    e = casadi.MX.sym("E", step.size1_in(3), m)
    mask = casadi.MX.sym("mask", m)
    xk, energy, pmv, tvk = step(x, u, tv, e[:, 0], mask[0])
    pmvs = [pmv]
    for j in range(1, m):
        xk, en, pmv, tvk = step(xk, u, tvk, e[:, j], mask[j])
        pmvs.append(pmv)
        energy = energy + en
    return casadi.Function(
        "oracle_interval",
        [x, u, tv, e, mask],
        [xk, energy, casadi.vertcat(*pmvs), tvk],
        _INTERVAL_IN,
        _INTERVAL_OUT,
        _DIFF_OPTS,
    )


def replay(
    scenario,
    commands: np.ndarray,
    control_period_s: float,
    plant_dt_s: float = PLANT_STEP_S,
    names: Sequence[str] = INPUT_NAMES,
):
    """The commands (per control step, columns ``names``) open loop on the numeric plant; (RunResult, KPIs).

    Through the simulator, scored with the scenario's air-quality limits like every benchmark run.
    """
    from .closed_loop import SimSettings, simulate

    settings = SimSettings(control_period_s=control_period_s, plant_dt_s=plant_dt_s, progress=False)
    res = simulate(scenario, "baseline", settings, controller=ScheduleController(commands, names))
    res.strategy = res.metrics["strategy"] = "oracle"
    kpis, _ = compute_kpis(
        res.timeseries,
        step_time_s=None,
        control_period_s=res.metrics["control_period_s"],
        fallback_steps=0,
        air_limits=scenario.air_quality.limits,
    )
    return res, kpis


class OracleStopped(RuntimeError):
    """A simulation the oracle cannot do without stopped: the plant left its model (a ``PlantStepError``).

    The message is one line: which simulation, then the run's reason (``the simulation stopped: ...``).
    """


def baseline_commands(
    scenario, control_period_s: float, setpoint_c: float | None = None, door_logic: tuple = ()
) -> np.ndarray:
    """The production law's commands per control step on the scenario (the oracle's initial guess).

    Columns :data:`INPUT_NAMES`; with ``door_logic`` (``RecircSettings`` items) the law runs with that door
    logic and the columns are :data:`DOOR_INPUT_NAMES` (the door's command). :class:`OracleStopped` when the
    plant cannot simulate the law's run.
    """
    from ceco_plant_sim.plant_ops import PlantStepError

    from .closed_loop import SimSettings, simulate

    ovr = (() if setpoint_c is None else (("setpoint_c", float(setpoint_c)),)) + tuple(door_logic)
    try:
        res = simulate(
            scenario,
            "baseline",
            SimSettings(control_period_s=control_period_s, progress=False, strategy_overrides=ovr),
        )
    except PlantStepError as exc:
        raise OracleStopped(f"the production law's run (the oracle's start commands): {exc.run_error}") from None
    ts = res.timeseries
    m = int(round(control_period_s / (ts["t_s"][1] - ts["t_s"][0])))
    cols = [ts[nm][::m] for nm in INPUT_NAMES]
    if door_logic:
        cols.append(ts["recirc_share_cmd"][::m])  # the door's command (the plant's share lags it by its travel)
    return np.column_stack(cols)


def solve_levels(
    scenario,
    levels: Sequence[float],
    settings: OracleSettings | None = None,
    progress=None,
    problem: OracleProblem | None = None,
    start_commands: np.ndarray | None = None,
) -> list[LevelResult]:
    """The oracle at each discomfort level [PMV h], one :class:`LevelResult` per level in the given order.

    Solved from the loosest level to the tightest, each warm-started from the previous solved level's
    solution (the first from the production law's run, which meets a loose bound: IPOPT starts feasible,
    and the tightest level, near the least discomfort the plant allows, starts next to its optimum),
    replayed on the numeric plant and scored.

    ``progress``: a callable taking one line of text (None: silent). ``start_commands``: the first level's start
    (per control step, columns :attr:`OracleProblem.input_names`; None: the production law's run).
    """
    say = progress or (lambda _line: None)
    lv = [float(x) for x in levels]
    bad = [x for x in lv if not (math.isfinite(x) and x > 0)]
    if not lv or bad:
        raise ValueError(f"oracle: levels must be finite and > 0 PMV h, got {list(levels)}")
    t0 = time.perf_counter()
    pb = problem or OracleProblem(scenario, settings)
    say(
        f"oracle {scenario.name}: NLP built ({pb.n_control} intervals of {pb.steps_per_control} steps) in "
        f"{time.perf_counter() - t0:.1f} s; plant steps: {pb.evaluation}"
    )
    guess = (
        baseline_commands(scenario, pb.control_period_s, pb.settings.guess_setpoint_c, pb.settings.door_logic)
        if start_commands is None
        else start_commands
    )
    w, lam = pb.guess_from_commands(guess), None
    out: dict[int, LevelResult] = {}
    summed: OracleProblem | None = None  # the fallback form, built on the first lifted failure
    for i in sorted(range(len(lv)), key=lambda j: -lv[j]):
        status, ok, it, wall, w_new, lam_new = pb.solve(lv[i], w, lam)
        form = "lifted" if pb.settings.lift_energy else "summed"
        stalled = None  # a stalled attempt's point, replayed: (commands, run, kpis)
        if status == STALLED:
            cmd = pb.commands_of(w_new)
            head = (
                f"oracle {scenario.name}: level {lv[i]:.4f} PMV h: {status} after {it} iterations, {wall:.1f} s "
                f"(energy lifted; the objective within {pb.stall.rtol:g} of itself for {pb.stall.window} iterations); "
            )
            run, kpis, stopped = _replay_or_stop(scenario, cmd, pb)
            if stopped:
                say(head + f"its least violating iterate's replay: {stopped}")
            else:
                meets = kpis["discomfort_pmvh"] <= lv[i] * (1.0 + STALL_LEVEL_RTOL)
                say(
                    head + f"its least violating iterate replays at {kpis['discomfort_pmvh']:.4f} "
                    f"PMV h, {kpis['energy_kwh']:.4f} kWh: "
                    + ("within the level, kept (no certificate)" if meets else "above the level")
                )
                stalled = (cmd, run, kpis) if meets else None
        if not ok and stalled is None and pb.settings.lift_energy:
            # the lifted form's IPOPT path can stall where the summed form's converges (udds-hot's least level:
            # 1200 iterations against 127, docs/oracle.md "Lifted energy"): the level again, summed
            say(
                f"oracle {scenario.name}: level {lv[i]:.4f} PMV h: {status} after {it} iterations, {wall:.1f} s "
                "(energy lifted); again with the energy summed in the objective"
            )
            summed = summed or OracleProblem(scenario, dataclasses.replace(pb.settings, lift_energy=False))
            w_s, lam_s = pb.summed_start(w, lam)
            status, ok, it2, wall2, w_new, lam_new = summed.solve(lv[i], w_s, lam_s)
            form, it, wall = "lifted, then summed", it + it2, wall + wall2
            if ok:  # the next level starts lifted from this solution (its multipliers belong to the other form)
                w_new, lam_new = pb.lifted_start(w_new), None
        r = LevelResult(
            level_pmvh=lv[i],
            status=status,
            success=ok or stalled is not None,
            iterations=it,
            wall_time_s=wall,
            form=form,
            input_names=pb.input_names,
            evaluation=pb.evaluation,
            certified=ok,
        )
        if ok:  # the next level starts from a certified solution only
            w, lam = w_new, lam_new
        if r.success:
            r.commands = pb.commands_of(w_new)
            r.nlp_energy_kwh, r.nlp_discomfort_pmvh = pb.evaluate(w_new)
            r.nlp_pmv = pb.pmv_of(w_new)
            if stalled is not None:
                r.commands, r.run, r.kpis = stalled
            else:
                r.run, r.kpis, stopped = _replay_or_stop(scenario, r.commands, pb)
                if stopped:  # the NLP's point cannot be replayed: no point, and none certified
                    r.success, r.certified, r.status = False, False, f"{status}; replay: {stopped}"
        out[i] = r
        tail = (
            f"replay {r.kpis['energy_kwh']:.4f} kWh / {r.kpis['discomfort_pmvh']:.4f} PMV h "
            f"(NLP {r.nlp_energy_kwh:.4f} / {r.nlp_discomfort_pmvh:.4f})"
            if r.kpis
            else "not solved"
        )
        say(
            f"oracle {scenario.name}: level {lv[i]:.4f} PMV h: {r.status}, {it} iterations, {wall:.1f} s"
            f"{' (' + form + ')' if form == 'lifted, then summed' else ''}; {tail}"
        )
    return [out[i] for i in range(len(lv))]


def _replay_or_stop(scenario, commands: np.ndarray, pb: OracleProblem) -> tuple:
    """:func:`replay` of ``commands`` on ``pb``'s grid: (run, KPIs, '').

    (None, None, why) when the plant cannot simulate it (a ``PlantStepError``: ``the simulation stopped: ...``).
    """
    from ceco_plant_sim.plant_ops import PlantStepError

    try:
        run, kpis = replay(scenario, commands, pb.control_period_s, pb.settings.plant_dt_s, pb.input_names)
    except PlantStepError as exc:
        return None, None, exc.run_error
    return run, kpis, ""


def edge_arrival_s(result: LevelResult) -> float | None:
    """When a level's replay comes to the band's upper edge [s after key-on]; None without a replay or if it never does.

    ``ceco_core.kpis.edge_arrival_index`` on its timeseries.
    """
    from ceco_core.kpis import band_phase, edge_arrival_index

    if result.run is None:
        return None
    ts = result.run.timeseries  # type: ignore[attr-defined]  # a closed_loop.RunResult (``run`` is typed object)
    i = edge_arrival_index(ts["pmv"], band_phase(ts["pmv_lb"], ts["pmv_ub"]))
    return None if i is None else float(ts["t_s"][i] - ts["t_s"][0])


def solve_levels_holding_edge(
    scenario, levels: Sequence[float], settings: OracleSettings | None = None, progress=None
) -> list[tuple[LevelResult, LevelResult | None]]:
    """Per level the oracle (:func:`solve_levels`) and the oracle that holds the edge: (free, held).

    The held problem is the same with :attr:`OracleSettings.hold_edge_from_s` at the time the free optimum's replay
    comes to the band's upper edge (:func:`edge_arrival_s`), started from the free optimum's commands: the same
    pull-down deadline, and from there on the PMV never back above +0.5. The difference of the two energies is
    what the crossings the free optimum allows itself are worth at that discomfort (docs/oracle.md "The oracle
    that holds the edge"). ``held`` is None where the free level has no point or never comes to the edge.
    """
    say = progress or (lambda _line: None)
    base = (settings or OracleSettings()).validate()
    free = solve_levels(scenario, levels, base, progress)
    out: list[tuple[LevelResult, LevelResult | None]] = []
    for r in free:
        t_edge = edge_arrival_s(r) if r.success else None
        if t_edge is None:
            say(
                f"oracle {scenario.name}: level {r.level_pmvh:.4f} PMV h: no edge to hold (free level without a point "
                "or never at the edge)"
            )
            out.append((r, None))
            continue
        say(f"oracle {scenario.name}: level {r.level_pmvh:.4f} PMV h: holding the edge from {t_edge:.0f} s")
        held_settings = dataclasses.replace(base, hold_edge_from_s=t_edge)
        (held,) = solve_levels(scenario, [r.level_pmvh], held_settings, progress, start_commands=r.commands)
        out.append((r, held))
    return out


def solve_front(case, seed, levels, settings: OracleSettings | None = None) -> list[dict]:
    """The benchmark's entry point (``runner.ORACLE_ENTRY``): per level ``{'kpis', 'solver'}``.

    ``kpis`` the replayed run's KPIs (None when the level was not solved), ``solver`` IPOPT's account of the
    level: ``status`` (its return status), ``iterations``, ``wall_time_s`` [s] and ``evaluation`` ('compiled'
    or 'virtual machine': on a whole drive the two may end at local optima a little apart, docs/oracle.md), so
    that an unsolved level says why (the wall limit, the iteration limit, an infeasible bound).

    ``case`` a benchmark Case, ``seed`` one of its seeds: the oracle knows the truth of the drive, which
    does not depend on the seed (the seeds draw forecast errors only), so every seed gets the same front.
    The door is a decision where the case's baselines drive it (``case.baseline_door``): the oracle gets
    the controllers' permissions.
    """
    del seed  # the truth does not depend on the preview-error seed
    s = settings or OracleSettings(control_period_s=case.control_period_s, door_logic=tuple(case.baseline_door))
    res = solve_levels(case.load_scenario(), levels, s)
    return [
        {
            "kpis": r.kpis if r.success else None,
            "solver": {
                "status": r.status,
                "iterations": int(r.iterations),
                "wall_time_s": float(r.wall_time_s),
                "evaluation": r.evaluation.split(" (")[0],  # 'compiled' or 'virtual machine'
                "form": r.form,
            },
        }
        for r in res
    ]
