"""What every ceco node shares: clocks as floats, throttled notices, lifecycle plumbing.

* :class:`NodeTools` (mixin): ``wall_s()`` (steady clock [s], for wall-clock limits),
  ``clock_s()`` (the node clock [s]: /clock under use_sim_time), ``log(level, text)``,
  ``notice(key, text)`` (logged at most once per throttle period per key), ``use_params``
  (declare a node's table, validate its configuration, accept ``ros2 param set``),
  ``qos_event`` (count and log a QoS event), ``liveliness_probe`` (watch the liveliness of a
  topic's publishers, :func:`ceco_ros.interfaces.liveliness_probe_qos`).
* :class:`ManagedNode`: an rclpy LifecycleNode that tracks its state as text
  (``self.lifecycle``), configures and activates itself when asked to (``autostart``), and
  releases what ``on_configure`` created on cleanup, shutdown and error (``release()``).
"""

from __future__ import annotations

from rclpy.clock import Clock, ClockType
from rclpy.duration import Infinite
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn

from ceco_core.supervision import Rejections
from ceco_ros import interfaces, params

__all__ = ['NodeTools', 'ManagedNode', 'SUCCESS', 'FAILURE']

SUCCESS, FAILURE = TransitionCallbackReturn.SUCCESS, TransitionCallbackReturn.FAILURE


class NodeTools:
    """Mixin for an rclpy Node: call ``setup_tools`` in the constructor."""

    def setup_tools(self, throttle_s: float) -> None:
        """Create the steady clock and the notice throttle (``throttle_s`` [s])."""
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.notices = Rejections(throttle_s)
        """Counts and throttles the node's repeated notices (not rejections)."""

    @property
    def steady(self) -> Clock:
        """The steady clock (for timers on wall-clock time)."""
        return self._steady

    def wall_s(self) -> float:
        """Steady (monotonic wall) clock [s]."""
        return self._steady.now().nanoseconds * 1e-9

    def clock_s(self) -> float:
        """The node clock [s] (simulation time under use_sim_time)."""
        return self.get_clock().now().nanoseconds * 1e-9

    def log(self, level: str, text: str) -> None:
        """Log ``text`` at 'debug', 'info', 'warn', 'error' or 'fatal'.

        One call site per severity: rclpy refuses a call site that logs at another severity than
        it did before ("Logger severity cannot be changed between calls", a ValueError).
        """
        logger = self.get_logger()
        if level == 'debug':
            logger.debug(text)
        elif level == 'info':
            logger.info(text)
        elif level == 'warn':
            logger.warn(text)
        elif level == 'error':
            logger.error(text)
        else:
            logger.fatal(text)

    def notice(self, key: str, text: str, level: str = 'warn') -> None:
        """Log ``text`` unless a notice of the same ``key`` was logged within the throttle period."""
        line = self.notices.add('notice', key, text, self.wall_s())
        if line:
            self.log(level, line)

    # ------------------------------------------------------------- parameters
    def use_params(self, specs, config_from, unconfigured=None):
        """Declare the table ``specs``, set ``self.config = config_from({name: value})`` and take ``ros2 param set``.

        A change is validated as a whole configuration, then ``self.config`` is replaced,
        :meth:`config_changed` called and the change logged. ``unconfigured()`` (managed nodes)
        says when configuration parameters may change. rclpy's ``use_sim_time`` is checked against
        ``timing`` (:func:`ceco_ros.params.sim_time_conflict`) at start (ValueError: the node's FATAL
        line, exit 2) and on a set of either. Returns the configuration.
        """
        self.config = config_from(params.declare_all(self, specs))
        why = params.sim_time_conflict(self.config.timing, self.get_parameter('use_sim_time').value)
        if why:
            raise ValueError(why)
        params.on_set(self, specs, self._set_params, unconfigured)
        self.setup_tools(self.config.log_throttle_s)
        self.qos_events = {'incompatible_qos': 0}
        return self.config

    def _set_params(self, changes: dict) -> str | None:
        ours = {k: v for k, v in changes.items() if k != 'use_sim_time'}
        try:
            config = self.config.replaced(ours) if ours else self.config
        except ValueError as err:
            return str(err)
        sim_time = changes.get('use_sim_time', self.get_parameter('use_sim_time').value)
        why = params.sim_time_conflict(config.timing, sim_time)
        if why:
            return why
        if not ours:
            return None  # use_sim_time alone: rclpy's time source applies it
        self.config = config
        self.notices.throttle_s = self.config.log_throttle_s
        self.config_changed()
        self.get_logger().info(f'parameters set: {changes}')
        return None

    def config_changed(self) -> None:
        """``self.config`` was replaced by ``ros2 param set`` (override to pass it on)."""

    # -------------------------------------------------------------------- QoS
    def qos_event(self, name: str, topic: str) -> None:
        """Count a QoS event of ``topic`` and log it (throttled)."""
        self.qos_events[name] = self.qos_events.get(name, 0) + 1
        self.notice(f'{name} {topic}', f'QoS event on {topic}: {name} (total {self.qos_events[name]})')

    def checked_subscription(self, msg_type, topic: str, callback, qos):
        """A subscription whose QoS ``ros2 param`` may override (``qos_overrides``), incompatible-QoS events counted."""
        from rclpy.event_handler import SubscriptionEventCallbacks

        return self.create_subscription(
            msg_type,
            topic,
            callback,
            qos,
            qos_overriding_options=interfaces.qos_overrides(),
            event_callbacks=SubscriptionEventCallbacks(
                incompatible_qos=lambda _e: self.qos_event('incompatible_qos', topic)
            ),
        )

    def data_readers(self, topic: str, publisher=None) -> int:
        """Subscriptions on ``topic`` that read its data; liveliness probes are not counted.

        Probes: ``interfaces.is_liveliness_probe``. Counted: the graph's subscriptions (remapped name); with
        ``publisher``, at most its matched subscriptions less the probes that match it (a probe matches a
        publisher offering a lease at most the probe's: DDS's request-offer rule). Discovery updates the graph
        and the matches separately: the smaller count holds a lockstep command a moment longer rather than
        release it early. A plant's hvac/command probe otherwise counted as a reader:
        ``lockstep.min_command_subscribers`` (plant and recorder) was met before the recorder had matched
        (issue 19).
        """
        subs = self.get_subscriptions_info_by_topic(self.resolve_topic_name(topic))
        probe = interfaces.is_liveliness_probe
        leases = [e.qos_profile.liveliness_lease_duration for e in subs if probe(e.qos_profile)]
        n = len(subs) - len(leases)
        if publisher is not None:
            offered = publisher.qos_profile.liveliness_lease_duration  # 0: none offered (infinite)
            offers = 0 < offered.nanoseconds and offered != Infinite
            matching = sum(offers and lease.nanoseconds >= offered.nanoseconds for lease in leases)
            n = min(n, publisher.get_subscription_count() - matching)
        return max(0, n)

    def liveliness_probe(self, msg_type, topic: str, lease_s: float, changed):
        """A subscription that only watches the liveliness of ``topic``'s publishers (lease ``lease_s`` [s]).

        ``changed(alive_count, not_alive_count_change)`` on every liveliness event. A publisher
        that offers no lease (or a longer one) does not match the probe; that is not an error
        (it still matches the data subscription), so the probe's incompatible-QoS events are
        not counted.
        """
        from rclpy.event_handler import SubscriptionEventCallbacks

        return self.create_subscription(
            msg_type,
            topic,
            lambda _msg: None,
            interfaces.liveliness_probe_qos(lease_s),
            event_callbacks=SubscriptionEventCallbacks(
                liveliness=lambda e: changed(e.alive_count, e.not_alive_count_change),
                incompatible_qos=lambda _e: None,
            ),
        )


class ManagedNode(NodeTools, LifecycleNode):
    """A lifecycle node that tracks its state and releases its entities.

    Subclasses create their entities in ``on_configure`` and destroy them in ``release()``;
    ``on_activate``/``on_deactivate`` call super() so the lifecycle publishers follow the state.
    """

    lifecycle = 'unconfigured'
    """'unconfigured', 'inactive', 'active' or 'finalized'."""

    def __init__(self, node_name: str, **kwargs):
        super().__init__(node_name, **kwargs)
        # rclpy 7.1 (Jazzy) raises out of the change_state service for a transition the current
        # state does not have (ros2/rclpy#1209, fixed upstream by #1319): the node would die on a
        # wrong `ros2 lifecycle set` or a second manager. Answer success=false instead, as rclcpp.
        service = self._service_change_state
        unsafe = service.callback

        def change_state(request, response):
            try:
                return unsafe(request, response)
            except _rclpy.RCLError as err:
                self.get_logger().warn(
                    f'lifecycle transition {request.transition.id} '
                    f'{request.transition.label!r} refused in state {self.lifecycle}: {err}'
                )
                response.success = False
                return response

        service.callback = change_state

    def start_managed(self, autostart: bool, what: str = '') -> None:
        """Call at the end of the constructor (``what``: the node's role, for the first log line).

        With ``autostart``, configure and activate as soon as the node spins; otherwise wait for
        a lifecycle manager, and say how to be one by hand.
        """
        if autostart:
            self._auto = self.create_timer(0.0, self._autostart)
            self.get_logger().info(f'{what}: unconfigured; autostart: configuring and activating')
        else:
            name = self.get_fully_qualified_name()
            self.get_logger().info(
                f'{what}: unconfigured, waiting for a lifecycle manager (ceco run, a launch file); by hand: '
                f'ros2 lifecycle set {name} configure, then ros2 lifecycle set {name} activate '
                '(or start it with -p autostart:=true)'
            )

    @property
    def active(self) -> bool:
        """True in the active state."""
        return self.lifecycle == 'active'

    def checked_lifecycle_publisher(self, msg_type, topic: str, qos):
        """A lifecycle publisher whose QoS ``ros2 param`` may override, incompatible-QoS events counted."""
        from rclpy.event_handler import PublisherEventCallbacks

        return self.create_lifecycle_publisher(
            msg_type,
            topic,
            qos,
            qos_overriding_options=interfaces.qos_overrides(),
            event_callbacks=PublisherEventCallbacks(
                incompatible_qos=lambda _e: self.qos_event('incompatible_qos', topic)
            ),
        )

    def is_unconfigured(self) -> bool:
        """True in the unconfigured state (configuration parameters may change)."""
        return self.lifecycle == 'unconfigured'

    def use_params(self, specs, config_from, unconfigured=None):
        """:meth:`NodeTools.use_params` with configuration parameters settable while unconfigured."""
        return super().use_params(specs, config_from, unconfigured or self.is_unconfigured)

    def _autostart(self) -> None:
        self.destroy_timer(self._auto)
        if self.trigger_configure() == SUCCESS:
            self.trigger_activate()

    def configured(self) -> TransitionCallbackReturn:
        """Mark a successful configure (return its value from ``on_configure``)."""
        self.lifecycle = 'inactive'
        return SUCCESS

    def on_activate(self, state) -> TransitionCallbackReturn:
        """Activate the lifecycle publishers."""
        self.lifecycle = 'active'
        return super().on_activate(state)

    def on_deactivate(self, state) -> TransitionCallbackReturn:
        """Deactivate the lifecycle publishers."""
        self.lifecycle = 'inactive'
        return super().on_deactivate(state)

    def on_cleanup(self, state) -> TransitionCallbackReturn:
        """Release everything; back to unconfigured."""
        self._release('unconfigured')
        return SUCCESS

    def on_shutdown(self, state) -> TransitionCallbackReturn:
        """Release everything; finalized."""
        self._release('finalized')
        return SUCCESS

    def on_error(self, state) -> TransitionCallbackReturn:
        """Release everything after an error in a transition; back to unconfigured."""
        self._release('unconfigured')
        return SUCCESS

    def _release(self, new_state: str) -> None:
        if self.lifecycle in ('inactive', 'active'):
            self.release()
        self.lifecycle = new_state

    def release(self) -> None:
        """Destroy what ``on_configure`` created (override)."""
