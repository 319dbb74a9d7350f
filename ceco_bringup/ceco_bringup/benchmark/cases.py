"""Benchmark test cases: named, versioned files (scenario + forecast uncertainty + seeds).

Format ``ceco-benchmark-case/1`` (YAML; docs/benchmark.md, "Test cases")::

    schema: ceco-benchmark-case/1
    name: udds-hot                  # unique; a bundled case's file is <name>.yaml
    version: 1                      # bumped on any change that changes results
    description: ...
    scenario: udds                  # bundled scenario name or YAML path (relative to this file)
    duration_s: null                # optional run length override [s]
    forecast_uncertainty: medium    # none | low | medium | high
    seeds: [0, 1, 2, 3, 4]          # exactly [0] for none; at least 5 distinct for the others
    control_period_s: null          # optional Ts [s] and Np overrides
    horizon_steps: null

The bundled cases live in ``ceco_bringup/data/benchmark/cases/`` (package data,
found through :mod:`importlib.resources`). :func:`load_case` validates every
field and raises :class:`CaseError` naming it. :meth:`Case.sha` fingerprints
the *resolved* case (the scenario's full mapping after the overrides, the
level's error-model parameters, the seeds, Ts, Np), so results state exactly
what they were computed on even if a bundled scenario file changes.

Pure Python; no ROS import.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
from collections.abc import Mapping
from importlib import resources
from pathlib import Path

import yaml

from ceco_core import yamlio
from ceco_core.contracts import NOISE_SEED_RANGE
from ceco_core.scenario_types import yaml_number_hint

__all__ = [
    "CASE_SCHEMA",
    "CaseError",
    "Case",
    "load_case",
    "case_from_dict",
    "list_cases",
    "DEFAULT_CASES",
    "QUICK_CASES",
    "MIN_UNCERTAIN_SEEDS",
]

CASE_SCHEMA = "ceco-benchmark-case/1"
"""Value of a case file's ``schema`` key."""

MIN_UNCERTAIN_SEEDS = 5
"""Fewest seeds a case with forecast uncertainty may have (issue 10)."""

DEFAULT_CASES = (
    "sc03-paper",
    "sc03-low",
    "sc03-medium",
    "sc03-high",
    "hotsoak-pulldown",
    "udds-hot",
    "hwfet-hot",
    "us06-hot",
    "mild-day",
    "hot-commute-1p",
    "hot-commute-4p",
    "hot-humid-4p",
    "tunnel",
    "sun-shade",
    "idle-traffic",
    "highway-to-city",
    "known-stop",
)
"""The cases of a full ``ceco benchmark`` run, in report order (the last five: previewable disturbances)."""

QUICK_CASES = ("sc03-paper", "us06-hot", "mild-day")
"""The three cases of ``ceco benchmark --quick`` (each 600 s; with the first of the case file's seeds only: 0 in
every bundled case)."""

_KEYS = {
    "schema",
    "name",
    "version",
    "description",
    "scenario",
    "duration_s",
    "forecast_uncertainty",
    "seeds",
    "control_period_s",
    "horizon_steps",
    "occupants",
    "baseline_door",
}
_REQUIRED = ("schema", "name", "version", "scenario", "forecast_uncertainty", "seeds")


class CaseError(ValueError):
    """An invalid case file; the message names the field."""


@dataclasses.dataclass(frozen=True)
class Case:
    """A validated test case (build with :func:`load_case`)."""

    name: str
    """Case name, e.g. ``sc03-paper``."""
    version: int
    """Case version (>= 1)."""
    description: str
    """Free text."""
    scenario: str
    """The scenario as written: a bundled name or a YAML path."""
    forecast_uncertainty: str
    """Forecast-uncertainty level (``ceco_v2x_preview.forecast_error.LEVELS``)."""
    seeds: tuple
    """Preview-error seeds."""
    duration_s: float | None = None
    """Run length override [s]; None: the scenario's."""
    control_period_s: float | None = None
    """Control period override Ts [s]; None: the scenario's."""
    horizon_steps: int | None = None
    """Horizon override Np [steps]; None: the scenario's."""
    source: str = ""
    """Where the case was loaded from (bundled name or file path)."""
    base_dir: str | None = None
    """Directory relative scenario paths are resolved against (None for a bundled case)."""
    occupants: int | None = None
    """People in the car, overriding the scenario's (1..5); None: the scenario's."""
    baseline_door: tuple = ()
    """``((field, value), ...)`` of :class:`ceco_core.recirc_law.RecircSettings` given to every baseline of the case
    (e.g. the production door logic, ``door_mode: auto``); empty: the baselines leave the door to the plant."""

    @property
    def preview(self) -> str:
        """The preview quality of its strategies' runs (``parse_quality`` text): ``perfect`` or ``uncertain:LEVEL``."""
        return 'perfect' if self.forecast_uncertainty == 'none' else f'uncertain:{self.forecast_uncertainty}'

    def strategy_overrides(self, strategy: str) -> dict:
        """The case's own settings for a run of ``strategy``: :attr:`baseline_door` for a baseline, none otherwise."""
        return dict(self.baseline_door) if strategy == 'baseline' else {}

    def scenario_path(self) -> str:
        """The scenario argument for ``load_scenario`` (a relative YAML path resolved against the case file)."""
        s = self.scenario
        if self.base_dir and s.endswith((".yaml", ".yml")) and not Path(s).is_absolute():
            return str(Path(self.base_dir) / s)
        return s

    def load_scenario(self):
        """The :class:`~ceco_v2x_preview.scenario.Scenario` of the case, run length override applied."""
        from ceco_v2x_preview.scenario import load_scenario, scenario_from_dict

        sc = load_scenario(self.scenario_path())
        if self.duration_s is None and self.occupants is None:
            return sc
        d = self.scenario_dict()
        return scenario_from_dict(d, source=sc.source)

    def scenario_dict(self) -> dict:
        """The scenario as a mapping (``scenario_from_dict`` form) with the case's overrides applied."""
        from ceco_bringup.sweep import scenario_dict
        from ceco_v2x_preview.scenario import load_scenario

        d = scenario_dict(load_scenario(self.scenario_path()))
        if self.duration_s is not None:
            d["duration_s"] = float(self.duration_s)
        if self.occupants is not None:
            d["occupants"] = int(self.occupants)
        return d

    def write_scenario(self, path: str | os.PathLike) -> Path:
        """Write :meth:`scenario_dict` as a scenario YAML file (what the benchmark simulates); return its path.

        A CSV drive cycle is copied beside the file, which points at the copy (``provenance.copy_drive_cycle``).
        """
        from ceco_bringup.provenance import copy_drive_cycle

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        data, note = copy_drive_cycle(self.scenario_dict(), Path.cwd(), path.parent)  # (its path: as loaded)
        header = f"# the scenario of benchmark case {self.name} v{self.version} (sha {self.sha()}), overrides applied"
        header += f"; {note}\n" if note else "\n"
        path.write_text(header + yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
        return path

    def resolved(self) -> dict:
        """Everything that determines the case's runs, as plain data (what :meth:`sha` hashes)."""
        from ceco_v2x_preview.forecast_error import level_models

        levels = {q: dataclasses.asdict(m) for q, m in level_models(self.forecast_uncertainty).items()}
        return {
            "name": self.name,
            "version": self.version,
            "scenario": self.scenario_dict(),
            "forecast_uncertainty": self.forecast_uncertainty,
            "error_models": levels,
            "seeds": list(self.seeds),
            "control_period_s": self.control_period_s,
            "horizon_steps": self.horizon_steps,
            **({"baseline_door": dict(self.baseline_door)} if self.baseline_door else {}),
        }

    def sha(self) -> str:
        """SHA-256 (16 hex digits) of :meth:`resolved` as canonical JSON."""
        text = json.dumps(self.resolved(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def _data_dir():
    return resources.files("ceco_bringup").joinpath("data", "benchmark", "cases")


def list_cases() -> list[str]:
    """Names of the bundled cases, sorted."""
    return sorted(p.name[:-5] for p in _data_dir().iterdir() if p.name.endswith(".yaml"))


def _number(field: str, value, *, integer: bool = False, low_open: float | None = None):
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or (integer and not isinstance(value, int)):
        what = "an integer" if integer else "a number"
        raise CaseError(f"{field}: must be {what}, got {value!r}{yaml_number_hint(value)}")
    if not math.isfinite(value) or (low_open is not None and not value > low_open):
        raise CaseError(f"{field}: must be finite and > {low_open}, got {value!r}")
    return int(value) if integer else float(value)


def case_from_dict(
    data: Mapping, *, source: str = "", base_dir: str | os.PathLike | None = None, expected_name: str | None = None
) -> Case:
    """Validate a parsed case mapping (CaseError naming the field) and build a :class:`Case`."""
    from ceco_v2x_preview.forecast_error import LEVELS

    if not isinstance(data, Mapping):
        raise CaseError(f"case: top level must be a mapping, got {type(data).__name__}")
    unknown = sorted(set(data) - _KEYS)
    if unknown:
        raise CaseError(f"{unknown[0]}: unknown case key (allowed: {sorted(_KEYS)})")
    for key in _REQUIRED:
        if key not in data or data[key] is None:
            raise CaseError(f"{key}: missing")
    if data["schema"] != CASE_SCHEMA:
        raise CaseError(f"schema: must be {CASE_SCHEMA!r}, got {data['schema']!r}")
    name = data["name"]
    if not isinstance(name, str) or not name.strip() or any(c.isspace() for c in name) or "/" in name:
        raise CaseError(f"name: must be a non-empty string without spaces or '/', got {name!r}")
    if expected_name is not None and name != expected_name:
        raise CaseError(f"name: {name!r} differs from the file name {expected_name!r}")
    version = _number("version", data["version"], integer=True, low_open=0)
    description = data.get("description") or ""
    if not isinstance(description, str):
        raise CaseError("description: must be a string")
    scenario = data["scenario"]
    if not isinstance(scenario, str) or not scenario.strip():
        raise CaseError(f"scenario: must be a bundled scenario name or a YAML path, got {scenario!r}")
    level = data["forecast_uncertainty"]
    if level not in LEVELS:
        raise CaseError(f"forecast_uncertainty: must be one of {list(LEVELS)}, got {level!r}")
    seeds = data["seeds"]
    lo, hi = NOISE_SEED_RANGE  # preview_node's: a run over DDS takes the seed as its parameter
    if (
        not isinstance(seeds, (list, tuple))
        or not seeds
        or not all(isinstance(s, int) and not isinstance(s, bool) and lo <= s <= hi for s in seeds)
    ):
        raise CaseError(f"seeds: must be a non-empty list of integers in {lo}..{hi}, got {seeds!r}")
    if len(set(seeds)) != len(seeds):
        raise CaseError(f"seeds: must be distinct, got {list(seeds)}")
    if level == "none" and list(seeds) != [0]:
        raise CaseError("seeds: must be [0] for forecast_uncertainty none (perfect previews are deterministic)")
    if level != "none" and len(seeds) < MIN_UNCERTAIN_SEEDS:
        raise CaseError(
            f"seeds: a case with forecast uncertainty needs at least {MIN_UNCERTAIN_SEEDS} seeds, got {len(seeds)}"
        )
    duration = _number("duration_s", data.get("duration_s"), low_open=0.0)
    ts = _number("control_period_s", data.get("control_period_s"), low_open=0.0)
    n_p = _number("horizon_steps", data.get("horizon_steps"), integer=True, low_open=0)
    occupants = _number("occupants", data.get("occupants"), integer=True, low_open=0)
    door = data.get("baseline_door") or {}
    if not isinstance(door, Mapping):
        raise CaseError(f"baseline_door: must be a mapping of RecircSettings fields, got {door!r}")
    from ceco_core.recirc_law import RecircSettings

    try:
        RecircSettings(**door).validate()
    except (TypeError, ValueError) as exc:
        raise CaseError(f"baseline_door: {exc}") from None
    case = Case(
        name=name,
        version=version,
        description=description.strip(),
        scenario=scenario.strip(),
        forecast_uncertainty=level,
        seeds=tuple(int(s) for s in seeds),
        duration_s=duration,
        control_period_s=ts,
        horizon_steps=n_p,
        source=source,
        base_dir=None if base_dir is None else str(base_dir),
        occupants=None if occupants is None else int(occupants),
        baseline_door=tuple(sorted(door.items())),
    )
    try:
        case.load_scenario()
    except (ValueError, OSError) as exc:
        raise CaseError(f"scenario: {exc}") from None
    return case


def load_case(name_or_path: str | os.PathLike) -> Case:
    """Load a bundled case by name (:func:`list_cases`) or a case file by path."""
    text_name = str(name_or_path)
    if text_name in list_cases():
        with _data_dir().joinpath(text_name + ".yaml").open("r", encoding="utf-8") as fh:
            text = fh.read()
        source, base_dir, expected = text_name, None, text_name
    else:
        path = Path(text_name).expanduser()
        if not path.is_file():
            raise CaseError(f"case: unknown case {text_name!r}: use one of {list_cases()} or a case YAML path")
        text = path.read_text(encoding="utf-8")
        source, base_dir, expected = str(path), path.parent, None
    try:
        data = yamlio.safe_load(text)
    except yaml.YAMLError as exc:
        raise CaseError(f"case: {source}: not valid YAML{yamlio.error_text(exc)}") from None
    return case_from_dict(data, source=source, base_dir=base_dir, expected_name=expected)
