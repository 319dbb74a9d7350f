"""Supervision logic of the nodes: watchdog, fallback state machine, rejections, health.

The watchdog, the plant's fallback state machine, the count of rejected inputs (with
throttled logging) and the health summary that becomes a ``diagnostic_msgs/DiagnosticStatus``.

Pure logic (no rclpy, no message types): times are plain floats [s] the node reads from
its clock (a steady clock for wall-clock limits); the node logs the texts returned here.
"""

from __future__ import annotations

import dataclasses
import math

__all__ = [
    'Watchdog',
    'FallbackSupervisor',
    'SourceGate',
    'Liveliness',
    'Rejections',
    'reason_kind',
    'Health',
    'OK',
    'WARN',
    'ERROR',
    'STALE',
    'LEVEL_NAMES',
]


class Watchdog:
    """Time since the last kick against a limit.

    Args:
        timeout_s: the limit [s]; > 0.
    """

    def __init__(self, timeout_s: float):
        self.timeout_s = _positive('timeout_s', timeout_s)
        self.last_s: float | None = None
        """Time of the last kick [s]; None: never kicked."""

    def kick(self, now_s: float) -> None:
        """Restart the count at ``now_s`` [s]."""
        self.last_s = float(now_s)

    def clear(self) -> None:
        """Back to never kicked."""
        self.last_s = None

    def age(self, now_s: float) -> float:
        """Time since the last kick [s]; inf when never kicked."""
        return math.inf if self.last_s is None else now_s - self.last_s

    def expired(self, now_s: float) -> bool:
        """True when the last kick is older than the limit, or there was none."""
        return self.age(now_s) > self.timeout_s


class FallbackSupervisor:
    """Who drives the plant: the controller's commands or the plant's own ACC law.

    ``normal`` while commands arrive; ``fallback`` from the first control period without an
    acceptable command until the next accepted one. The methods return the line to log at a
    transition (None when nothing changed).
    """

    def __init__(self, in_fallback: bool = False):
        self.in_fallback = bool(in_fallback)
        """True while the ACC law drives the plant."""
        self.n_entered = 0
        """Number of times the fallback was entered [-]."""
        self.n_fallback_periods = 0
        """Control periods driven by the ACC law [-]."""
        self.reason = ''
        """Why the current (or last) fallback started."""

    def command_missing(self, where: str, reason: str) -> str | None:
        """A control period without an acceptable command (``where``: e.g. 'step 35 (t=35.0 s)')."""
        self.n_fallback_periods += 1
        if self.in_fallback:
            return None
        self.in_fallback = True
        self.n_entered += 1
        self.reason = reason
        return f'FALLBACK at {where}: {reason}; applying the production ACC law until commands resume'

    def command_accepted(self, k: int, strategy: str) -> str | None:
        """A command was accepted for control step ``k``."""
        if not self.in_fallback:
            return None
        self.in_fallback = False
        return f'commands resumed at control step {k} from {strategy}: leaving fallback'


class SourceGate:
    """Commands from one source only: the controller a plant is bound to, told apart by its epoch.

    A ceco controller draws a random non-zero ``epoch`` at each activation and numbers its
    commands ``sequence`` = 1, 2, ... (``ceco_msgs/AcCommand``); epoch 0 is a command without
    them (an older controller, a third-party one that does not set them, a bag of before). The
    first accepted command binds the gate to its epoch; from then on a command of another epoch
    is *foreign* and one of the bound epoch whose sequence is not above the last accepted one is
    a *duplicate* (a replay). The gate is released when the plant stops trusting the bound
    source (its liveliness lost, no fresh command: the plant falls back); the next accepted
    command binds it anew (a restarted controller has a new epoch).

    Defence in depth, not authentication: a participant that reads ``hvac/command`` can copy the
    epoch (DDS security, SROS2, is what stops it; docs/ros.md).

    Args:
        require_sequence: refuse epoch 0 (unsequenced) commands altogether, as foreign (the plant's default).
    """

    def __init__(self, require_sequence: bool = False):
        self.require_sequence = bool(require_sequence)
        self.epoch: int | None = None
        """The bound epoch (0: an unsequenced source), None: not bound."""
        self.last_sequence = 0
        """Sequence of the last accepted command of the bound epoch [-]."""
        self.n_bound = 0
        """Times a source was bound [-]."""
        self.n_unsequenced = 0
        """Accepted commands without epoch/sequence [-]."""

    def check(self, epoch: int, sequence: int) -> str | None:
        """Why a command with ``epoch`` / ``sequence`` is refused ('foreign: ...', 'duplicate: ...'), or None."""
        if epoch == 0 and self.require_sequence:
            return (
                'foreign: epoch 0, a command without a source epoch and sequence; this plant takes sequenced '
                'commands only (commands.require_sequence): set AcCommand.epoch (random, non-zero, new at each '
                'start) and AcCommand.sequence = 1, 2, ... (docs/benchmark.md)'
            )
        if self.epoch is None:
            return None
        if epoch != self.epoch:
            bound = 'an unsequenced source (epoch 0)' if self.epoch == 0 else f'epoch {self.epoch:#018x}'
            return f'foreign: epoch {epoch:#018x}, the plant is bound to {bound}'
        if epoch != 0 and sequence <= self.last_sequence:
            return f'duplicate: sequence {sequence} of epoch {epoch:#018x} is not above {self.last_sequence}'
        return None

    def accepted(self, epoch: int, sequence: int) -> str | None:
        """A command passed :meth:`check` and every other check; returns the line to log when it binds."""
        self.n_unsequenced += epoch == 0
        self.last_sequence = sequence
        if self.epoch == epoch:
            return None
        self.epoch = epoch
        self.n_bound += 1
        if epoch == 0:
            return (
                'bound to a command source without epoch/sequence: commands of another such source '
                'cannot be told apart (set AcCommand.epoch, random and non-zero per activation, and '
                'AcCommand.sequence = 1, 2, ...)'
            )
        return f'bound to the command source of epoch {epoch:#018x}'

    def release(self) -> None:
        """The bound source is no longer trusted (lost, silent); the next accepted command binds anew."""
        self.epoch = None
        self.last_sequence = 0


class Liveliness:
    """The liveliness of a topic's publishers, as DDS reports it (automatic liveliness, a lease).

    A subscription that requests a liveliness lease gets ``liveliness_changed`` events with the
    number of matched publishers alive and not alive; a publisher whose process died is not
    alive once the lease has passed without its participant asserting it.
    """

    def __init__(self):
        self.alive = 0
        """Publishers alive [-]."""
        self.n_lost = 0
        """Times a publisher lost its liveliness [-]."""
        self.lost_s: float | None = None
        """When the latest loss was reported [s], None: none since the last publisher came alive."""
        self.seen = False
        """True once any publisher was alive."""

    def changed(self, alive_count: int, not_alive_change: int, now_s: float) -> bool:
        """A liveliness event; True when a publisher lost its liveliness or went away (fewer alive)."""
        gained, fewer = alive_count > self.alive, alive_count < self.alive
        self.alive = int(alive_count)
        self.seen |= alive_count > 0
        if not_alive_change > 0 or fewer:
            self.n_lost += 1
            self.lost_s = now_s
            return True
        if gained:
            self.lost_s = None
        return False


REASON_KINDS = ('stale', 'future', 'duplicate', 'foreign')
"""Reasons of an out-of-order message, written ``'<kind>: ...'``; every other reason is 'invalid'."""


def reason_kind(reason: str) -> str:
    """The kind of a rejection reason: its first word before ':' if one of :data:`REASON_KINDS`, else 'invalid'."""
    head = reason.split(':', 1)[0]
    return head if head in REASON_KINDS else 'invalid'


class Rejections:
    """Counts rejected input messages per topic and decides which rejections are logged.

    The first rejection of each (topic, kind) is logged, then at most one per
    ``throttle_s`` with the number of similar rejections since the last line.

    Args:
        throttle_s: shortest time between two log lines of one (topic, kind) [s]; >= 0.
    """

    def __init__(self, throttle_s: float = 2.0):
        if not (math.isfinite(throttle_s) and throttle_s >= 0):
            raise ValueError(f'throttle_s: must be finite and >= 0, got {throttle_s!r}')
        self.throttle_s = float(throttle_s)
        self.by_topic: dict[str, int] = {}
        """Rejections per topic [-]."""
        self.by_kind: dict[tuple[str, str], int] = {}
        """Rejections per (topic, kind) [-]."""
        self._logged: dict[tuple[str, str], tuple[float, int]] = {}  # (time of the line, count then)

    @property
    def total(self) -> int:
        """Every rejection so far [-]."""
        return sum(self.by_topic.values())

    def add(self, topic: str, kind: str, text: str, now_s: float) -> str | None:
        """Count one rejection; the line to log (None: throttled).

        ``kind`` is a short class of the reason ('invalid', 'stale', 'future', ...); ``text``
        the full reason naming the field and value.
        """
        key = (topic, kind)
        self.by_topic[topic] = self.by_topic.get(topic, 0) + 1
        n = self.by_kind[key] = self.by_kind.get(key, 0) + 1
        last = self._logged.get(key)
        if last is not None and now_s - last[0] < self.throttle_s:
            return None
        self._logged[key] = (now_s, n)
        skipped = 0 if last is None else n - last[1] - 1
        return text + (f' ({skipped} similar rejections since the last line)' if skipped else '')

    def summary(self) -> str:
        """``topic: count`` pairs, e.g. ``cabin/state: 3, hvac/command: 1`` ('none' when empty)."""
        return ', '.join(f'{t}: {n}' for t, n in sorted(self.by_topic.items())) or 'none'


OK, WARN, ERROR, STALE = 0, 1, 2, 3
"""Levels of diagnostic_msgs/DiagnosticStatus."""
LEVEL_NAMES = {OK: 'OK', WARN: 'WARN', ERROR: 'ERROR', STALE: 'STALE'}


@dataclasses.dataclass
class Health:
    """One component's status: the worst level raised, every reason, and key values."""

    level: int = OK
    """OK, WARN, ERROR or STALE."""
    reasons: list[str] = dataclasses.field(default_factory=list)
    """Why the level is not OK (in the order raised)."""
    values: dict[str, str] = dataclasses.field(default_factory=dict)
    """Key values shown with the status (numbers with their unit in the key)."""

    def raise_level(self, level: int, reason: str) -> Health:
        """Raise the level to at least ``level`` and note the reason."""
        self.level = max(self.level, level)
        self.reasons.append(reason)
        return self

    def warn(self, reason: str) -> Health:
        """Raise to WARN."""
        return self.raise_level(WARN, reason)

    def error(self, reason: str) -> Health:
        """Raise to ERROR."""
        return self.raise_level(ERROR, reason)

    def set(self, key: str, value) -> Health:
        """Add a key value (floats with 4 significant digits, None as 'n/a')."""
        if value is None:
            text = 'n/a'
        elif isinstance(value, bool):
            text = 'true' if value else 'false'
        elif isinstance(value, float):
            text = f'{value:.4g}'
        else:
            text = str(value)
        self.values[key] = text
        return self

    @property
    def message(self) -> str:
        """'OK' or the reasons joined with '; '."""
        return '; '.join(self.reasons) if self.reasons else 'OK'


def _positive(name: str, value: float) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f'{name}: must be finite and > 0, got {value!r}')
    return v
