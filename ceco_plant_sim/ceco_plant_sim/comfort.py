"""The occupant comfort evaluation of the plant: ISO 7730 PMV/PPD, the scored cabin PMV, draught.

The equations live once, in the pure shared core (:mod:`ceco_core.comfort`: ISO 7730 PMV/PPD;
:mod:`ceco_core.cabin_comfort`: the occupant's environment, the scored PMV, fog margin;
:mod:`ceco_core.draught`: ISO 7730 draught rating; the NMPC evaluates the same functions
symbolically); this module is where users of the simulator find them
(``ceco_plant_sim.comfort.pmv``, ``ppd``, ``cabin_pmv``, ``draught_rating``).
"""

from ceco_core.cabin_comfort import *  # noqa: F403 - the public comfort API, re-exported
from ceco_core.cabin_comfort import __all__ as _cabin_all
from ceco_core.comfort import *  # noqa: F403
from ceco_core.comfort import __all__ as _iso_all
from ceco_core.draught import *  # noqa: F403
from ceco_core.draught import __all__ as _draught_all

__all__ = list(_iso_all) + list(_cabin_all) + list(_draught_all)
