"""The Jazzy ``main`` every ceco node runs."""

from __future__ import annotations

__all__ = ['run_node']


def run_node(node_factory, argv=None, name: str = 'node') -> int:
    """The Jazzy main: init, construct, spin; on any stop path destroy the node and shut down.

    A ValueError while constructing (an invalid parameter) is
    reported as one clear line and exits with status 2.
    """
    import sys

    import rclpy
    from rclpy.executors import ExternalShutdownException

    rclpy.init(args=argv)
    node = None
    try:
        node = node_factory()
        rclpy.spin(node)
    except ValueError as err:
        print(f'[FATAL] [{name}]: {err}', file=sys.stderr, flush=True)
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
