"""Energy and comfort metrics and the benchmark KPIs of a run (``ceco_plant_sim.metrics``).

Defined once in the pure shared core, :mod:`ceco_core.metrics` (the paper's metrics and the
comfort statistics) and :mod:`ceco_core.kpis` (the benchmark KPIs): the simulator, the DDS
stack, report, sweep and benchmark all score runs with them. Re-exported here, where the
plant's users find them.
"""

from ceco_core import kpis as _kpis
from ceco_core import metrics as _metrics
from ceco_core.kpis import *  # noqa: F403 - the public KPI API, re-exported
from ceco_core.metrics import *  # noqa: F403 - the public metrics API, re-exported

__all__ = [*_metrics.__all__, *_kpis.__all__]
