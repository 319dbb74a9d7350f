"""plant_node's run without ROS: the plant, its energy totals and end, and who drives it.

:class:`PlantLoop` holds the simulator's own plant core (:class:`~ceco_plant_sim.scenario_plant.ScenarioPlant`),
the energy totals over the run, the run's end, the production ACC law that drives the plant when no
acceptable command came (:class:`~ceco_core.supervision.FallbackSupervisor` says when) and, in real
time, which input drives each plant tick (:class:`~ceco_plant_sim.plant_io.RealtimeCommands`). The
node publishes what it returns and logs the lines it hands back.

When a step cannot be simulated (:class:`~ceco_plant_sim.plant_ops.PlantStepError`: the refrigerant
cycle left its model) the loop stops for good (:attr:`PlantLoop.stopped`); the node then exits with
:data:`PLANT_STOPPED_EXIT` after its ERROR line (:func:`stopped_line`), which ``ceco run`` reads back
(:func:`simulation_stopped`).

Pure logic: no rclpy, no message types; times are floats the node passes in.
"""

from __future__ import annotations

from collections.abc import Callable

from ceco_core.acc_law import AccLaw
from ceco_core.contracts import AcInput
from ceco_core.supervision import FallbackSupervisor, Health, Watchdog
from ceco_v2x_preview.scenario import Scenario

from .compiled_plant import PlantEvaluation
from .plant_io import CONTROLLER_LOST, STARTED, CommandPolicy, PlantNodeConfig, RealtimeCommands, plant_health
from .plant_ops import SIMULATION_STOPPED, PlantStepError
from .scenario_plant import PlantStepRecord, ScenarioPlant, n_plant_steps, steps_per_control

__all__ = ['PLANT_STOPPED_EXIT', 'PlantLoop', 'simulation_stopped', 'stopped_line']

PLANT_STOPPED_EXIT = 3
"""plant_node's exit status when its plant cannot go on (a :class:`PlantStepError`; docs/ros.md)."""

_CANNOT_GO_ON = f'; the plant cannot go on: exit {PLANT_STOPPED_EXIT}'


def stopped_line(reason: str) -> str:
    """plant_node's ERROR line when its plant cannot go on (``reason``: the PlantStepError's message), one line."""
    return SIMULATION_STOPPED + ' '.join(reason.split()) + _CANNOT_GO_ON


def simulation_stopped(exit_status: int | None, log_text: str) -> str | None:
    """``the simulation stopped: <reason>`` of a plant_node that exited with :data:`PLANT_STOPPED_EXIT`, else None.

    The reason is read from its last :func:`stopped_line` in ``log_text`` (its log); None without one.
    """
    if exit_status != PLANT_STOPPED_EXIT:
        return None
    lines = [line for line in log_text.splitlines() if line.endswith(_CANNOT_GO_ON) and SIMULATION_STOPPED in line]
    if not lines:
        return None
    return SIMULATION_STOPPED + lines[-1].split(SIMULATION_STOPPED, 1)[1].removesuffix(_CANNOT_GO_ON)


class PlantLoop:
    """The plant side of a node run: one plant step at a time, from key-on to the run's end."""

    def __init__(self, scenario: Scenario, cfg: PlantNodeConfig, log: Callable[[str, str], None] | None = None):
        """Key-on state of ``scenario`` with the node's plant step, control period and run length.

        ``log(level, text)`` receives the lines of the command policy, the start gate and the
        command source.
        """
        self.cfg = cfg
        self._log = log or (lambda _level, _text: None)
        self.sp = ScenarioPlant(scenario, cfg.plant_dt_s, evaluation=PlantEvaluation(cfg.plant_evaluation))
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
        self.policy = CommandPolicy(cfg, self._log)
        """Which command applies (field checks, control step, stamp, source)."""
        self.wait = Watchdog(cfg.command_timeout_s)
        """lockstep: the wall-clock wait for the awaited command."""
        self.started = False
        """True once step 0 was published."""
        self.waiting_for = ''
        """What step 0 waits for ('' once started or free to start)."""
        self.controller_lost = False
        """lockstep: the command publisher's liveliness was lost while a command was awaited."""
        self.stopped: str | None = None
        """Why the plant cannot go on (a step's :class:`PlantStepError`), else None; no step follows."""
        self._reported = 0

    def set_config(self, cfg: PlantNodeConfig) -> None:
        """Run-time parameter changes (the lockstep wait, the log throttle)."""
        self.cfg = self.policy.cfg = cfg
        self.wait.timeout_s = cfg.command_timeout_s
        self.policy.rejections.throttle_s = cfg.log_throttle_s

    # ------------------------------------------------------------------ start
    def may_start(self, waiting_for: str, wall_s: float) -> bool:
        """True once when step 0 may be published (``waiting_for``: :func:`~ceco_plant_sim.plant_io.start_gate`).

        While waiting, each new reason is logged once (a lone plant says what it waits for).
        """
        if self.started:
            return False
        if waiting_for and waiting_for != self.waiting_for:
            self._log('info', f'waiting for subscribers before step 0: {waiting_for}')
        self.waiting_for = waiting_for
        if waiting_for:
            return False
        self.started = True
        self._log('info', STARTED)
        self.wait.kick(wall_s)
        return True

    @property
    def running(self) -> bool:
        """Started, not finished and not stopped."""
        return self.started and not self.finished and self.stopped is None

    # -------------------------------------------------------------- commands
    def take_command(self, msg, wall_s: float, clock_s: float, to_input: Callable[[object], AcInput]) -> AcInput | None:
        """An AcCommand: the input to apply when the policy accepts it (lockstep: now, for a period), else None.

        ``to_input(msg)``: the accepted command's input, blower, set-point and door (the node's
        ``ceco_ros.conversions.command_input``); called only once the policy has checked the message.
        """
        if not self.running or not self.policy.accept(msg, self.k, wall_s):
            return None
        u = to_input(msg)
        rt = self.cfg.timing == 'realtime'
        self.controller_lost = False
        line = self.accept_command(u, int(msg.step_index), msg.strategy, clock_s if rt else None)
        if line:
            self._log('info', line)
        return u

    def liveliness_changed(self, alive: int, lost: int, wall_s: float) -> None:
        """A liveliness event of the hvac/command publishers (the node's probe); a loss ends trust in the source."""
        if self.policy.liveliness.changed(alive, lost, wall_s):
            self._log('warn', f'hvac/command: a publisher lost its liveliness ({alive} alive): {CONTROLLER_LOST}')
            self.rt.controller_lost = self.controller_lost = True
            self.policy.source.release()

    def lockstep_overdue(self, wall_s: float) -> str | None:
        """lockstep: why the awaited command will not come (the ACC law drives this period now), or None."""
        if not self.running:
            return None
        if self.controller_lost:
            return CONTROLLER_LOST
        if self.wait.expired(wall_s):
            return f'no command for control step {self.k} within {self.wait.timeout_s} s (wall clock)'
        return None

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
        """One plant step with ``u`` held; the energy totals follow; :attr:`finished` after the last one.

        A :class:`PlantStepError` (the step cannot be simulated) sets :attr:`stopped` and is raised again.
        """
        if self.finished:
            raise RuntimeError(f'the run is finished ({self.n_steps} plant steps)')
        if self.stopped is not None:
            raise RuntimeError(f'the plant cannot go on: {self.stopped}')
        try:
            r = self.sp.step(u)
        except PlantStepError as err:
            self.stopped = str(err)
            raise
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
            self.policy.source.release()  # the next accepted command binds its source anew
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

    def health(
        self, waiting_for: str, wall_s: float, clock_s: float, events: dict, clock_publishers: int = 1
    ) -> Health:
        """The plant's /diagnostics status now (``waiting_for``: what step 0 waits for; publishers on /clock)."""
        rej, rt = self.policy.rejections, self.cfg.timing == 'realtime'
        new, self._reported = rej.total - self._reported, rej.total
        age = self.rt.watchdog.age(clock_s) if rt else self.wait.age(wall_s)
        h = plant_health(
            cfg=self.cfg,
            started=self.started,
            finished=self.finished,
            n=self.n,
            t_s=self.t_s,
            supervisor=self.fallback,
            command_age_s=None if age == float('inf') else age,
            policy=self.policy,
            new_rejections=new,
            events=events,
            waiting_for='' if self.started else waiting_for,
            clock_publishers=clock_publishers,
        )
        if self.stopped is not None:
            h.set('state', 'stopped').error(stopped_line(self.stopped))
        return h

    def summary(self) -> str:
        """The line logged at the run's end."""
        return (
            f'scenario complete: {self.n} plant steps, E_comp {self.e_comp_j:.0f} J, E_blower {self.e_blower_j:.0f} J'
        )
