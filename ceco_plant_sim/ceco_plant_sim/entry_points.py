"""The executable of ceco_plant_sim (setup.py console_scripts), through :func:`ceco_ros.entry.start`."""

from ceco_ros.entry import start


def plant_node() -> int:
    """The plant_node executable."""
    return start('ceco_plant_sim.plant_node', 'plant_node')
