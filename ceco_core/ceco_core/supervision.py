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


REASON_KINDS = ('stale', 'future', 'duplicate')
"""Reasons of an out-of-order message, written ``'<kind>: ...'``; every other reason is 'invalid'."""


def reason_kind(reason: str) -> str:
    """The kind of a rejection reason: 'stale', 'future', 'duplicate' (its first word before ':'), else 'invalid'."""
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
