"""Which input a node takes next: the sequence gate on scenario time and the lockstep buffer.

Pure logic (no rclpy, no message types): the nodes feed positions (scenario times [s],
control step indices [-]) and payloads they have already validated field by field.

* :class:`SequenceGate` accepts a stream of positions that moves forward within a window. A
  single malformed position (far in the future, stale) is rejected *without moving* the
  gate; a real new time base (a restarted plant, a new bag playback, a node that missed a
  long span) is adopted once a few consecutive positions agree with each other, or at once
  when it is key-on (the origin, t = 0). Either way the gate reports a reset, and the node
  drops its per-drive state (warm start, estimator, buffers).
* :class:`LockstepBuffer` pairs the state of control step k with the two previews issued
  for k (lockstep timing), bounded to a window of steps.
* :class:`HeldSample` keeps a lockstep sample (a command, a step's previews) until its
  publisher has matched its subscribers.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

__all__ = ['Verdict', 'SequenceGate', 'LockstepBuffer', 'HeldSample', 'PREVIEW_KINDS']


@dataclasses.dataclass(frozen=True)
class Verdict:
    """The gate's answer for one position."""

    accepted: bool
    """True: the node takes the message."""
    reset: bool = False
    """True: accepted as a new time base (key-on or a confirmed jump); drop the per-drive state."""
    reason: str = ''
    """Why it was rejected (empty when accepted); with ``reset``, what kind of jump."""


class SequenceGate:
    """Accepts positions that move forward: the first one, any in ``(last, last + ahead]``.

    Rejected without moving the gate: a repeat of the last position (``duplicate``), one
    behind it (``stale``), one beyond ``last + ahead`` (``future``). Adopted as a new time
    base (``Verdict.reset``): the origin (key-on) when the gate is past it, and any position
    once ``confirm`` consecutive rejected positions formed a forward sequence of their own
    (each in ``(previous, previous + ahead]``), so one bad message never moves the gate but a
    restart or a new playback is followed within ``confirm`` messages. Both only once the
    accepted stream has been silent for ``silence_s`` (the times passed to :meth:`offer`): a
    new time base replaces a source that stopped, never one that still speaks, so a storm of
    stale or key-on messages beside a live plant moves nothing.

    Args:
        ahead: how far ahead of the last accepted position a position is accepted
            (same unit as the positions: [s] or [steps]); > 0.
        confirm: consecutive agreeing out-of-window positions that establish a new time
            base [-]; >= 1.
        origin: the key-on position (scenario time 0) [s or steps].
        tol: positions within ``tol`` of each other are equal (same unit).
        silence_s: how long no position must have been accepted before a new time base is
            adopted [s] (0: at once).
    """

    def __init__(self, ahead: float, confirm: int = 3, origin: float = 0.0, tol: float = 1e-9, silence_s: float = 0.0):
        if not (math.isfinite(ahead) and ahead > 0):
            raise ValueError(f'ahead: must be finite and > 0, got {ahead!r}')
        if int(confirm) < 1:
            raise ValueError(f'confirm: must be >= 1, got {confirm!r}')
        self.ahead = float(ahead)
        self.confirm = int(confirm)
        self.origin = float(origin)
        self.tol = float(tol)
        if not (math.isfinite(silence_s) and silence_s >= 0):
            raise ValueError(f'silence_s: must be finite and >= 0, got {silence_s!r}')
        self.silence_s = float(silence_s)
        self.reset()

    def reset(self) -> None:
        """Forget every position (the next one is accepted as the first)."""
        self.last: float | None = None
        """Last accepted position; None before the first."""
        self.last_s = -math.inf
        """Time the last position was accepted [s]."""
        self._chain: list[float] = []

    def offer(self, x: float, now_s: float = 0.0) -> Verdict:
        """Accept or reject position ``x`` (finite; a NaN/inf is rejected as invalid) at time ``now_s`` [s]."""
        if not math.isfinite(x):
            return Verdict(False, reason=f'invalid: position {x!r} is not finite')
        last = self.last
        if last is None:
            return self._take(x, now_s, False, '')
        if abs(x - last) <= self.tol:
            self._chain.clear()
            return Verdict(False, reason=f'duplicate: {_fmt(x)} is the last accepted position')
        if last < x <= last + self.ahead + self.tol:
            return self._take(x, now_s, False, '')
        silent = now_s - self.last_s >= self.silence_s
        if abs(x - self.origin) <= self.tol and silent:
            return self._take(x, now_s, True, f'key-on ({_fmt(x)} after {_fmt(last)}): restart')
        chain = self._chain
        if chain and chain[-1] < x <= chain[-1] + self.ahead + self.tol:
            chain.append(x)
        else:
            chain[:] = [x]
        if len(chain) >= self.confirm and silent:
            return self._take(
                x,
                now_s,
                True,
                f'new time base {_fmt(x)} (was {_fmt(last)}), confirmed by {self.confirm} consecutive messages',
            )
        if x < last:
            return Verdict(False, reason=f'stale: {_fmt(x)} is behind the last accepted {_fmt(last)}')
        return Verdict(False, reason=f'future: {_fmt(x)} is beyond the window {_fmt(last)} + {_fmt(self.ahead)}')

    def _take(self, x: float, now_s: float, reset: bool, reason: str) -> Verdict:
        self.last, self.last_s = float(x), float(now_s)
        self._chain.clear()
        return Verdict(True, reset=reset, reason=reason)


def _fmt(x: float) -> str:
    return f'{x:.9g}'


PREVIEW_KINDS = ('weather', 'traffic')
"""The two previews a lockstep control step waits for."""


class LockstepBuffer:
    """The inputs of the lockstep control steps still to be computed.

    Holds at most one pending state (the newest control step's: a newer state supersedes
    an older one still waiting, because the plant has moved on) and the previews of the
    steps in ``(last_done, last_done + window]`` (before the first step: the ``window``
    newest). Step k is *ready* when its state and both previews are here, *overdue* when
    its state has waited longer than the preview timeout.
    """

    def __init__(self, window: int):
        if int(window) < 1:
            raise ValueError(f'window: must be >= 1, got {window!r}')
        self.window = int(window)
        self.reset()

    def reset(self) -> None:
        """Drop everything (a new drive)."""
        self.last_done: int | None = None
        """The last control step handed out by :meth:`take`; None before the first."""
        self._state: tuple[int, Any, float] | None = None
        self._previews: dict[str, dict[int, Any]] = {kind: {} for kind in PREVIEW_KINDS}

    def _check(self, k: int) -> str | None:
        if self.last_done is not None:
            if k <= self.last_done:
                return f'stale: step {k}, step {self.last_done} done'
            if k > self.last_done + self.window:
                return f'future: step {k} is beyond the window {self.last_done} + {self.window}'
        return None

    def put_state(self, k: int, state: Any, now_s: float) -> str | None:
        """Store the state of control step ``k`` received at ``now_s`` [s, wall clock].

        Returns the reason when it is not taken (stale or future), else None.
        """
        why = self._check(k)
        if why is None:
            if self._state is not None and self._state[0] > k:
                return f'stale: step {k}, the state of step {self._state[0]} is already waiting'
            self._state = (k, state, now_s)
        return why

    def put_preview(self, kind: str, k: int, msg: Any) -> str | None:
        """Store the ``kind`` preview ('weather' or 'traffic') issued for step ``k``.

        Returns the reason when it is not taken, else None.
        """
        why = self._check(k)
        if why is None:
            store = self._previews[kind]
            store[k] = msg
            while len(store) > self.window:
                del store[min(store)]
        return why

    @property
    def pending(self) -> int | None:
        """The control step whose state is waiting, or None."""
        return None if self._state is None else self._state[0]

    def ready(self) -> int | None:
        """The waiting step when both its previews are here, else None."""
        k = self.pending
        if k is not None and all(k in self._previews[kind] for kind in PREVIEW_KINDS):
            return k
        return None

    def overdue(self, now_s: float, timeout_s: float) -> int | None:
        """The waiting step when its state has waited longer than ``timeout_s`` [s], else None."""
        if self._state is not None and now_s - self._state[2] > timeout_s:
            return self._state[0]
        return None

    def take(self, k: int) -> tuple[Any, Any, Any]:
        """Hand out step ``k`` (the pending one): ``(state, weather or None, traffic or None)``.

        Everything up to ``k`` is dropped.
        """
        if self._state is None or self._state[0] != k:
            raise KeyError(f'step {k} is not the pending step ({self.pending})')
        state = self._state[1]
        w, s = (self._previews[kind].get(k) for kind in PREVIEW_KINDS)
        self.last_done = k
        self._state = None
        for store in self._previews.values():
            for j in [j for j in store if j <= k]:
                del store[j]
        return state, w, s


class HeldSample:
    """lockstep: samples wait here until their publisher has its subscribers.

    A volatile sample never reaches a reader that has not matched yet, so a sample made before
    the node's ``lockstep.min_*_subscribers`` matched (mpc_node's command, preview_node's pair of
    previews) is sent once they have. ``keep`` samples wait at most, in order; beyond that a newer one
    pushes the oldest out. ``keep=1`` (mpc_node's command): a newer command replaces the waiting one, each
    step's command is sent once. preview_node keeps every step's previews (``keep`` its lockstep
    history): a controller that does not wait for the previews (an external one) lets the plant run on
    while the recorder is still matching, and each step's previews must still reach the bag (a run of
    tests/test_benchmark_external.py recorded the previews of steps 2 and 3 of 4 when the newer replaced the older).
    """

    def __init__(self, keep: int = 1):
        if keep < 1:
            raise ValueError(f'keep: {keep} samples; at least 1')
        self.keep = int(keep)
        self.waiting: list[Any] = []
        """The samples waiting for their subscribers, oldest first."""
        self.since_s: float | None = None
        """When the oldest unsent sample began waiting [s, the caller's clock] (None: none waits)."""

    @property
    def msg(self) -> Any:
        """The oldest sample waiting for its subscribers (None: none)."""
        return self.waiting[0] if self.waiting else None

    def offer(self, msg, short_of_subscribers: bool, now_s: float = 0.0) -> list:
        """A new sample: the samples to send now, in order (the waiting ones, then ``msg``), or ``[]``.

        ``[]`` while short of subscribers (``msg`` then waits). Either way past ``keep`` samples the oldest go.
        """
        kept = (self.waiting + [msg])[-self.keep :]
        if not short_of_subscribers:
            self.waiting, self.since_s = [], None
            return kept
        if self.since_s is None:
            self.since_s = now_s
        self.waiting = kept
        return []

    def release(self, may_send: bool) -> list:
        """The waiting samples, oldest first, once they ``may_send`` (active, subscribers matched), else ``[]``."""
        if not self.waiting or not may_send:
            return []
        out, self.waiting, self.since_s = self.waiting, [], None
        return out

    def clear(self) -> None:
        """Forget the waiting samples (a new activation)."""
        self.waiting, self.since_s = [], None
