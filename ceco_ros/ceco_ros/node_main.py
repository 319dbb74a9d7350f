"""The Jazzy ``main`` every ceco node runs."""

from __future__ import annotations

import signal

__all__ = ['START_FAILED_EXIT', 'run_node']

START_FAILED_EXIT = 1
"""Exit status of a node that could not start for another reason than a bad parameter (2)."""

SECURITY_HINT = (
    'ROS_SECURITY_ENABLE is true: the node needs its enclave (--enclave) with its keys in '
    'ROS_SECURITY_KEYSTORE (ceco security create-keystore DIR) and a Fast DDS built with security '
    '(docs/ros.md, "Who may command the plant")'
)
"""Added to a start failure whose message is about security while ROS security is on."""


def run_node(node_factory, argv=None, name: str = 'node') -> int:
    """The Jazzy main: init, construct, spin; on any stop path destroy the node and shut down.

    * A ValueError while constructing (an invalid parameter, scenario or file) is logged as one
      ``[FATAL]`` line by a logger of the node's actual name (``name`` with the command line's
      ``__node`` / ``__ns`` remaps applied by rcl) and exits with status 2.
    * Any other exception from ``rclpy.init`` or while constructing (rcl could not create the node:
      ``ROS_SECURITY_ENABLE=true`` without the enclave's keys, or a Fast DDS without security) is
      logged as one ``[ERROR]`` line ``could not start: <the exception's message>`` (with a hint
      when ROS security is on and the message is about security), no traceback, and exits with
      status 1 (:data:`START_FAILED_EXIT`).
    * SIGINT (Ctrl-C, ``ros2 launch`` stopping, ``ceco run``), SIGTERM (rclpy's handler: an
      external shutdown) or a shutdown of the context: the node logs ``stopped (<why>): exit 0``,
      is destroyed and the process exits 0. Signals that arrive during that cleanup (a
      terminal's Ctrl-C reaches every node of a ``ros2 launch`` twice: from the terminal and
      from launch) are ignored, so no KeyboardInterrupt cuts the cleanup short.
    * A node that ends itself (it shuts the context down) may say how first: its ``exit_status`` (int) and
      ``exit_reason`` attributes, when set, are the status returned and the ``<why>`` of the line above
      (plant_node when its plant cannot go on: status 3).
    * The node spins in an executor of its own that cannot be left half-built: a stop signal that
      lands inside ``Executor.__init__`` stops the node as above, without the traceback rclpy's
      ``Executor.__del__`` prints for an executor whose ``__init__`` did not reach its last line.
    """
    import rclpy
    from rclpy.executors import ExternalShutdownException

    # Before init, so rclpy's own handler (it shuts the context down) chains to this one: the first
    # SIGINT / SIGTERM stops spinning, and from then on every stop signal is ignored.
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, _stop)
    try:
        rclpy.init(args=argv)
    except Exception as err:  # rcl could not initialise (a security enclave that is not in the keystore)
        _console(name, start_failure(err), 'ERROR')
        return START_FAILED_EXIT
    node, executor, status, why = None, None, 0, 'shutdown'
    try:
        try:
            node = node_factory()
        except ValueError as err:  # only the construction: a ValueError later is a bug, with its traceback
            _fatal(name, str(err))
            status = 2
        except Exception as err:  # rcl could not create the node, or the constructor failed otherwise
            _console(name, start_failure(err), 'ERROR')  # no probe node: creating one may fail the same way
            status = START_FAILED_EXIT
        else:
            executor = _executor()
            rclpy.spin(node, executor)
    except KeyboardInterrupt as stop:
        why = str(stop) or 'SIGINT'
    except ExternalShutdownException:
        why = 'external shutdown'
    finally:
        _ignore_stop_signals()  # the cleanup runs to its end
        if node is not None:
            if status == 0 and getattr(node, 'exit_status', None) is not None:  # the node ended itself, said why
                status, why = int(node.exit_status), str(getattr(node, 'exit_reason', why))
            _console(node.get_logger().name, f'stopped ({why}): exit {status}')
            node.destroy_node()
            if executor is not None:
                executor.shutdown()
        elif status == 0:  # stopped while the node was being constructed
            _console(name, f'stopped ({why}) while starting: exit 0')
        rclpy.try_shutdown()
        _ignore_stop_signals()  # try_shutdown puts back the handlers of before init
    return status


def _executor():
    """A SingleThreadedExecutor whose ``__del__`` is safe even if ``__init__`` is interrupted."""
    from rclpy.executors import SingleThreadedExecutor

    executor = SingleThreadedExecutor.__new__(SingleThreadedExecutor)
    executor._sigint_gc = None  # what Executor.__del__ reads; __init__ sets it near its end
    executor.__init__()
    return executor


def start_failure(err: BaseException) -> str:
    """The one line of a node that could not start: ``could not start: <message>``.

    With a hint when ROS security is on (``ROS_SECURITY_ENABLE=true``, rcl's own test) and the message speaks of
    security. rcutils' ``, at <file>:<line>`` locations are left out and the message's lines joined.
    """
    import os
    import re

    text = ' '.join(re.sub(r', at /\S+:\d+', '', str(err)).split()) or type(err).__name__
    line = f'could not start: {text}'
    if os.environ.get('ROS_SECURITY_ENABLE') == 'true' and 'secur' in text.lower():
        line += f' ({SECURITY_HINT})'
    return line


def _console(logger_name: str, text: str, level: str = 'INFO') -> None:
    """A line in rcutils' console format, without /rosout (rclpy's SIGINT handler has shut the context down)."""
    import sys
    import time

    print(f'[{level}] [{time.time():.9f}] [{logger_name}]: {text}', file=sys.stderr, flush=True)


def _stop(signum, _frame) -> None:
    _ignore_stop_signals()
    raise KeyboardInterrupt(signal.Signals(signum).name)


def _ignore_stop_signals() -> None:
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.SIG_IGN)


def _fatal(default_name: str, text: str) -> None:
    """Log ``text`` as FATAL under the node's resolved name (a probe node gets the same remaps)."""
    import sys

    import rclpy

    try:
        probe = rclpy.create_node(default_name, enable_rosout=False)
        probe.get_logger().fatal(text)
        probe.destroy_node()
    except Exception:  # the context is gone: say it without ROS logging
        print(f'[FATAL] [{default_name}]: {text}', file=sys.stderr, flush=True)
