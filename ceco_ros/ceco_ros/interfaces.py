"""The stack's ROS 2 interfaces, named in one place: topic names, QoS profiles, timing modes.

Imports rclpy's QoS types; used by the ``*_node.py`` modules and by ``ceco_bringup``
only (the pure cores never import it).
"""

from __future__ import annotations

from rclpy.duration import Duration, Infinite
from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSPolicyKind, QoSProfile, ReliabilityPolicy
from rclpy.qos_overriding_options import QoSOverridingOptions

from ceco_core import control_grid
from ceco_ros.params import LIVELINESS_LEASE_S

# --- Topics (relative, so namespaces and remapping work) -------------------
from ceco_ros.topics import (  # noqa: F401 - the names, re-exported beside their QoS
    TOPIC_CLOCK,
    TOPIC_COMFORT,
    TOPIC_COMMAND,
    TOPIC_DIAGNOSTICS,
    TOPIC_POWER,
    TOPIC_ROS_DIAGNOSTICS,
    TOPIC_ROSOUT,
    TOPIC_STATE,
    TOPIC_TRAFFIC,
    TOPIC_WEATHER,
)

# --- QoS profiles ------------------------------------------------------------
LOCKSTEP_DEPTH = 10000
"""History depth of every lockstep writer [samples]: 10000 plant steps (2.8 h of driving at 1 s).

In lockstep the plant publishes as fast as the loop turns (hundreds of messages a second) and
nothing waits for the recorder, so a recorder that is starved or frozen for a while (issue 17)
falls behind by up to the whole run. The writers keep that backlog, and the reliable protocol
repairs every sample the recorder has not acknowledged; the history grows only with what is
published (about 0.5 kB a sample). A run longer than this can lose the oldest samples of a
frozen recorder: `ceco run` checks what arrived against what was sent and says so."""

# States and commands: reliable, keep-last (the backlog of a whole lockstep run), volatile.
QOS_STATE = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=LOCKSTEP_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
QOS_COMMAND = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=LOCKSTEP_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
# Previews: reliable + transient-local, depth 1: a late joiner (a restarted
# controller) gets the latest forecast at once.
QOS_PREVIEW = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
# Lockstep previews as published: the same latched profile with the backlog of a whole run
# (a late joiner gets the run's previews; a controller's depth-1 reader keeps the newest).
QOS_PREVIEW_LOCKSTEP = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=LOCKSTEP_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
# /clock as published by the plant (a best-effort volatile subscriber, as rclpy's
# TimeSource uses, matches a reliable transient-local publisher and gets no history).
# Transient-local with the run's backlog: the plant's start gate counts /clock's
# subscribers, and the preview node's and controller's time sources can fill that count
# before the recorder's reader has matched; a late-matching recorder (transient-local,
# QOS_RECORD_LATCHED) still gets every /clock (a CI run once recorded 39 of 60 without).
QOS_CLOCK = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=LOCKSTEP_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
# The recorder's subscriptions: reliable KEEP_ALL, so a recorder that falls
# behind back-pressures instead of losing samples (transient-local where the
# publisher offers it, to get the latest preview even when subscribing late).
QOS_RECORD = QoSProfile(
    history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE
)
QOS_RECORD_LATCHED = QoSProfile(
    history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
QOS_ROSOUT = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

# Real time (timing: realtime, as on a vehicle): the latest states, not a backlog: keep-last
# 10 on both sides (a recorder that lags a little still gets every sample; a burst of other
# messages on the topic does not push the plant's newest state out of a reader's history).
# Commands and previews are published with an automatic liveliness lease (with_liveliness), so
# a reader that asks for it (liveliness_probe_qos) learns within the lease that the publisher's
# process is gone; the data subscriptions ask for nothing, so any publisher matches them.
QOS_STATE_LATEST = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
# /diagnostics: what diagnostic_updater offers (reliable, keep-last 10, volatile).
QOS_DIAGNOSTICS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)


def state_qos(timing: str) -> QoSProfile:
    """QoS of cabin/state and the plant's other outputs, both sides.

    Lockstep keeps its reliable history (:data:`QOS_STATE`); real time the latest states
    (:data:`QOS_STATE_LATEST`).
    """
    return QOS_STATE if timing == 'lockstep' else QOS_STATE_LATEST


def preview_qos(timing: str) -> QoSProfile:
    """QoS of the previews as published: :data:`QOS_PREVIEW_LOCKSTEP` in lockstep, else :data:`QOS_PREVIEW`."""
    return QOS_PREVIEW_LOCKSTEP if timing == 'lockstep' else QOS_PREVIEW


def command_qos(timing: str) -> QoSProfile:
    """QoS of hvac/command: :data:`QOS_COMMAND` in lockstep, keep-last 10 in real time (both sides)."""
    if timing == 'lockstep':
        return QOS_COMMAND
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=10,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )


def with_liveliness(qos: QoSProfile, lease_s: float) -> QoSProfile:
    """A publisher's ``qos`` offering automatic liveliness with a lease of ``lease_s`` [s].

    rmw_fastrtps asserts it every 2/3 of the lease from the participant's own thread, so a
    process that is alive (even busy) stays alive; one that died is not alive once the lease
    has passed. It matches every reader that requests a lease at least as long, or none.
    """
    return QoSProfile(
        history=qos.history,
        depth=qos.depth,
        reliability=qos.reliability,
        durability=qos.durability,
        liveliness=LivelinessPolicy.AUTOMATIC,
        liveliness_lease_duration=Duration(nanoseconds=int(lease_s * 1e9)),
    )


def command_publisher_qos(timing: str, lease_s: float = LIVELINESS_LEASE_S) -> QoSProfile:
    """QoS of a controller's hvac/command publisher: :func:`command_qos` offering a liveliness lease of ``lease_s`` [s].

    The plant's data reader and its liveliness probe (lease at least ``lease_s``) both match it.
    """
    return with_liveliness(command_qos(timing), lease_s)


def preview_publisher_qos(timing: str, lease_s: float = LIVELINESS_LEASE_S) -> QoSProfile:
    """QoS of a preview publisher: :func:`preview_qos` offering a liveliness lease of ``lease_s`` [s]."""
    return with_liveliness(preview_qos(timing), lease_s)


def liveliness_probe_qos(lease_s: float) -> QoSProfile:
    """A reader that only watches the liveliness of a topic's publishers, with a lease of ``lease_s`` [s].

    Fast DDS judges a publisher's liveliness by the *reader's* requested lease (measured: a
    reader without one never gets a liveliness event), and a reader requesting a lease matches
    only publishers offering one at most as long. So the nodes keep their data subscriptions
    without a lease (any publisher matches: a third-party controller, ``ceco play``) and add this
    probe beside them: it matches ceco's own publishers (:func:`with_liveliness`) and reports
    within the lease that one of them is gone.
    """
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=1,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
        liveliness=LivelinessPolicy.AUTOMATIC,
        liveliness_lease_duration=Duration(nanoseconds=int(lease_s * 1e9)),
    )


def is_liveliness_probe(qos: QoSProfile) -> bool:
    """Whether a subscription (as the ROS graph reports its QoS) is a liveliness probe (:func:`liveliness_probe_qos`).

    A probe requests a finite liveliness lease; ceco's data readers request none (any publisher matches
    them), and the graph reports the lease of a remote reader too (its depth it does not).
    """
    return qos.liveliness_lease_duration != Infinite


def qos_overrides() -> QoSOverridingOptions:
    """QoS policies overridable from parameters: history, depth, reliability.

    The parameters are ``qos_overrides.<topic>.<publisher|subscription>.<policy>``, read-only,
    set with ``--ros-args -p`` or a parameter file.
    """
    return QoSOverridingOptions([QoSPolicyKind.HISTORY, QoSPolicyKind.DEPTH, QoSPolicyKind.RELIABILITY])


# Every topic of the stack: name -> (ROS type name, publisher QoS, recorder QoS).
STACK_TOPICS: dict[str, tuple[str, QoSProfile, QoSProfile]] = {
    TOPIC_STATE: ('ceco_msgs/msg/CabinState', QOS_STATE, QOS_RECORD),
    TOPIC_COMFORT: ('ceco_msgs/msg/Comfort', QOS_STATE, QOS_RECORD),
    TOPIC_POWER: ('ceco_msgs/msg/AcPower', QOS_STATE, QOS_RECORD),
    TOPIC_COMMAND: ('ceco_msgs/msg/AcCommand', QOS_COMMAND, QOS_RECORD),
    TOPIC_DIAGNOSTICS: ('ceco_msgs/msg/ControllerDiagnostics', QOS_COMMAND, QOS_RECORD),
    TOPIC_WEATHER: ('ceco_msgs/msg/WeatherPreview', QOS_PREVIEW, QOS_RECORD_LATCHED),
    TOPIC_TRAFFIC: ('ceco_msgs/msg/TrafficPreview', QOS_PREVIEW, QOS_RECORD_LATCHED),
    TOPIC_CLOCK: ('rosgraph_msgs/msg/Clock', QOS_CLOCK, QOS_RECORD_LATCHED),
    TOPIC_ROSOUT: ('rcl_interfaces/msg/Log', QOS_ROSOUT, QOS_RECORD_LATCHED),
}

TIMING_MODES = control_grid.TIMING_MODES
"""The nodes' timing modes (defined with the control-step grid)."""

PLANT_FALLBACK_STRATEGY = 'plant-fallback'
"""AcCommand.strategy of the commands the plant's own fallback law produces."""
