"""The executables of ceco_controller (setup.py console_scripts), through :func:`ceco_ros.entry.start`."""

from ceco_ros.entry import start


def mpc_node() -> int:
    """The mpc_node executable."""
    return start('ceco_controller.mpc_node', 'mpc_node')


def baseline_node() -> int:
    """The baseline_node executable."""
    return start('ceco_controller.baseline_node', 'baseline_node')
