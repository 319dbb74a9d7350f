"""What mpc_node / baseline_node do between their callbacks, without ROS.

:class:`ControllerSession` holds the controller core (built in the lifecycle configure
transition), the checked and ordered inputs, the bookkeeping behind /diagnostics, the command
source identity (a random epoch per activation, a sequence per command: ``AcCommand.epoch`` /
``sequence``, checked by the plant's :class:`~ceco_core.supervision.SourceGate`) and the
liveliness of the preview publishers. Each input method returns the steps computed because of
it (:class:`StepResult`); the node converts and publishes them.

Pure logic: messages are read by attribute; times are floats the node passes in.
"""

from __future__ import annotations

import dataclasses
import secrets
import time
from collections.abc import Callable
from typing import Any

from ceco_core.contracts import AcInput, Diagnostics
from ceco_core.supervision import Health, Liveliness

from .controller_io import ControllerInputs, ControllerNodeConfig, ControllerRecord, StepInputs

__all__ = ['StepResult', 'ControllerSession', 'new_epoch']

PREVIEW_KINDS = ('weather', 'traffic')


def new_epoch() -> int:
    """A random non-zero 64-bit command source id (one per activation)."""
    return secrets.randbits(64) or 1


@dataclasses.dataclass(frozen=True)
class StepResult:
    """One computed control step, to publish as AcCommand and ControllerDiagnostics."""

    k: int
    """Control step index [-]."""
    stamp: Any
    """Header stamp of the state it was computed from (the command's stamp)."""
    command: AcInput
    """The command."""
    diagnostics: Diagnostics
    """The core's report of the step."""
    epoch: int
    """This activation's source id."""
    sequence: int
    """1, 2, ... within the epoch."""

    @property
    def fallback(self) -> bool:
        """True when a fallback law (not the strategy's optimum) produced the command."""
        return bool(self.diagnostics.fallback)


class ControllerSession:
    """A controller node's state across configure / activate / deactivate / cleanup.

    Args:
        cfg: the node's configuration (replaced by :meth:`configure`).
        log: ``log(level, text)``.
        notice: ``notice(key, text)``: a throttled warning.
    """

    def __init__(self, cfg: ControllerNodeConfig, log: Callable[[str, str], None], notice: Callable[[str, str], None]):
        self.cfg = cfg
        self._log = log
        self._notice = notice
        self.ctl: Any = None
        """The controller core (:class:`~ceco_controller.step_adapter.NodeController`), None unless configured."""
        self.inputs = ControllerInputs(cfg, log, self.reset)
        self.record = ControllerRecord()
        self.epoch = 0
        """Source id of the current activation (0: never activated)."""
        self.sequence = 0
        """Commands computed in this epoch [-]."""
        self.previews = {kind: Liveliness() for kind in PREVIEW_KINDS}
        """Liveliness of the preview publishers (events of the node's liveliness probes)."""

    # -------------------------------------------------------------- lifecycle
    def configure(self, cfg: ControllerNodeConfig) -> str:
        """Build the controller for ``cfg`` (raises ValueError, RuntimeError, OSError); returns how it warmed up."""
        from .step_adapter import NodeController

        self.ctl = NodeController(cfg)
        self.cfg = cfg
        self.inputs = ControllerInputs(cfg, self._log, self.reset)
        return self.ctl.warm_up

    def configured_line(self, warm: str, seconds: float) -> str:
        """The line a node logs after configure (``warm``: how the first step was solved, in ``seconds``)."""
        cfg = self.cfg
        return (
            f'configured in {seconds:.2f} s (controller built, first solve by {warm}): '
            f'{cfg.strategy}, Ts {cfg.control_period_s} s, Np {cfg.horizon_steps}, timing {cfg.timing}, '
            f'measurements {cfg.measurements}, scenario {self.ctl.scenario.name}'
        )

    def activate(self) -> None:
        """A fresh controller state and a new source epoch."""
        self.reset()
        self.epoch, self.sequence = new_epoch(), 0

    def release(self) -> None:
        """Forget the controller and the inputs (cleanup, shutdown)."""
        self.ctl = None
        self.inputs.clear()

    def reset(self) -> None:
        """A fresh controller state (activation, a new time base)."""
        if self.ctl is not None:
            self.ctl.reset()

    def set_config(self, cfg: ControllerNodeConfig) -> None:
        """Run-time parameter changes (the limits read per message, the log throttle)."""
        self.cfg = cfg
        self.inputs.configure(cfg)

    # ----------------------------------------------------------------- inputs
    def on_state(self, msg, wall_s: float, clock_s: float, active: bool) -> list[StepResult]:
        """A CabinState; the step it completes (lockstep) or a due real-time step."""
        if not self.inputs.offer_state(msg, wall_s, clock_s):
            return []
        if self.cfg.timing == 'lockstep':
            return self.poll(wall_s, active)
        if self.inputs.due():  # realtime: a tick came before this control step's first state
            return self.on_timer(clock_s, active)
        return []

    def on_preview(self, kind: str, msg, wall_s: float, active: bool) -> list[StepResult]:
        """A WeatherPreview ('weather') or TrafficPreview ('traffic'); the step it completes (lockstep)."""
        if self.inputs.offer_preview(kind, msg, wall_s) and self.cfg.timing == 'lockstep':
            return self.poll(wall_s, active)
        return []

    def poll(self, wall_s: float, active: bool) -> list[StepResult]:
        """lockstep: the waiting step when complete or overdue (inactive: the inputs wait in the buffer)."""
        if not active:
            return []
        return self._run(self.inputs.ready() or self.inputs.overdue(wall_s))

    def on_timer(self, clock_s: float, active: bool) -> list[StepResult]:
        """realtime: the control period's step from the latest inputs."""
        si, why = self.inputs.realtime_step(clock_s)
        if si is None and why and active:
            self._notice('no-state', f'not commanding: {why}')
        return self._run(si) if active else []

    def preview_liveliness(self, kind: str, alive_count: int, not_alive_change: int, wall_s: float) -> None:
        """A liveliness event of a preview publisher; a loss is logged (once per loss)."""
        if self.previews[kind].changed(alive_count, not_alive_change, wall_s):
            self._log('warn', f'v2x/{kind}_preview: the publisher lost its liveliness (preview source dead?)')

    # ------------------------------------------------------------------ steps
    def _run(self, si: StepInputs | None) -> list[StepResult]:
        if si is None or self.ctl is None:
            return []
        t0, cfg = time.perf_counter(), self.cfg
        try:
            cmd, diag, note = self.ctl.step(si, cfg)
        except Exception as err:  # one bad step must not take the node down
            self.record.error(si.k, err)
            self._log('error', f'step {si.k} failed: {err!r}')
            return []
        if note:
            self._notice('no-previews', f'step {si.k}: {note}: solving without previews')
        self.sequence += 1
        result = StepResult(si.k, si.state.header.stamp, cmd, diag, self.epoch, self.sequence)
        self.record.step(si.k, (time.perf_counter() - t0) * 1e3, diag, note)
        if result.fallback:
            self._notice('fallback', f'step {si.k}: fallback {diag.fallback}: {diag.message}')
        return [result]

    def settle(self, k: int) -> None:
        """After step ``k``'s command went out: the controller's work for its next step (``NodeController.settle``)."""
        if self.ctl is None:
            return
        try:
            self.ctl.settle()
        except Exception as err:  # as a step's: logged and counted, the node goes on
            self.record.error(k, err)
            self._log('error', f'step {k}: after the command: {err!r}')

    # ----------------------------------------------------------------- health
    def health(self, lifecycle: str, wall_s: float, node_name: str = '') -> Health:
        """The /diagnostics status of the node (``node_name``: its fully qualified name, for the hint)."""
        budget = self.ctl.step_budget_s if self.ctl is not None else None
        h = self.record.health(lifecycle, self.cfg, self.inputs, wall_s, budget)
        if lifecycle == 'unconfigured' and node_name:
            h.set('hint', f'ros2 lifecycle set {node_name} configure; ros2 lifecycle set {node_name} activate')
        h.set('epoch', f'{self.epoch:#018x}').set('commands_sent', self.sequence)
        ages = self.inputs.ages_s(wall_s)
        for kind in PREVIEW_KINDS:
            live = self.previews[kind]
            h.set(f'{kind}_publishers_alive', live.alive if live.seen else None)
            if lifecycle == 'active' and live.lost_s is not None and live.alive == 0:
                h.warn(f'v2x/{kind}_preview: no live publisher (liveliness lost {wall_s - live.lost_s:.1f} s ago)')
            limit = self.cfg.control_period_s + self.cfg.preview_timeout_s
            age = ages.get(kind)
            if lifecycle == 'active' and self.cfg.timing == 'realtime' and age is not None and age > limit:
                h.warn(
                    f'v2x/{kind}_preview: no update for {age:.1f} s (one is due every control period, '
                    f'{self.cfg.control_period_s:g} s; missed after {limit:g} s)'
                )
        return h
