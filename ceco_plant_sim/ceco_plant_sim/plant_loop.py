"""plant_node's run without ROS: the plant, its energy totals and end, and who drives it.

:class:`PlantLoop` holds the simulator's own plant core (:class:`~ceco_plant_sim.scenario_plant.ScenarioPlant`),
the energy totals over the run, the run's end, the production ACC law that drives the plant when no
acceptable command came (:class:`~ceco_core.supervision.FallbackSupervisor` says when) and, in real
time, which input drives each plant tick (:class:`~ceco_plant_sim.plant_io.RealtimeCommands`). The
node publishes what it returns and logs the lines it hands back.

Pure logic: no rclpy, no message types; times are floats the node passes in.
"""

from __future__ import annotations

from ceco_core.acc_law import AccLaw
from ceco_core.contracts import AcInput
from ceco_core.supervision import FallbackSupervisor
from ceco_v2x_preview.scenario import Scenario

from .plant_io import PlantNodeConfig, RealtimeCommands
from .scenario_plant import PlantStepRecord, ScenarioPlant, n_plant_steps, steps_per_control

__all__ = ['PlantLoop']


class PlantLoop:
    """The plant side of a node run: one plant step at a time, from key-on to the run's end."""

    def __init__(self, scenario: Scenario, cfg: PlantNodeConfig):
        """Key-on state of ``scenario`` with the node's plant step, control period and run length."""
        self.sp = ScenarioPlant(scenario, cfg.plant_dt_s)
        self.dt_s = cfg.plant_dt_s
        """Plant step [s]."""
        self.control_period_s = cfg.control_period_s
        """Control period Ts [s]."""
        self.m = steps_per_control(cfg.control_period_s, cfg.plant_dt_s)
        """Plant steps per control period [-]."""
        self.n_steps = n_plant_steps(min(cfg.duration_s or scenario.duration_s, scenario.duration_s), self.dt_s)
        """Plant steps of the run [-]."""
        self.e_comp_j = 0.0
        """Compressor electrical energy since key-on [J]."""
        self.e_blower_j = 0.0
        """Blower electrical energy since key-on [J]."""
        self.finished = False
        """True once the run's last plant step is done."""
        self.acc = AccLaw()
        self.fallback = FallbackSupervisor()
        self.rt = RealtimeCommands(cfg.command_timeout_rt_s)

    @property
    def n(self) -> int:
        """Current plant step index (measurements at t_n) [-]."""
        return self.sp.n

    @property
    def t_s(self) -> float:
        """t_n [s]."""
        return self.sp.t_s

    @property
    def k(self) -> int:
        """The control step t_n belongs to [-]."""
        return self.n // self.m

    def step(self, u: AcInput) -> PlantStepRecord:
        """One plant step with ``u`` held; the energy totals follow; :attr:`finished` after the last one."""
        if self.finished:
            raise RuntimeError(f'the run is finished ({self.n_steps} plant steps)')
        r = self.sp.step(u)
        self.e_comp_j += r.out.e_comp_j
        self.e_blower_j += r.out.e_blower_j
        self.finished = self.n >= self.n_steps
        return r

    def fallback_command(self, why: str) -> tuple[AcInput, str | None]:
        """The ACC law's command for a control period without an acceptable command.

        Returns ``(command, line)``: ``line`` is the warning to log when the fallback starts
        (the law then starts from its reset state), else None.
        """
        line = self.fallback.command_missing(f'step {self.n} (t={self.t_s:.1f} s)', why)
        if line:
            self.acc.reset()
        a = self.acc.step(self.sp.meas['t_cab_c'], self.control_period_s)
        return AcInput(mdot_bl_kgps=a.mdot_bl_kgps, t_evap_sp_c=a.t_evap_sp_c), line

    def accept_command(self, u: AcInput, k: int, strategy: str, now_s: float | None = None) -> str | None:
        """An accepted command ``u`` for control step ``k`` from ``strategy``; ``now_s`` [s] in real time only.

        Leaves the fallback (returns the line to log, else None); in real time the command becomes
        the latest one, taken at the next control-step boundary.
        """
        if now_s is not None:
            self.rt.accepted(u, now_s)
        return self.fallback.command_accepted(k, strategy)

    def realtime_input(self, now_s: float) -> tuple[AcInput, bool, str | None]:
        """Real time: ``(input, from the fallback law, line to log)`` of this plant tick at ``now_s`` [s].

        A fresh command is taken at control-step boundaries; a stale one hands over to the ACC law
        at once, which drives until a fresh command comes at a boundary (:class:`RealtimeCommands`).
        """
        line = None
        if self.rt.must_choose(self.n % self.m == 0, now_s, self.fallback.in_fallback):
            if self.rt.fresh(now_s):
                self.rt.applied = (self.rt.latest, False)
            else:
                u, line = self.fallback_command(self.rt.why_stale(now_s))
                self.rt.applied = (u, True)
        u, fallback = self.rt.applied
        return u, fallback, line

    def summary(self) -> str:
        """The line logged at the run's end."""
        return (
            f'scenario complete: {self.n} plant steps, E_comp {self.e_comp_j:.0f} J, E_blower {self.e_blower_j:.0f} J'
        )
