"""The console-script entry of every ceco node: a stop signal during start-up ends it with exit 0.

A node's module imports numpy, rclpy, CasADi (0.3-1 s) before its ``main`` installs the stop
handlers (:func:`ceco_ros.node_main.run_node`); a Ctrl-C or a ``ros2
launch`` shutdown in that window used to end the process with a KeyboardInterrupt traceback from
inside an import (exit -2). :func:`start` installs a handler first (standard library only), so
such a stop is said in one line and exits 0; nothing is open yet that would need cleaning up.
"""

from __future__ import annotations

import importlib
import os
import signal
import sys
import time

__all__ = ['start']


def start(module: str, name: str) -> int:
    """Import ``module`` (a node's module) with stop signals ending the process cleanly, then run its ``main``."""

    def stopped(signum, _frame) -> None:
        sig = signal.Signals(signum).name
        print(
            f'[INFO] [{time.time():.9f}] [{name}]: stopped ({sig}) while starting: exit 0', file=sys.stderr, flush=True
        )
        os._exit(0)

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, stopped)
    return importlib.import_module(module).main()
