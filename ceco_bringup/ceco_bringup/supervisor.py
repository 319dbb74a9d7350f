"""Start and stop the stack's node processes.

This is what `ros2 launch` would do on a full install; here there is no launch,
so we supervise them ourselves.

Each node runs as its own OS process in its own session (so the terminal's
Ctrl-C reaches only `ceco run`, which then stops the children in order),
on a private ROS_DOMAIN_ID with localhost-only discovery, optionally in a ROS
namespace (`-r __ns:=/veh1`), its output in `<log_dir>/<name>.log`. Stopping
is SIGINT (rclpy shuts down cleanly), then SIGKILL after a grace period.

Children are started without a `preexec_fn` (not safe while the recorder's
spin thread runs): `start_new_session=True` gives the session, and util-linux
`setpriv --pdeathsig SIGINT` (where installed; it is on Debian and Ubuntu)
sets the parent-death signal in the child before it execs the node, so no node
outlives a SIGKILLed `ceco run`.

Also here: :class:`StopFlag` (SIGINT/SIGTERM as an event), :func:`wait_for` (poll a
condition while watching the children), :func:`exited_message` (why a child is gone),
:func:`configure_and_activate` (the managed controller's lifecycle transitions through
:class:`LifecycleClient`).
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import signal
import subprocess
import tempfile
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path

from ceco_core.cli_flags import normalize_namespace
from ceco_core.contracts import DOMAIN_ID_MAX

LOG_KEEP_BYTES = 4 * 1024 * 1024
"""Largest log a stopped child leaves [bytes]: a longer one keeps its first and last half of this, whole lines,
with one line between them saying how much was left out (:func:`trim_log`). A controller printing 1 MB per
control step wrote 12 MB per minute of drive, in every cell of a benchmark."""

# Fast DDS participant profile: a UDPv4 transport, a short lease announcement so late
# joiners (a restarted controller) are discovered in ~0.3 s instead of ~3 s, and Fast
# DDS's default 20-s lease. A participant that misses its announcements for longer than the
# lease is dropped with its endpoints and every sample they had not acknowledged: with the
# earlier 2-s lease, `ceco run` frozen for 4 s (SIGSTOP) lost 425 of 600 states (issue 17;
# docs/ros.md, "Starvation and stalls"). Dead peers are the nodes' watchdogs' business
# (fallback within a control period), not the lease's. (With ROS_AUTOMATIC_DISCOVERY_RANGE=
# LOCALHOST the user data still travel over Fast DDS's shared-memory transport: measured,
# /dev/shm/fastrtps_port<7411 + 250 d + 2 i> of the run's domain d.)
FASTDDS_PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <transport_descriptors>
    <transport_descriptor>
      <transport_id>ceco_udp</transport_id>
      <type>UDPv4</type>
    </transport_descriptor>
  </transport_descriptors>
  <participant profile_name="ceco_fast_discovery" is_default_profile="true">
    <rtps>
      <userTransports>
        <transport_id>ceco_udp</transport_id>
      </userTransports>
      <useBuiltinTransports>false</useBuiltinTransports>
      <builtin>
        <discovery_config>
          <leaseDuration><sec>20</sec><nanosec>0</nanosec></leaseDuration>
          <leaseAnnouncement><sec>0</sec><nanosec>250000000</nanosec></leaseAnnouncement>
          <initialAnnouncements><count>5</count><period><sec>0</sec><nanosec>100000000</nanosec></period></initialAnnouncements>
        </discovery_config>
      </builtin>
    </rtps>
  </participant>
</profiles>
"""


def pick_domain_id() -> int:
    """A ROS_DOMAIN_ID for a private run: the pid spread over 1..100, overridable with CECO_DOMAIN_ID.

    Valid ids with localhost discovery are 0..101.
    """
    if os.environ.get('CECO_DOMAIN_ID'):
        return int(os.environ['CECO_DOMAIN_ID'])
    return 1 + (os.getpid() * 7919 + int(time.time())) % 100


_RESERVED: list = []
"""The open lock file of the private domain this process holds (:func:`reserve_domain_id`), or nothing."""


def reserve_domain_id(first: int) -> int:
    """A private ROS_DOMAIN_ID in 1..101 that no other ceco process holds, from ``first`` on, held until the next call.

    Two `ceco run`s, or two workers of `ceco benchmark --controller-cmd`, started at once picked their private
    domain from their pids and the time, so two stacks could share one (1 in 100 per pair) and hear each
    other. Each private domain now has a lock file (``<tmp>/ceco_domain_<id>.lock``, ``flock``): the first
    id from ``first`` (wrapping over 1..101) whose lock this process gets is returned and held; the lock
    goes when this process calls again (its runs are sequential) or exits, however it ends. When every id
    is held, ``first`` is returned as it is (the pid spread then decides, as before).
    """
    import fcntl

    for f in _RESERVED:
        f.close()
    _RESERVED.clear()
    for k in range(101):
        d = 1 + (first - 1 + k) % 101
        try:  # mode 0666: a lock file another user made can be locked by everyone
            fd = os.open(Path(tempfile.gettempdir()) / f'ceco_domain_{d}.lock', os.O_WRONLY | os.O_CREAT, 0o666)
        except OSError:  # (an older lock file of another user, not writable: taken)
            continue
        try:
            os.fchmod(fd, 0o666)  # (the umask took write from the others)
        except OSError:  # not ours
            pass
        f = os.fdopen(fd, 'w')
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.close()
            continue
        _RESERVED.append(f)
        return d
    return first


def private_domain_id(index: int = 0) -> int:
    """The private ROS_DOMAIN_ID of run number ``index`` of this process.

    ``CECO_DOMAIN_ID + index`` as given, folded into 1..101 (an id asked for is used, held or not); else
    ``pick_domain_id() + index`` folded into 1..101, or the next one no other ceco process holds
    (:func:`reserve_domain_id`).
    """
    if os.environ.get('CECO_DOMAIN_ID'):
        return 1 + (pick_domain_id() + index - 1) % 101
    return reserve_domain_id(1 + (pick_domain_id() + index - 1) % 101)


def resolve_domain_id(explicit: int | None = None, index: int = 0, environ=None) -> tuple[int, bool]:
    """The ROS_DOMAIN_ID of run number `index` of one `ceco run`, and whether the user chose it.

    `explicit` (the --domain-id flag) first, then the user's ROS_DOMAIN_ID
    (non-empty), used as is for every run (the runs are sequential; each
    stops its nodes before the next starts); otherwise a private id per run
    (:func:`private_domain_id`). Raises ValueError for an
    id that is not an integer in 0..DOMAIN_ID_MAX.
    """
    environ = os.environ if environ is None else environ
    if explicit is not None:
        chosen, source = explicit, '--domain-id'
    elif environ.get('ROS_DOMAIN_ID', '').strip():
        text = environ['ROS_DOMAIN_ID'].strip()
        if not re.fullmatch(r'\d+', text):
            raise ValueError(f'ROS_DOMAIN_ID={text!r}: must be an integer in 0..{DOMAIN_ID_MAX}')
        chosen, source = int(text), 'ROS_DOMAIN_ID'
    else:
        return private_domain_id(index), False
    if not 0 <= chosen <= DOMAIN_ID_MAX:
        raise ValueError(f'{source}={chosen}: must be an integer in 0..{DOMAIN_ID_MAX}')
    return chosen, True


def dds_env(domain_id: int, base: dict | None = None) -> dict:
    """Environment for a private, localhost-only DDS run with the :data:`FASTDDS_PROFILE` participant profile.

    The profile file is named after its content (``ceco_fastdds_profile_<sha>.xml`` in the temp
    directory), so checkouts with different profiles on one machine never rewrite each other's.
    """
    env = dict(os.environ if base is None else base)
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.pop('ROS_LOCALHOST_ONLY', None)
    env.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    env['FASTDDS_BUILTIN_TRANSPORTS'] = 'UDPv4'
    digest = hashlib.sha256(FASTDDS_PROFILE.encode()).hexdigest()[:12]
    profile = Path(tempfile.gettempdir()) / f'ceco_fastdds_profile_{digest}.xml'
    if not profile.exists() or profile.read_text() != FASTDDS_PROFILE:
        tmp = profile.with_suffix(f'.{os.getpid()}.tmp')
        tmp.write_text(FASTDDS_PROFILE)
        tmp.replace(profile)
    env['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(profile)
    env['PYTHONUNBUFFERED'] = '1'
    env['RCUTILS_COLORIZED_OUTPUT'] = '0'
    return env


def find_executable(package: str, executable: str) -> str:
    """`<prefix>/lib/<package>/<executable>` on AMENT_PREFIX_PATH (where `ros2 run` looks).

    Raises FileNotFoundError (saying how to build the workspace) if no prefix has it.
    """
    for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        if prefix:
            path = Path(prefix) / 'lib' / package / executable
            if path.is_file() and os.access(path, os.X_OK):
                return str(path)
    raise FileNotFoundError(
        f'{package}/{executable} not found on AMENT_PREFIX_PATH: build the workspace '
        '(bash tools/setup.sh) and `source tools/env.sh`'
    )


def share_file(package: str, relpath: str) -> str:
    """A file in `<prefix>/share/<package>/` on AMENT_PREFIX_PATH."""
    for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        if prefix:
            path = Path(prefix) / 'share' / package / relpath
            if path.is_file():
                return str(path)
    raise FileNotFoundError(f'share/{package}/{relpath} not found on AMENT_PREFIX_PATH')


STACK_NODES = {
    'preview_node': 'ceco_v2x_preview',
    'mpc_node': 'ceco_controller',
    'baseline_node': 'ceco_controller',
    'plant_node': 'ceco_plant_sim',
}
"""The stack's executables and their packages (the launch file's ``NODES``; ceco_bringup/test/test_launch.py
checks they agree)."""


def stack_node(
    executable: str, *, env: dict, log_dir: Path, params: dict | None = None, namespace: str | None = None, name=None
) -> NodeProcess:
    """A :class:`NodeProcess` of one of the :data:`STACK_NODES` with its installed ``config/<executable>.yaml``."""
    package = STACK_NODES[executable]
    return NodeProcess(
        name or executable,
        package,
        executable,
        env=env,
        log_dir=log_dir,
        namespace=namespace,
        params_files=[share_file(package, f'config/{executable}.yaml')],
        params=params,
    )


class NodeProcess:
    """One node executable as a child process."""

    def __init__(
        self,
        name: str,
        package: str | None,
        executable: str | None,
        *,
        params_files=(),
        params: dict | None = None,
        env: dict,
        log_dir: Path,
        node_name: str | None = None,
        namespace: str | None = None,
        command: list[str] | None = None,
    ):
        """A ceco node ``package/executable`` with ROS arguments, or any ``command``.

        The node runs under ``namespace`` if given. A ``command`` (a third-party controller in
        any language) is run as given, without ROS arguments.
        """
        self.name = name
        if command is not None:
            if not command:
                raise ValueError(f'{name}: empty command')
            self.cmd = list(command)
        else:
            self.cmd = [find_executable(package, executable), '--ros-args']
            if node_name:
                self.cmd += ['-r', f'__node:={node_name}']
            if normalize_namespace(namespace):
                self.cmd += ['-r', f'__ns:={normalize_namespace(namespace)}']
            for f in params_files:
                self.cmd += ['--params-file', str(f)]
            for key, value in (params or {}).items():
                self.cmd += ['-p', f'{key}:={_param_text(value)}']
        self.env = env
        self.log_path = Path(log_dir) / f'{name}.log'
        self.proc: subprocess.Popen | None = None
        self.starts = 0

    def start(self) -> None:
        """Start the process in its own session, appending its output to ``log_path``.

        Each start is logged with its command line first; ``starts`` counts them.
        """
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        log = open(self.log_path, 'ab')
        log.write(f'--- start {self.starts + 1}: {" ".join(self.cmd)}\n'.encode())
        log.flush()
        self.proc = subprocess.Popen(
            _die_with_parent_prefix() + self.cmd,
            env=self.env,
            stdout=log,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
        )
        log.close()
        self.starts += 1

    @property
    def pid(self) -> int | None:
        """The process id of the latest start, None before the first."""
        return None if self.proc is None else self.proc.pid

    def running(self) -> bool:
        """True if the process has been started and has not exited."""
        return self.proc is not None and self.proc.poll() is None

    def returncode(self):
        """The exit code, None if the process was never started or is still running."""
        return None if self.proc is None else self.proc.poll()

    def cpu_time_s(self) -> float | None:
        """CPU time the process has used so far (user + system, Linux ``/proc/<pid>/stat``) [s]; None if unknown."""
        if self.proc is None:
            return None
        try:
            fields = proc_stat_fields(self.proc.pid)
            return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')  # utime, stime: fields 14, 15
        except (OSError, ValueError, IndexError):
            return None

    def signal(self, sig) -> None:
        """Send signal ``sig`` to the process if it is running (a process that just exited is ignored)."""
        if self.running():
            try:
                os.kill(self.proc.pid, sig)
            except ProcessLookupError:
                pass

    def stop(self, timeout_s: float = 5.0) -> int | None:
        """SIGINT (and SIGCONT, so a stopped process handles it), wait, then SIGKILL. Returns the exit code.

        The signals go to the process's whole group (its own session: :meth:`start`), so what it started goes
        with it (a third-party controller's helper process, or the node a launcher script runs without ``exec``:
        both outlived the benchmark before, the node still on the run's private domain). Whatever of its
        group, or of the processes it started in a session of their own, is left once it has exited is killed,
        and its log says which (:func:`left_behind`). The log is then trimmed to :data:`LOG_KEEP_BYTES`
        (:func:`trim_log`).
        """
        if self.proc is None:
            return None
        started = descendants(self.proc.pid) if self.running() else {}
        self.signal_group(signal.SIGINT)
        self.signal_group(signal.SIGCONT)
        try:
            code = self.proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            self.signal_group(signal.SIGKILL)
            code = self.proc.wait()
        left = left_behind(self.proc.pid, started)
        if left:
            with open(self.log_path, 'a', encoding='utf-8') as f:
                f.write(f'--- stopped: killed {len(left)} process(es) it left behind: pids {left}\n')
        trim_log(self.log_path)
        return code

    def signal_group(self, sig) -> None:
        """Send ``sig`` to the process's group (its session's), or to it alone where there is no such group."""
        if self.proc is None:
            return
        try:
            os.killpg(self.proc.pid, sig)
        except (ProcessLookupError, PermissionError):
            self.signal(sig)

    def kill(self) -> None:
        """SIGKILL (fault injection)."""
        self.signal(signal.SIGKILL)
        if self.proc is not None:
            self.proc.wait()

    def log_text(self) -> str:
        """The process's log file so far ('' if it does not exist yet)."""
        try:
            return self.log_path.read_text(errors='replace')
        except FileNotFoundError:
            return ''


def proc_stat_fields(pid: int) -> list[str]:
    """The fields of ``/proc/<pid>/stat`` from the state on (field 3, ``proc(5)``); OSError without the process.

    They follow ``pid (comm) ``, whose command name may hold spaces and parentheses.
    """
    text = Path(f'/proc/{pid}/stat').read_text()
    return text[text.rindex(')') + 2 :].split()


ORPHAN_GRACE_S = 1.0
"""How long what a stopped process left behind may take to end on its SIGINT before SIGKILL [s]."""


def _proc_table() -> dict[int, tuple[int, int, int]]:
    """{pid: (parent pid, process group id, start time)} of every live process (Linux ``/proc/<pid>/stat``).

    The start time (clock ticks since boot) tells a process from a later one with its pid.
    """
    table = {}
    for d in Path('/proc').iterdir():
        if not d.name.isdigit():
            continue
        try:
            fields = proc_stat_fields(int(d.name))  # state(3) ppid(4) pgrp(5) ... starttime(22)
            if fields[0] != 'Z':  # a zombie is already gone
                table[int(d.name)] = (int(fields[1]), int(fields[2]), int(fields[19]))
        except (OSError, ValueError, IndexError):
            continue
    return table


def descendants(pid: int) -> dict[int, int]:
    """{pid: start time} of the processes ``pid`` started, and of theirs, as they are now (Linux ``/proc``)."""
    table = _proc_table()
    children: dict[int, list[int]] = {}
    for p, (ppid, _, _) in table.items():
        children.setdefault(ppid, []).append(p)
    out, todo = {}, list(children.get(pid, []))
    while todo:
        p = todo.pop()
        out[p] = table[p][2]
        todo += children.get(p, [])
    return out


def left_behind(pgid: int, started: Mapping[int, int] | None = None, grace_s: float = ORPHAN_GRACE_S) -> list[int]:
    """Kill (SIGKILL) what is left of process group ``pgid`` and of the processes ``started``; their pids.

    Called once the group's leader has exited: its members, and the processes it had started in sessions
    of their own (``setsid``; ``started``: :func:`descendants` before the stop), are orphans. They had the
    group's SIGINT; those still there after ``grace_s`` are killed.
    """
    started = dict(started or {})

    def left() -> list[int]:
        return sorted(p for p, (_, g, t) in _proc_table().items() if g == pgid or started.get(p) == t)

    deadline = time.monotonic() + grace_s
    pids = left()
    while pids and time.monotonic() < deadline:
        time.sleep(0.05)
        pids = left()
    for p in pids:
        try:
            os.kill(p, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
    return pids


def _die_with_parent_prefix() -> list[str]:
    """The command prefix `setpriv --pdeathsig SIGINT --`, or [] where util-linux's setpriv is missing.

    The child gets SIGINT when the thread that started it dies (even by SIGKILL),
    so no node outlives `ceco run` (Linux prctl PR_SET_PDEATHSIG, kept across the
    exec into the node). Without setpriv the nodes outlive a SIGKILL.
    """
    setpriv = shutil.which('setpriv')
    return [setpriv, '--pdeathsig', 'SIGINT', '--'] if setpriv else []


def _param_text(value) -> str:
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, (list, tuple)):
        return '[' + ','.join(_param_text(v) for v in value) + ']'
    if isinstance(value, float):
        return repr(value)
    return str(value)


def call_service(client, request, timeout_s: float, attempt_s: float | None = None):
    """Call a service and wait for its answer while an executor spins the client's node in another thread.

    Args:
        client: an rclpy service client.
        request: the request message.
        timeout_s: how long to wait in all [s].
        attempt_s: if given, the request is sent again after each ``attempt_s`` [s] without an
            answer. An answer can be lost (Fast DDS drops a response when the server has not
            matched the client's response reader yet: see :meth:`LifecycleClient.change`), so a
            request that is safe to repeat (get or set parameters, get_state) is resent; one that
            is not (change_state) is sent once and its outcome read from the node's state.

    Returns:
        The response, or None when none came within ``timeout_s``.
    """
    deadline = time.monotonic() + timeout_s
    while True:
        future = client.call_async(request)
        give_up = deadline if attempt_s is None else min(deadline, time.monotonic() + attempt_s)
        while not future.done():
            if time.monotonic() > give_up:
                client.remove_pending_request(future)
                break
            time.sleep(0.005)
        if future.done():
            return future.result()
        if time.monotonic() >= deadline:
            return None


class LifecycleClient:
    """Drives a managed node's transitions through its ``<node>/change_state`` service.

    What ``ros2 lifecycle set`` and launch_ros' lifecycle events do, from a node that some
    executor spins in another thread.

    Args:
        node: the rclpy node to create the service clients on (spun elsewhere).
        target: the managed node's fully qualified name, e.g. ``/mpc_node`` or ``/veh1/mpc_node``.
    """

    TRANSITIONS = ('configure', 'activate', 'deactivate', 'cleanup', 'shutdown')

    def __init__(self, node, target: str):
        from lifecycle_msgs.srv import ChangeState, GetState

        self.target = target if target.startswith('/') else '/' + target
        self._change = node.create_client(ChangeState, f'{self.target}/change_state')
        self._get = node.create_client(GetState, f'{self.target}/get_state')

    def wait(self, timeout_s: float) -> bool:
        """True once the lifecycle services are up (within ``timeout_s`` [s])."""
        return self._change.wait_for_service(timeout_sec=timeout_s) and self._get.wait_for_service(timeout_sec=1.0)

    def state(self, timeout_s: float = 5.0) -> str | None:
        """The node's current state label ('unconfigured', 'inactive', 'active', 'finalized'), None on timeout."""
        from lifecycle_msgs.srv import GetState

        res = call_service(self._get, GetState.Request(), timeout_s)
        return None if res is None else res.current_state.label

    GOAL = {
        'configure': 'inactive',
        'activate': 'active',
        'deactivate': 'inactive',
        'cleanup': 'unconfigured',
        'shutdown': 'finalized',
    }
    """The primary state each transition ends in when it succeeds (REP 2002 / design.ros2.org)."""

    ORIGIN = {'configure': 'unconfigured', 'activate': 'inactive', 'deactivate': 'active', 'cleanup': 'inactive'}
    """The primary state each transition starts from ('shutdown' starts from any of three)."""

    PRIMARY = ('unconfigured', 'inactive', 'active', 'finalized')
    """The primary (settled) states; the others are transition states (configuring, ..., errorprocessing)."""

    def change(
        self,
        transition: str,
        timeout_s: float = 30.0,
        attempt_s: float = 5.0,
        alive: Callable[[], bool] = lambda: True,
    ) -> bool:
        """Request a transition by name (:data:`TRANSITIONS`); True when the node made it.

        For 'shutdown' the node's current state picks the transition id (from unconfigured,
        inactive or active).

        An answer can be lost: Fast DDS drops a service's response when the server has not
        matched the client's response reader yet (rmw_fastrtps "failed to send response
        (timeout): client will not receive response", seen on a loaded machine at start-up).
        So after ``attempt_s`` [s] without an answer the node's state decides: the goal state
        is success; the state the transition starts from means the request never ran, and it
        is sent again; another primary state is a failure (e.g. finalized after an error); a
        transition state or no answer to get_state either is polled every 0.1 s. A refusal
        that comes after a resent request is checked against the state too (the first request
        may have run after all). False when the node answers that the transition failed, after
        ``timeout_s`` [s] in all, or as soon as ``alive()`` is false (the node's process gone,
        a stop signal).
        """
        from lifecycle_msgs.msg import Transition
        from lifecycle_msgs.srv import ChangeState

        deadline = time.monotonic() + timeout_s

        def budget() -> float:
            return max(min(attempt_s, deadline - time.monotonic()), 0.1)

        if transition == 'shutdown':
            origin = self.state(min(attempt_s, 0.5 * timeout_s)) or 'active'
            ids = {
                'unconfigured': Transition.TRANSITION_UNCONFIGURED_SHUTDOWN,
                'inactive': Transition.TRANSITION_INACTIVE_SHUTDOWN,
            }
            tid = ids.get(origin, Transition.TRANSITION_ACTIVE_SHUTDOWN)
        else:
            origin = self.ORIGIN[transition]
            tid = getattr(Transition, f'TRANSITION_{transition.upper()}')
        goal = self.GOAL[transition]
        request = ChangeState.Request(transition=Transition(id=tid))
        sent = 0
        send = True
        while time.monotonic() < deadline and alive():
            if send:
                res = call_service(self._change, request, budget())
                sent += 1
                if res is not None:
                    if res.success or sent == 1:
                        return bool(res.success)
                    return self.state(budget()) == goal
            state = self.state(budget())
            if state == goal:
                return True
            if state in self.PRIMARY and state != origin:
                return False
            send = state == origin
            if not send:
                time.sleep(0.1)
        return False


class Interrupted(Exception):
    """SIGINT/SIGTERM received."""


class StopFlag:
    """A SIGINT/SIGTERM latch: ``install`` sets handlers that set ``event``; ``restore`` puts the old ones back."""

    def __init__(self):
        self.event = threading.Event()
        self.signum = None

    def install(self):
        """Handle SIGINT and SIGTERM by setting the flag (main thread only)."""

        def handler(signum, _frame):
            self.signum = signum
            self.event.set()

        self._old = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}

    def restore(self):
        """Put back the handlers that were there before :meth:`install`."""
        for s, h in getattr(self, '_old', {}).items():
            signal.signal(s, h)


def configure_and_activate(context, executor, name, timeout_s, stop, procs):
    """Configure and activate the managed controller ``name`` (a node of ``procs``); returns its LifecycleClient."""
    import rclpy

    node = rclpy.create_node('ceco_run_lifecycle', context=context)
    executor.add_node(node)
    client = LifecycleClient(node, name)
    wait_for(lambda: client.wait(0.05), timeout_s, stop, procs, f'the lifecycle services of {name}')
    controller = procs['controller']
    for transition in ('configure', 'activate'):
        if not client.change(
            transition, timeout_s=timeout_s, alive=lambda: not stop.event.is_set() and controller.running()
        ):
            if stop.event.is_set():
                raise Interrupted()
            exited = '' if controller.running() else f' (it exited with status {controller.returncode()})'
            raise RuntimeError(
                f'{name}: lifecycle transition {transition} failed{exited}; log: '
                f'{controller.log_path}\n' + log_tail(controller.log_text())
            )
    return client


def wait_for(cond, timeout_s, stop, procs, what):
    """Poll ``cond`` until true.

    Raises Interrupted on a stop signal, RuntimeError (with the log's tail) if a child of ``procs``
    exits or after ``timeout_s``.
    """
    t0 = time.monotonic()
    while not cond():
        if stop.event.wait(0.05):
            raise Interrupted()
        for name, proc in procs.items():
            if proc.proc is not None and not proc.running():
                raise RuntimeError(exited_message(name, proc, f' while waiting for {what}'))
        if time.monotonic() - t0 > timeout_s:
            raise RuntimeError(f'timeout ({timeout_s} s) waiting for {what}')


def exited_message(name: str, proc: NodeProcess, when: str = '') -> str:
    """Why the child ``name`` of a run is gone, for the run's error.

    plant_node that stopped the simulation (its exit status 3 and ERROR line,
    ``ceco_plant_sim.plant_loop``): ``the simulation stopped: <reason> (plant_node; log: <path>)``;
    any other exit: its status (``when``: e.g. ' while waiting for ...'), log path and the log's tail.
    """
    if name == 'plant_node':
        from ceco_plant_sim.plant_loop import simulation_stopped  # (here: the plant package imports CasADi)

        stopped = simulation_stopped(proc.returncode(), proc.log_text())
        if stopped:
            return f'{stopped} ({name}; log: {proc.log_path})'
    return f'{name} exited with status {proc.returncode()}{when}; log: {proc.log_path}\n' + log_tail(proc.log_text())


def trim_log(path: Path, keep_bytes: int = LOG_KEEP_BYTES) -> int:
    """Cut the middle out of a log longer than ``keep_bytes``; returns the bytes left out (0: unchanged).

    The first and the last ``keep_bytes // 2`` bytes are kept, each cut back to whole lines, with the line
    ``[ceco: N bytes of this log left out (longer than K bytes); its start and its end are kept]`` between
    them: the start holds the command line and the first errors, the end the exit's reason. Written to a
    temporary file, then renamed over the log (a reader sees the whole log or the trimmed one). Best effort: a
    log that cannot be read or rewritten (a full disk, a read-only directory) is left whole, and 0 returned.
    """
    path = Path(path)
    half = keep_bytes // 2
    try:
        size = path.stat().st_size
        if size <= keep_bytes:
            return 0
        with open(path, 'rb') as f:
            head = f.read(half)
            f.seek(size - half - 1)  # with the byte before the last half: a newline there starts a whole line
            tail = f.read()
    except OSError:  # no log (never started), or one that cannot be read: left as it is
        return 0
    head = head[: head.rfind(b'\n') + 1]  # '' when the first half has no newline: nothing of it is kept
    tail = tail[tail.find(b'\n') + 1 :]  # all of it when that byte is no newline and the half holds none
    left_out = size - len(head) - len(tail)
    marker = f'[ceco: {left_out} bytes of this log left out (longer than {keep_bytes} bytes); '
    marker += 'its start and its end are kept]'
    tmp = path.with_name(path.name + '.trim')
    try:  # best effort: a full disk or a read-only directory leaves the log whole (the run's stop goes on)
        tmp.write_bytes(head + marker.encode() + b'\n' + tail)
        os.replace(tmp, path)
    except OSError:
        tmp.unlink(missing_ok=True)
        return 0
    return left_out


def log_tail(text: str, n: int = 15) -> str:
    """The last ``n`` lines of a log text."""
    return '\n'.join(text.strip().splitlines()[-n:])
