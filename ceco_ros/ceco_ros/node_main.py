"""The Jazzy ``main`` every ceco node runs."""

from __future__ import annotations

import signal

__all__ = ['run_node']


def run_node(node_factory, argv=None, name: str = 'node') -> int:
    """The Jazzy main: init, construct, spin; on any stop path destroy the node and shut down.

    * A ValueError while constructing (an invalid parameter, scenario or file) is logged as one
      ``[FATAL]`` line by a logger of the node's actual name (``name`` with the command line's
      ``__node`` / ``__ns`` remaps applied by rcl) and exits with status 2.
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
    rclpy.init(args=argv)
    node, executor, status, why = None, None, 0, 'shutdown'
    try:
        try:
            node = node_factory()
        except ValueError as err:  # only the construction: a ValueError later is a bug, with its traceback
            _fatal(name, str(err))
            status = 2
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


def _console(logger_name: str, text: str) -> None:
    """An INFO line in rcutils' console format, without /rosout (rclpy's SIGINT handler has shut the context down)."""
    import sys
    import time

    print(f'[INFO] [{time.time():.9f}] [{logger_name}]: {text}', file=sys.stderr, flush=True)


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
