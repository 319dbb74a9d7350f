"""The shipped refrigerant table file, and the plant's tables taken from it.

The default configuration (R-1234yf, 5 K superheat, 5 K subcooling,
:data:`~ceco_plant_sim.refrigerant_tables.DEFAULT_GRID`) is shipped as the generated data file
``data/cycle_tables_R1234yf.npz`` (the raw CoolProp values of
:func:`~ceco_plant_sim.refrigerant_tables.build_cycle_tables`, float64, with their provenance:
CoolProp version, fluid, grid, superheat, subcooling, generation command and date), loaded in a
few milliseconds without importing CoolProp (whose import alone takes ~2.3 s). Any other
configuration is built with CoolProp, imported then, with a warning. Regenerate the file with
``python tools/make_refrigerant_tables.py``; ``--check`` (and ``tests/test_refrigerant.py``)
compare it bit for bit with a fresh build.
"""

from __future__ import annotations

import functools
import json
import logging
import os
from dataclasses import asdict
from typing import Any

import numpy as np

from .refrigerant_tables import (
    ARRAY_2D,
    ARRAYS_1D_TC,
    ARRAYS_1D_TE,
    DEFAULT_GRID,
    CycleTables,
    TableGrid,
    build_cycle_tables,
    make_tables,
)

__all__ = [
    "SHIPPED_TABLES",
    "REGENERATE_COMMAND",
    "StaleTablesError",
    "cycle_tables",
    "tables_arrays",
    "write_tables_file",
    "read_tables_file",
    "load_tables_file",
    "check_tables_file",
]

_LOG = logging.getLogger(__name__)

SHIPPED_TABLES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "cycle_tables_R1234yf.npz")
"""The generated cycle-table file installed with the package (package_data)."""
REGENERATE_COMMAND = "python tools/make_refrigerant_tables.py"
"""The command that regenerates :data:`SHIPPED_TABLES` (from the repository root)."""
TABLES_FORMAT = 1
"""Layout version of the table file (arrays and provenance keys below)."""


class StaleTablesError(ValueError):
    """A table file that does not match what it claims or what is asked (format, grid, CoolProp, values)."""


def tables_arrays(tab: CycleTables) -> dict[str, np.ndarray]:
    """The raw property values of ``tab`` (float64 arrays, the table file's content)."""
    out = {k: np.asarray(getattr(tab, k).y, dtype=np.float64) for k in ARRAYS_1D_TE + ARRAYS_1D_TC}
    out[ARRAY_2D] = np.asarray(tab.dh_is_jpkg.z, dtype=np.float64)
    return out


def write_tables_file(
    path: str,
    fluid: str = "R1234yf",
    superheat_k: float = 5.0,
    subcool_k: float = 5.0,
    grid: TableGrid = DEFAULT_GRID,
    command: str = REGENERATE_COMMAND,
    extra: dict | None = None,
) -> dict:
    """Build the tables with CoolProp and write them with their provenance to ``path`` (NPZ). Returns the provenance.

    The arrays are the float64 values :func:`build_cycle_tables` computes (bit for bit); the
    provenance (a JSON string under the key ``provenance``) records the format, fluid,
    superheat, subcooling, grid, CoolProp version and git revision, the command and the UTC
    date, plus ``extra``.
    """
    import datetime
    import platform

    import CoolProp

    grid.validate()
    tab = build_cycle_tables(fluid, float(superheat_k), float(subcool_k), *grid.build_args())
    prov = {
        "format": TABLES_FORMAT,
        "fluid": fluid,
        "superheat_k": float(superheat_k),
        "subcool_k": float(subcool_k),
        "grid": asdict(grid),
        "coolprop_version": CoolProp.__version__,
        "coolprop_gitrevision": CoolProp.__gitrevision__,
        "generator": "ceco_plant_sim.refrigerant.build_cycle_tables",
        "command": command,
        "date_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": f"{platform.machine()} {platform.system()}, Python {platform.python_version()}, "
        f"numpy {np.__version__}",
        "units": {
            "p_evap_pa": "Pa",
            "rho_suc_kgm3": "kg/m3",
            "h_suc_jpkg": "J/kg",
            "p_cond_pa": "Pa",
            "h_liq_jpkg": "J/kg",
            "dh_is_jpkg": "J/kg",
        },
        **(extra or {}),
    }
    members = {"provenance": np.array(json.dumps(prov, sort_keys=True)), **tables_arrays(tab)}
    savez: Any = np.savez  # numpy's stubs type **kwds as its own keyword arguments
    with open(path, "wb") as f:
        savez(f, **members)
    return prov


def read_tables_file(path: str) -> tuple[dict, dict[str, np.ndarray]]:
    """(provenance, arrays) of a table file, checked for layout: format, grid, shapes, finite values.

    Raises StaleTablesError naming what is wrong and the regeneration command; never imports CoolProp.
    """
    fix = f"regenerate it with `{REGENERATE_COMMAND}`"
    try:
        with np.load(path, allow_pickle=False) as z:
            prov = json.loads(str(z["provenance"]))
            arrays = {k: z[k] for k in z.files if k != "provenance"}
    except (OSError, KeyError, ValueError) as err:
        raise StaleTablesError(f"refrigerant table file {path}: unreadable ({err}); {fix}") from err
    if prov.get("format") != TABLES_FORMAT:
        raise StaleTablesError(
            f"refrigerant table file {path}: format {prov.get('format')!r}, this code reads "
            f"format {TABLES_FORMAT}; {fix}"
        )
    try:
        grid = TableGrid(**prov["grid"]).validate()
    except (KeyError, TypeError, ValueError) as err:
        raise StaleTablesError(f"refrigerant table file {path}: bad grid {prov.get('grid')!r} ({err}); {fix}") from err
    for key, shape in grid.shapes().items():
        a = arrays.get(key)
        if a is None or a.shape != shape or a.dtype != np.float64 or not np.all(np.isfinite(a)):
            got = "missing" if a is None else f"{a.dtype} {a.shape}"
            raise StaleTablesError(
                f"refrigerant table file {path}: {key} is {got}, the grid {asdict(grid)} "
                f"needs finite float64 {shape}; {fix}"
            )
    return prov, arrays


def load_tables_file(
    path: str, fluid: str = "R1234yf", superheat_k: float = 5.0, subcool_k: float = 5.0, grid: TableGrid = DEFAULT_GRID
) -> CycleTables:
    """The cycle tables of one configuration from a table file (no CoolProp import).

    Raises StaleTablesError if the file is unreadable, of another format, on another grid than
    ``grid``, or holds another (fluid, superheat, subcooling) configuration.
    """
    prov, arrays = read_tables_file(path)
    held = (prov.get("fluid"), prov.get("superheat_k"), prov.get("subcool_k"))
    if held != (fluid, float(superheat_k), float(subcool_k)):
        raise StaleTablesError(
            f"refrigerant table file {path} holds {held[0]} with superheat {held[1]} K and "
            f"subcooling {held[2]} K, not {fluid} with {float(superheat_k)} K and "
            f"{float(subcool_k)} K"
        )
    if prov["grid"] != asdict(grid):
        raise StaleTablesError(
            f"refrigerant table file {path}: grid {prov['grid']} differs from the plant's "
            f"{asdict(grid)}; regenerate it with `{REGENERATE_COMMAND}`"
        )
    source = (
        f"shipped file {os.path.basename(path)} (CoolProp {prov.get('coolprop_version')}, "
        f"generated {prov.get('date_utc')})"
    )
    return make_tables(fluid, superheat_k, subcool_k, grid, arrays, source)


def check_tables_file(path: str = SHIPPED_TABLES) -> dict:
    """Check a table file against the installed CoolProp: same version, values equal bit for bit to a fresh build.

    Imports CoolProp. Returns the provenance; raises StaleTablesError with what differs and the
    regeneration command otherwise (the test suite and ``tools/make_refrigerant_tables.py --check``).
    """
    import CoolProp

    prov, arrays = read_tables_file(path)
    fix = f"regenerate it with `{REGENERATE_COMMAND}`"
    if prov.get("coolprop_version") != CoolProp.__version__:
        raise StaleTablesError(
            f"refrigerant table file {path} was generated with CoolProp "
            f"{prov.get('coolprop_version')}, the installed CoolProp is {CoolProp.__version__}; "
            f"{fix}"
        )
    grid = TableGrid(**prov["grid"])
    fresh = tables_arrays(
        build_cycle_tables(prov["fluid"], float(prov["superheat_k"]), float(prov["subcool_k"]), *grid.build_args())
    )
    for key, ref in fresh.items():
        got = arrays[key]
        if not np.array_equal(got, ref):
            bad = np.flatnonzero(got.ravel() != ref.ravel())
            rel = float(np.max(np.abs(got.ravel()[bad] - ref.ravel()[bad]) / np.abs(ref.ravel()[bad])))
            raise StaleTablesError(
                f"refrigerant table file {path}: {key} differs from a fresh CoolProp "
                f"{CoolProp.__version__} build at {bad.size} of {ref.size} points "
                f"(largest relative difference {rel:.3g}); {fix}"
            )
    return prov


@functools.lru_cache(maxsize=8)
def cycle_tables(fluid: str = "R1234yf", superheat_k: float = 5.0, subcool_k: float = 5.0) -> CycleTables:
    """The plant's cycle tables on :data:`DEFAULT_GRID`: the shipped file if it holds them, else a CoolProp build.

    The shipped file (:data:`SHIPPED_TABLES`) is read without importing CoolProp (a few ms);
    for a configuration it does not hold, or if it is missing or stale, a warning is logged and
    :func:`build_cycle_tables` imports CoolProp and builds them (~2.5 s). Cached per argument set.
    """
    try:
        return load_tables_file(SHIPPED_TABLES, fluid, superheat_k, subcool_k, DEFAULT_GRID)
    except StaleTablesError as err:
        _LOG.warning("%s: building the tables with CoolProp instead (~2.5 s including its import)", err)
    return build_cycle_tables(fluid, float(superheat_k), float(subcool_k))
