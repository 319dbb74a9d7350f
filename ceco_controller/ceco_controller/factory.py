"""Building a strategy's controller core: the one constructor the simulator and the nodes call.

Imports no plant code (no CoolProp): ``mpc_node`` and ``baseline_node`` start
from here.
"""

from __future__ import annotations

import collections
import dataclasses

from ceco_core.acc_law import AccSettings
from ceco_core.cabin_comfort import ComfortParams, comfort_params_for
from ceco_core.recirc_law import RecircSettings
from ceco_core.scenario_types import Scenario

from . import model as cm
from .baseline import BaselineController
from .estimating_controller import with_measurements
from .nmpc import NmpcController
from .strategies import CONFIG_FILE_KEYS, StrategySettings, load_strategy_settings

__all__ = [
    "make_controller",
    "ControllerCache",
    "load_acc_settings",
    "write_acc_settings",
    "split_door_settings",
    "DOOR_FIELDS",
]


class ControllerCache:
    """NMPC controllers built once per process and reused, reset, by later runs (a benchmark worker's).

    Building an NMPC (transcribing its NLP, building or loading its solvers) costs 0.2-0.4 s, as much
    as all of a 600 s run's control steps. :meth:`nmpc` returns the controller built for the same
    settings, model and comfort parameters before, after :meth:`NmpcController.reset` (the key-on
    state: no plan, no warm start, no bias estimates, ``counters`` at zero), else builds one. A reset
    controller computes what a fresh one computes, bit for bit (``tests/test_sweep.py``).

    Args:
        max_size: controllers kept (least recently used dropped first).
    """

    def __init__(self, max_size: int = 16):
        if not (isinstance(max_size, int) and max_size >= 1):
            raise ValueError(f"ControllerCache.max_size must be an int >= 1, got {max_size!r}")
        self.max_size = max_size
        self._built: collections.OrderedDict[str, NmpcController] = collections.OrderedDict()
        self.hits = 0
        """Controllers reused."""
        self.builds = 0
        """Controllers built."""

    def nmpc(
        self,
        settings: StrategySettings,
        model_params: cm.ControlModelParams | None,
        comfort_params: ComfortParams,
    ) -> NmpcController:
        """A controller for these settings and parameters in its key-on state (reused or built)."""
        # the dataclasses' reprs hold every field (floats round-trip exactly): equal keys, equal controllers
        key = repr((settings, model_params, comfort_params))
        ctrl = self._built.get(key)
        if ctrl is not None:
            self._built.move_to_end(key)
            self.hits += 1
            ctrl.reset()
            return ctrl
        ctrl = NmpcController(settings, model_params=model_params, comfort_params=comfort_params)
        self.builds += 1
        self._built[key] = ctrl
        while len(self._built) > self.max_size:
            self._built.popitem(last=False)
        return ctrl


def load_acc_settings(path: str | None) -> dict:
    """The AccSettings fields of a baseline law file (``{}`` for None or '').

    Format: YAML with one key ``acc_law:`` mapping AccSettings field names to values, e.g.
    ``ceco_controller/config/baseline_pmv.yaml`` (the comfort-feedback law). ValueError naming an
    unknown top-level key, an unknown field or a value AccSettings.validate() rejects.
    """
    if not path:
        return {}

    from ceco_core import yamlio

    doc = yamlio.load_file(path)
    if not isinstance(doc, dict) or not isinstance(doc.get("acc_law"), dict):
        raise ValueError(f"{path}: a baseline law file needs a mapping 'acc_law:' of AccSettings fields")
    other = sorted(str(k) for k in doc if k not in CONFIG_FILE_KEYS)
    if other:  # (a misspelt or misplaced key was ignored without a word; common/strategies: a file the NMPC reads too)
        raise ValueError(
            f"{path}: unknown top-level key(s) {other}: a baseline law file has acc_law only "
            "(and common and strategies, the NMPC's, in a file both read)"
        )
    fields = dict(doc["acc_law"])
    _check_acc_fields(fields, f"{path}: ")
    return fields


def _check_acc_fields(fields: dict, where: str = "") -> None:
    """ValueError naming an unknown field of a baseline law, or a value AccSettings / RecircSettings refuse."""
    unknown = sorted(set(fields) - ({f.name for f in dataclasses.fields(AccSettings)} | set(DOOR_FIELDS)))
    if unknown:
        raise ValueError(f"{where}acc_law: unknown AccSettings or RecircSettings field(s) {unknown}")
    split_door_settings(fields)


def write_acc_settings(path, fields: dict, comment: str = "") -> str:
    """Write AccSettings / door fields as a baseline law file that :func:`load_acc_settings` reads; its path.

    The fields are checked as the reader checks them (ValueError naming a bad one) before anything is written;
    ``comment``: a first line ``# comment``.
    """
    from pathlib import Path

    import yaml

    _check_acc_fields(dict(fields))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    head = f"# {comment}\n" if comment else ""
    path.write_text(head + yaml.safe_dump({"acc_law": dict(fields)}, sort_keys=False), encoding="utf-8")
    return str(path.resolve())


DOOR_FIELDS = tuple(f.name for f in dataclasses.fields(RecircSettings))
"""The baseline's door settings (:class:`~ceco_core.recirc_law.RecircSettings`, ``door_*``) among its fields."""


def split_door_settings(fields: dict) -> tuple[AccSettings, RecircSettings]:
    """The validated ACC law and door settings of a baseline's fields (``door_*`` to the door, the rest to the law)."""
    door = {k: v for k, v in fields.items() if k in DOOR_FIELDS}
    acc = AccSettings(**{k: v for k, v in fields.items() if k not in DOOR_FIELDS})
    acc.validate()
    return acc, RecircSettings(**door).validate()


def make_controller(
    strategy: str,
    scenario: Scenario,
    control_period_s: float,
    horizon_steps: int,
    model_params: cm.ControlModelParams | None = None,
    overrides: dict | None = None,
    config_path: str | None = None,
    measurements: str = "full",
    estimator_settings=None,
    estimator_params=None,
    cache: ControllerCache | None = None,
):
    """Build the controller of a strategy for a scenario.

    NMPC settings: the controller file (``config_path``, default the package's
    ``config/controller.yaml``), then ``horizon_steps``/``control_period_s``, then ``overrides``.
    Baseline: ``config_path`` is an optional law file (:func:`load_acc_settings`), ``overrides`` are
    :class:`~ceco_core.acc_law.AccSettings` and door (:class:`~ceco_core.recirc_law.RecircSettings`, ``door_*``)
    fields applied after it; the door logic knows whether the scenario's car has a CO2 sensor.
    ``measurements``: 'full' (every modelled state read from the observation) or 'vehicle' (only the
    production sensors; the controller behind ``estimating_controller.EstimatingController``, with
    ``estimator_settings``/``estimator_params``, default the package's identified file).
    ``cache``: reuse an NMPC built before in this process (:class:`ControllerCache`).
    """
    ctrl: BaselineController | NmpcController
    if strategy == "baseline":
        # AccSettings fields: the law file (config_path, optional), then the overrides
        acc, door = split_door_settings({**load_acc_settings(config_path), **(overrides or {})})
        ctrl = BaselineController(
            acc,
            control_period_s=control_period_s,
            comfort_params=comfort_params_for(scenario),
            door=door,
            co2_sensor_fitted=scenario.air_quality.co2_sensor != "none",
            # the CO2-holding door's balance: the identified one of the control model, as the NMPC's door has it
            co2_model=(
                cm.co2_estimator_params(model_params if model_params is not None else cm.load_params())
                if door.door_mode == "co2_hold"
                else None
            ),
        )
    else:
        settings = load_strategy_settings(
            strategy, config_path, horizon_steps=horizon_steps, control_period_s=control_period_s, **(overrides or {})
        )
        comfort = comfort_params_for(scenario)
        if cache is not None:
            ctrl = cache.nmpc(settings, model_params, comfort)
        else:
            ctrl = NmpcController(settings, model_params=model_params, comfort_params=comfort)
        ctrl.co2_sensor_fitted = scenario.air_quality.co2_sensor != "none"
    return with_measurements(
        ctrl,
        measurements,
        control_period_s,
        model_params=model_params,
        params=estimator_params,
        settings=estimator_settings,
    )
