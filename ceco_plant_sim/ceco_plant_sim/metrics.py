"""Energy and comfort metrics of a run (``ceco_plant_sim.metrics``).

Defined once in the pure shared core :mod:`ceco_core.metrics` (the simulator,
the DDS stack, report, sweep and benchmark all score runs with it) and
re-exported here, where the plant's users find them.
"""

from ceco_core.metrics import *  # noqa: F403 - the public metrics API, re-exported
from ceco_core.metrics import __all__  # noqa: F401
