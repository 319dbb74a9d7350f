"""What a run's bag holds against what the stack sent: the arrival check of `ceco run` (issue 17).

The plant publishes one ``cabin/state``, ``cabin/comfort`` and ``hvac/power`` per plant step
n = 0 .. N-1 (and, in lockstep, one ``/clock`` with each state); in lockstep the preview node
publishes one weather and one traffic preview per control step k = 0 .. K-1, and every control
step the plant did not drive with its own law applied a command for that step (so the bag must
hold it). :func:`check_arrival` compares the step indices found with those; :func:`bag_arrival`
reads them from a bag. A run whose bag misses any of them lost data and is a failed run.

Pure Python; reading a bag needs rosbags (:mod:`ceco_bringup.bagio`), not rclpy.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping, Sequence

from ceco_ros.topics import (
    TOPIC_CLOCK,
    TOPIC_COMFORT,
    TOPIC_COMMAND,
    TOPIC_POWER,
    TOPIC_STATE,
    TOPIC_TRAFFIC,
    TOPIC_WEATHER,
)

__all__ = ['TopicArrival', 'check_arrival', 'expected_counts', 'bag_arrival', 'summary']

PLANT_TOPICS = (TOPIC_STATE, TOPIC_COMFORT, TOPIC_POWER)
"""Topics with one message per plant step, indexed by the plant step n."""

PREVIEW_TOPICS = (TOPIC_WEATHER, TOPIC_TRAFFIC)
"""Topics with one message per control step in lockstep, indexed by the control step k."""


@dataclasses.dataclass(frozen=True)
class TopicArrival:
    """One topic: how many of the messages the stack sent are in the bag."""

    topic: str
    """The stack's topic name."""
    expected: int
    """Messages sent [-] (distinct step indices, or the /clock count)."""
    received: int
    """Of them, in the bag [-]."""
    missing: tuple = ()
    """The first missing step indices (at most 10)."""

    @property
    def complete(self) -> bool:
        """True when every sent message is in the bag."""
        return self.received >= self.expected


def check_arrival(
    indices: Mapping[str, Iterable[int]],
    n_plant_steps: int,
    steps_per_control: int,
    timing: str,
    plant_fallback: Sequence[bool] = (),
    clock_count: int | None = None,
) -> list[TopicArrival]:
    """The arrival of every checked topic.

    Args:
        indices: per stack topic, the step indices found in the bag (``step_index`` fields).
        n_plant_steps: the run's plant steps N [-].
        steps_per_control: plant steps per control period m [-].
        timing: ``lockstep`` or ``realtime`` (real time: previews and commands follow wall-clock
            timers, so only the plant's topics are checked).
        plant_fallback: per recorded plant step n (``AcPower.fallback``, indexed by n): True when the
            plant's law drove it; the control steps with a step not driven by it need a command.
        clock_count: ``/clock`` messages in the bag (lockstep: one per state); None: not checked.
    """
    n, m = int(n_plant_steps), int(steps_per_control)
    expected = _expected_steps(n, m, timing)
    if timing == 'lockstep':
        expected[TOPIC_COMMAND] = {i // m for i, fb in enumerate(plant_fallback) if i < n and not fb}
    out = []
    for topic, want in expected.items():
        got = want & {int(i) for i in indices.get(topic, ())}
        missing = tuple(sorted(want - got)[:10])
        out.append(TopicArrival(topic, len(want), len(got), missing))
    if timing == 'lockstep' and clock_count is not None:
        out.append(TopicArrival(TOPIC_CLOCK, n, min(int(clock_count), n)))
    return out


def _expected_steps(n: int, m: int, timing: str) -> dict[str, set]:
    if n < 0 or m < 1:
        raise ValueError(f'n_plant_steps {n!r} >= 0 and steps_per_control {m!r} >= 1')
    expected = {t: set(range(n)) for t in PLANT_TOPICS}
    if timing == 'lockstep':
        expected.update({t: set(range(-(-n // m))) for t in PREVIEW_TOPICS})
    return expected


def expected_counts(n_plant_steps: int, steps_per_control: int, timing: str) -> dict[str, int]:
    """Messages a complete run sends on each topic whose count is fixed (plant topics, lockstep previews and /clock)."""
    out = {t: len(steps) for t, steps in _expected_steps(int(n_plant_steps), int(steps_per_control), timing).items()}
    if timing == 'lockstep':
        out[TOPIC_CLOCK] = int(n_plant_steps)
    return out


def bag_arrival(
    bag_dir, n_plant_steps: int, steps_per_control: int, timing: str, namespace: str | None = None
) -> list[TopicArrival]:
    """:func:`check_arrival` of the stack's bag in ``bag_dir``."""
    from ceco_bringup import bagio

    topics = PLANT_TOPICS + PREVIEW_TOPICS + (TOPIC_COMMAND,)
    indices: dict[str, list[int]] = {t: [] for t in topics}
    fallback: dict[int, bool] = {}
    clock = 0
    for topic, _, msg in bagio.read_messages(bag_dir, topics + (TOPIC_CLOCK,), namespace):
        if topic == TOPIC_CLOCK:
            clock += 1
            continue
        indices[topic].append(int(msg.step_index))
        if topic == TOPIC_POWER:
            fallback.setdefault(int(msg.step_index), bool(msg.fallback))
    # a plant step whose power message is missing: assume a command was due (the check is then
    # conservative, and the missing power message is reported anyway)
    plant_fallback = [fallback.get(i, False) for i in range(int(n_plant_steps))]
    return check_arrival(indices, n_plant_steps, steps_per_control, timing, plant_fallback, clock)


def summary(arrivals: Sequence[TopicArrival]) -> str:
    """``cabin/state 600/600, ...``: received over sent per topic, missing steps named."""
    parts = []
    for a in arrivals:
        text = f'{a.topic} {a.received}/{a.expected}'
        if a.missing:
            text += f' (missing steps {", ".join(map(str, a.missing))}{"…" if a.expected - a.received > 10 else ""})'
        parts.append(text)
    return ', '.join(parts)
