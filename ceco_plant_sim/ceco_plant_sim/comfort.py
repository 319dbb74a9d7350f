"""The occupant comfort evaluation of the plant: ISO 7730 PMV/PPD and the automotive modified PMV.

The equations live once, in the pure shared core :mod:`ceco_core.comfort` (the
NMPC evaluates the same functions symbolically); this module is where users of
the simulator find them (``ceco_plant_sim.comfort.pmv``, ``ppd``, ``cabin_pmv``).
"""

from ceco_core.comfort import *  # noqa: F403 - the public comfort API, re-exported
from ceco_core.comfort import __all__  # noqa: F401
