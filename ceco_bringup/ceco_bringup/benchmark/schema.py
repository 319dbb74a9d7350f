"""The results format ``ceco-benchmark/2`` and its validator.

``DIR/results.json`` of ``ceco benchmark`` (docs/benchmark.md, "Results format").
Two layers:

1. the JSON Schema ``ceco_bringup/data/benchmark/results.schema.json`` (Draft
   2020-12; usable from any language) for structure and types, the range of each KPI of
   :data:`KPI_RANGES` (``minimum``/``maximum`` of ``$defs/kpis``, :func:`kpi_range_properties`: the
   file is checked against the table by the tests) and at least one case (``minItems``);
2. :func:`validate_results` adds what a schema cannot express: runs are unique per
   (controller, seed); ``seed`` is null exactly for the seed-invariant baselines and
   one of the case's seeds otherwise; every null KPI of a finished run is explained
   in ``kpi_notes``; no energy is negative and ``energy_kwh`` is the sum of its parts (compressor + blower +
   condenser fan); a ``failed`` or ``error`` run says why in ``error``; each front member is
   a run of its family with status ``ok`` and the front's values, and the ``efficient`` flags
   recompute; every ``matched`` value recomputes from the fronts and the ``ok`` runs (:mod:`.front`,
   tolerance 1e-9): a failed run (its controller did not control it, ``ceco_core.run_status``) is
   never matched; the strongest family (per level and per controller) and ``headroom_captured``
   recompute from the fronts and the oracle's points; each oracle front recomputes from its solved
   points (one per level, >= 4 levels); every number is finite (JSON has no NaN; Python's ``json`` reads
   ``NaN`` and ``Infinity``); a document holds each case once; every seed-dependent controller has a run
   for each of the case's seeds; every strategy ``settings.strategies`` lists has a run (of any status) in
   every case.

Pure Python (jsonschema); no ROS import.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any

from ceco_core import yamlio

from . import front as fr

__all__ = [
    "SCHEMA",
    "BENCHMARK_VERSION",
    "REQUIRED_KPIS",
    "KPI_RANGES",
    "kpi_range_properties",
    "KINDS",
    "SEED_INVARIANT_KINDS",
    "FAMILIES",
    "DOOR_FAMILIES",
    "DOOR_SHARES_PCT",
    "DOOR_VARIANTS",
    "DOOR_CO2_HOLD",
    "DOOR_FAMILY_BASES",
    "door_family",
    "ORACLE_STATUSES",
    "oracle_member",
    "oracle_point_kpis",
    "load_json_schema",
    "read_results",
    "validate_results",
    "check_results",
    "ResultsError",
]

SCHEMA = "ceco-benchmark/2"
"""Value of results.json's ``schema`` key."""

BENCHMARK_VERSION = 3
"""Version of the benchmark's definition (KPIs, baseline families, levels, matched-comfort method).
2: the tuned and comfort-feedback families, the strongest family, the oracle's slots. 3: a run or family
member at the discomfort ceiling (PMV at the +-3 clip for the whole run) is not matched and anchors no match;
a run's fallback steps are the plant's AcPower.fallback alone (one rejected command counted two before);
an external controller's cells are its name, command and directory. Results of another version do not
compare."""

REQUIRED_KPIS = (
    "energy_kwh",
    "discomfort_pmvh",
    "i_pmv",
    "i_pmv_clipped",
    "otc_violation_pct",
    "draught_pct",
    "actuator_travel",
    "peak_comp_kw",
    "time_ratio_mean",
    "time_ratio_max",
    "fallback_steps",
)
"""KPIs every run reports (a number or null with a note)."""

KPI_RANGES = {
    "otc_violation_pct": (0.0, 100.0),
    "draught_pct": (0.0, 100.0),
    "fog_risk_pct": (0.0, 100.0),
    "co2_above_limit_pct": (0.0, 100.0),
    "iso7730_invalid_pct": (0.0, 100.0),
    "air_quality_met": (0.0, 1.0),
}
"""KPI -> (lowest, highest) value it can take by its definition (``ceco_core.kpis``): the shares of the run's
samples [%] (outside the scenario's PMV bounds, draught rating above 20 %, fog margin below 0, CO2 above the
limit, outside ISO 7730's validity ranges) and ``air_quality_met`` (0 or 1). The JSON Schema holds them
(:func:`kpi_range_properties`); null (a KPI that does not exist, explained in ``kpi_notes``) is in range."""


def kpi_range_properties() -> dict:
    """``properties`` of the JSON Schema's ``$defs/kpis``: each KPI of :data:`KPI_RANGES` a number in its range or null.

    The shipped ``results.schema.json`` holds exactly this (tests/test_benchmark_schema.py), so the ranges a
    user's JSON Schema validator checks are the table's.
    """
    return {k: {"type": ["number", "null"], "minimum": lo, "maximum": hi} for k, (lo, hi) in KPI_RANGES.items()}


FAMILIES = {
    "plain": "baseline",
    "allowance": "baseline-allowance",
    "tuned": "baseline-tuned",
    "tuned-allowance": "baseline-tuned-allowance",
    "pmv": "baseline-pmv",
    "pmv-allowance": "baseline-pmv-allowance",
}
"""Front name -> the kind of its members: the production-gains families (plain, allowance: the paper's
comparison), the production law with tuned gains, the comfort-feedback (PMV) law with tuned gains."""

DOOR_SHARES_PCT = (0, 50, 80, 100)
"""Recirculated shares of the fixed-door families [%] (issue 21): fresh air, half, the plant's default 0.8 of
before issue 21, full recirculation."""

DOOR_CO2_HOLD = "co2"
"""Door variant of the families whose door is the CO2-holding door of ``ceco-pmv-aq`` (``door_mode: co2_hold``,
``ceco_core.co2_door``): the strategy's door behind the baseline's law."""

DOOR_VARIANTS = (*(str(p) for p in DOOR_SHARES_PCT), DOOR_CO2_HOLD)
"""The door variants of the door families: each fixed share [%], then the CO2-holding door."""

DOOR_FAMILY_BASES = ("tuned", "pmv")
"""The families run with each door of :data:`DOOR_VARIANTS` on the cases whose baselines drive the door (a
case's ``baseline_door``): the strongest laws, the tuned temperature PI and the tuned PMV PI."""


def door_family(base: str, variant) -> str:
    """Front name of ``base`` (:data:`DOOR_FAMILY_BASES`) with a door of :data:`DOOR_VARIANTS`: ``tuned-door80``.

    ``variant`` a share [%] or ``co2`` (``pmv-doorco2``).
    """
    return f"{base}-door{variant}"


DOOR_FAMILIES = {door_family(base, v): f"{FAMILIES[base]}-door{v}" for base in DOOR_FAMILY_BASES for v in DOOR_VARIANTS}
"""Front name -> kind of the door families (``tuned-door80`` -> ``baseline-tuned-door80``, ``pmv-doorco2`` ->
``baseline-pmv-doorco2``); on the other cases their fronts are empty."""

FAMILIES = {**FAMILIES, **DOOR_FAMILIES}

KINDS = ("strategy", *FAMILIES.values(), "compensated", "compensated-allowance", "external")
"""Kinds of controller in a case's runs."""

SEED_INVARIANT_KINDS = (*FAMILIES.values(), "compensated", "compensated-allowance")
"""Kinds that use no preview: run once per case, ``seed`` null."""

ORACLE_STATUSES = ("ok", "unavailable", "skipped", "error")
"""A case's ``oracle.status``: fronts given, the oracle module absent, ``--no-oracle``, or every level failed."""

_TOL = 1e-9


class ResultsError(ValueError):
    """results.json does not conform to ceco-benchmark/2; the message lists the problems."""


def load_json_schema() -> dict:
    """The JSON Schema document of ceco-benchmark/2."""
    text = (
        resources.files("ceco_bringup").joinpath("data", "benchmark", "results.schema.json").read_text(encoding="utf-8")
    )
    return json.loads(text)


def read_results(path: str) -> Any:
    """The parsed JSON document in file ``path``; ValueError (one line naming the file) when it cannot be read."""
    if not str(path).strip():
        raise ValueError("--validate: the path is empty: give the results.json to check")
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except UnicodeDecodeError as exc:
        raise ValueError(
            f"{path}: not a UTF-8 text file ({exc.reason} at byte {exc.start}): "
            "give a results.json ceco benchmark wrote"
        ) from None
    except json.JSONDecodeError as exc:
        raise ValueError(
            f"{path}: not a JSON file ({exc.msg} at line {exc.lineno}, column {exc.colno}): "
            "give a results.json ceco benchmark wrote"
        ) from None
    except OSError as exc:
        raise ValueError(f"{path}: {yamlio.os_error_words(exc, 'the results.json in it')}") from None


def _same(a, b) -> bool:
    if a is None or b is None:
        return a is None and b is None
    if isinstance(a, bool) or isinstance(b, bool):
        return a is b
    return abs(float(a) - float(b)) <= _TOL * max(1.0, abs(float(a)), abs(float(b)))


def _schema_errors(doc: Any) -> list[str]:
    import jsonschema

    validator = jsonschema.Draft202012Validator(load_json_schema())
    out = []
    for err in sorted(validator.iter_errors(doc), key=lambda e: list(e.absolute_path)):
        where = "/".join(str(p) for p in err.absolute_path) or "(top level)"
        out.append(f"{where}: {err.message}")
    return out


def _check_match(where: str, stored: Mapping, expect: Mapping) -> list[str]:
    out = []
    for key in ("energy_saving_pct", "discomfort_reduction_pct", "dominated", "n_seeds"):
        if not _same(stored.get(key), expect[key]):
            out.append(f"{where}.{key}: {stored.get(key)!r} does not recompute ({expect[key]!r})")
    for key in ("energy_saving_pct", "discomfort_reduction_pct", "dominated"):
        a, b = stored.get("seeds", {}).get(key), expect["seeds"][key]
        if not isinstance(a, list) or len(a) != len(b) or not all(_same(x, y) for x, y in zip(a, b)):
            out.append(f"{where}.seeds.{key}: {a!r} does not recompute ({b!r})")
    return out


ENERGY_PARTS = ("energy_comp_kwh", "energy_blower_kwh", "energy_fan_kwh")
"""The parts of a run's ``energy_kwh``: compressor + blower + condenser fan [kWh] (``ceco_core.kpis``)."""


def _check_energy(where: str, kpis: Mapping) -> list[str]:
    """A run's energies and time ratios: none negative, and ``energy_kwh`` the sum of :data:`ENERGY_PARTS`."""
    out = [
        f"{where}: KPI {k} is {v!r}: an energy is never negative"
        for k, v in kpis.items()
        if k.startswith("energy_") and k.endswith("_kwh") and isinstance(v, (int, float)) and v < 0
    ]
    out += [  # (a command is timed from its state on: external.step_times_from_bag)
        f"{where}: KPI {k} is {kpis[k]!r}: a time ratio is never negative"
        for k in ("time_ratio_mean", "time_ratio_max")
        if isinstance(kpis.get(k), (int, float)) and kpis[k] < 0
    ]
    total, parts = kpis.get("energy_kwh"), [kpis.get(k) for k in ENERGY_PARTS]
    if total is not None and all(v is not None for v in parts) and not _same(total, sum(parts)):
        out.append(
            f"{where}: KPI energy_kwh {total!r} is not {' + '.join(ENERGY_PARTS)} ({sum(parts)!r}): "
            "energy is compressor + blower + condenser fan"
        )
    return out


def _check_case(i: int, case: Mapping, settings: Mapping) -> list[str]:
    out: list[str] = []
    tag = f"cases/{i} ({case.get('case')})"
    seeds = set(case.get("seeds", []))
    ok_runs: dict = {}
    seen = set()
    for j, run in enumerate(case.get("runs", [])):
        where = f"{tag}/runs/{j} ({run['controller']}, seed {run['seed']})"
        key = (run["controller"], run["seed"])
        if key in seen:
            out.append(f"{where}: duplicate run")
        seen.add(key)
        invariant = run["kind"] in SEED_INVARIANT_KINDS
        if invariant and run["seed"] is not None:
            out.append(f"{where}: seed must be null for the seed-invariant kind {run['kind']!r}")
        if not invariant and run["seed"] not in seeds:
            out.append(f"{where}: seed must be one of the case's seeds {sorted(seeds)}")
        if run["status"] != "ok" and not run.get("error"):
            out.append(f"{where}: status {run['status']} without an error message")
        if run["status"] == "error":
            continue
        for k, v in run["kpis"].items():  # (their ranges, KPI_RANGES: the JSON Schema's)
            if v is None and k not in run["kpi_notes"]:
                out.append(f"{where}: KPI {k} is null without a note in kpi_notes")
        out += _check_energy(where, run["kpis"])
        if run["status"] == "ok":  # a failed run keeps its KPIs but is never on a front nor matched
            ok_runs.setdefault(run["controller"], []).append(run)
    out += _check_seed_coverage(tag, case)
    fx, ex = settings["front_axis"], settings["energy_axis"]
    fronts = {}
    ceiling = fr.saturation_ceiling((r["kpis"] for rs in ok_runs.values() for r in rs), fx)
    for family, kind in FAMILIES.items():
        members = case["fronts"].get(family, [])
        pts = []
        for j, p in enumerate(members):
            where = f"{tag}/fronts/{family}/{j} ({p['controller']})"
            runs = ok_runs.get(p["controller"], [])
            if len(runs) != 1 or runs[0]["kind"] != kind:
                out.append(f"{where}: not a run of kind {kind!r} with status ok")
                continue
            k = runs[0]["kpis"]
            if not (_same(p["discomfort"], k.get(fx)) and _same(p["energy"], k.get(ex))):
                out.append(f"{where}: values differ from the run's {fx}/{ex}")
            pts.append((p["controller"], p["discomfort"], p["energy"]))
        if not pts:
            fronts[family] = None
            continue
        front = fr.build_front(pts, ceiling=ceiling)
        fronts[family] = front
        eff = {p.name: p.efficient for p in front.points}
        for j, p in enumerate(members):
            if p["controller"] in eff and eff[p["controller"]] != p["efficient"]:
                out.append(f"{tag}/fronts/{family}/{j} ({p['controller']}): efficient flag does not recompute")
    env = fr.Envelope.of(fronts) if any(f is not None for f in fronts.values()) else None
    out += _check_strongest(tag, case["strongest"], env, case["oracle"]["levels"])
    bounds, problems = _oracle_bounds(tag, case["oracle"])
    out += problems
    for name, entry in case.get("matched", {}).items():
        runs = ok_runs.get(name)
        where = f"{tag}/matched/{name}"
        if not runs:
            out.append(f"{where}: no run of this controller with status ok (a failed run is never matched)")
            continue
        if runs[0]["kind"] in FAMILIES.values():
            out.append(f"{where}: a family member is not matched against its own front")
            continue
        runs = sorted(runs, key=lambda r: -1 if r["seed"] is None else r["seed"])
        pts = [(r["kpis"].get(fx), r["kpis"].get(ex)) for r in runs]
        if any(a is None or b is None for a, b in pts):
            out.append(f"{where}: a run has no {fx} or {ex}")
            continue
        for family, sub in (("plain", entry), ("allowance", entry.get("allowance"))):
            if fronts.get(family) is None:
                if sub is not None and family != "plain":
                    out.append(f"{where}.{family}: given, but the {family} front is empty")
                elif family == "plain":
                    out.append(f"{where}: the plain front is empty")
                continue
            if sub is None:
                out.append(f"{where}.{family}: missing although the {family} front exists")
                continue
            out += _check_match(
                where if family == "plain" else f"{where}.{family}", sub, fr.match_seeds(fronts[family], pts)
            )
        if env is None:
            continue
        out += _check_match(f"{where}.strongest", entry["strongest"], fr.match_seeds(env, pts))
        fam = env.family_at(sum(d for d, _ in pts) / len(pts))
        if entry["strongest"].get("family") != fam:
            out.append(f"{where}.strongest.family: {entry['strongest'].get('family')!r} does not recompute ({fam!r})")
        if not bounds:
            if entry.get("headroom") is not None:
                out.append(f"{where}.headroom: given without an oracle front")
            continue
        expect = fr.headroom_seeds(env, bounds, [(r["seed"], d, e) for r, (d, e) in zip(runs, pts)])
        got = entry.get("headroom")
        if got is None:
            out.append(f"{where}.headroom: missing although the oracle gave a front")
            continue
        for key in ("headroom_captured", "saving_pct", "bound_saving_pct", "strongest", "n_seeds"):
            a, b = got.get(key), expect[key]
            if not (a == b if key == "strongest" else _same(a, b)):
                out.append(f"{where}.headroom.{key}: {a!r} does not recompute ({b!r})")
        for key in ("headroom_captured", "saving_pct", "bound_saving_pct"):
            a, b = got.get("seeds", {}).get(key), expect["seeds"][key]
            if not isinstance(a, list) or len(a) != len(b) or not all(_same(x, y) for x, y in zip(a, b)):
                out.append(f"{where}.headroom.seeds.{key}: {a!r} does not recompute ({b!r})")
        if entry.get("by_phase") is not None:  # absent from documents written before it
            fam_kpis = {n: rs[0]["kpis"] for n, rs in ok_runs.items() if rs[0]["kind"] in FAMILIES.values()}
            want = fr.by_phase(
                env,
                bounds,
                [(r["seed"], d, r["kpis"]) for r, (d, _) in zip(runs, pts)],
                fam_kpis,
                oracle_point_kpis(case["oracle"]),
            )
            have = entry["by_phase"]
            for who in ("controller", "strongest", "bound"):
                for key, b in want[who].items():
                    if not _same(have.get(who, {}).get(key), b):
                        out.append(f"{where}.by_phase.{who}.{key}: does not recompute ({b!r})")
            if have.get("families") != want["families"] or have.get("n_seeds") != want["n_seeds"]:
                out.append(f"{where}.by_phase.families/n_seeds: do not recompute")
    return out


def _check_seed_coverage(tag: str, case: Mapping) -> list[str]:
    """Every seed-dependent controller of the case has a run (of any status) for each of the case's seeds.

    A seed without its run would leave a controller's seed mean over fewer seeds than the case lists. A case
    whose runs are all seed-invariant (``--strategy none``) has nothing to cover.
    """
    seeds = set(case["seeds"])
    have: dict = {}
    for run in case["runs"]:
        if run["kind"] not in SEED_INVARIANT_KINDS:
            have.setdefault(run["controller"], set()).add(run["seed"])
    return [
        f"{tag}: {name} has no run for seed(s) {sorted(seeds - got)} of the case's seeds {sorted(seeds)}"
        for name, got in have.items()
        if seeds - got
    ]


def _check_listed(tag: str, case: Mapping, names) -> list[str]:
    """Every controller of ``names`` (``settings.strategies``: the strategies the document compares) has a run.

    ``ceco benchmark`` runs each of them on every case and records a run that could not be made with status
    ``error``; a listed strategy without any run in a case was dropped, not compared. Only the strategies are
    listed by name (the families' members and the compensated laws are not): nothing else is checked here.
    """
    have = {run["controller"] for run in case["runs"]}
    return [
        f"{tag}: controller {name!r} has no run (settings.strategies lists it)" for name in names if name not in have
    ]


def _non_finite(node: Any, where: str = "") -> list[str]:
    """Where ``node`` (a parsed JSON document) holds NaN or +-Infinity, one line each."""
    if isinstance(node, float):
        return [] if math.isfinite(node) else [f"{where or '(top level)'}: {node!r} is not a finite number"]
    if isinstance(node, Mapping):
        items: Any = node.items()
    elif isinstance(node, list):
        items = enumerate(node)
    else:
        return []
    out = []
    for key, value in items:
        out += _non_finite(value, f"{where}/{key}" if where else str(key))
    return out


def _check_strongest(tag: str, entry: Mapping, env, levels) -> list[str]:
    """The case's ``strongest`` recomputes from the fronts at the oracle's levels."""
    if env is None:
        return [] if not entry["families"] else [f"{tag}/strongest: families given without any front"]
    expect = {"families": [n for n, _ in env.fronts], **fr.strongest_by_level(env, levels)}
    out = []
    if entry["families"] != expect["families"] or entry["family"] != expect["family"]:
        out.append(f"{tag}/strongest: families/family do not recompute ({expect['families']}, {expect['family']!r})")
    got, want = entry["levels"], expect["levels"]
    if len(got) != len(want) or any(
        a["family"] != b["family"] or not _same(a["discomfort"], b["discomfort"]) or not _same(a["energy"], b["energy"])
        for a, b in zip(got, want)
    ):
        out.append(f"{tag}/strongest/levels: do not recompute at the oracle's levels")
    return out


def oracle_member(level: float) -> str:
    """The name of the oracle's point at ``level`` on its front (``oracle@<level>``)."""
    return f"oracle@{float(level):.6g}"


def oracle_point_kpis(oracle: Mapping) -> dict:
    """``{seed: {front member name: kpis}}`` of a case's ``oracle`` entry (the solved points of every seed)."""
    return {
        f["seed"]: {oracle_member(p["level"]): p["kpis"] for p in f["points"] if p.get("kpis")}
        for f in oracle.get("fronts", [])
    }


def _oracle_bounds(tag: str, oracle: Mapping) -> tuple[dict, list[str]]:
    """{seed: Front} of an 'ok' oracle entry, and the problems of its fronts (each recomputes from its points)."""
    out: list[str] = []
    bounds = {}
    if oracle["status"] != "ok":
        if oracle["fronts"]:
            out.append(f"{tag}/oracle: status {oracle['status']!r} with fronts")
        return bounds, out
    if not oracle["levels"] or len(oracle["levels"]) < 4:
        out.append(f"{tag}/oracle/levels: at least 4 levels, got {len(oracle['levels'])}")
    for j, f in enumerate(oracle["fronts"]):
        where = f"{tag}/oracle/fronts/{j} (seed {f['seed']})"
        if len(f["points"]) != len(oracle["levels"]) or any(
            not _same(p["level"], x) for p, x in zip(f["points"], oracle["levels"])
        ):
            out.append(f"{where}: one point per level, in order")
        solved = [
            (oracle_member(p["level"]), p["kpis"]["discomfort_pmvh"], p["kpis"]["energy_kwh"])
            for p in f["points"]
            if p["kpis"]
        ]
        if f["status"] != "ok" or not solved:
            if f["front"]:
                out.append(f"{where}: a front without solved points")
            continue
        front = fr.build_front(solved)
        want = [(p.name, p.discomfort, p.energy, p.efficient) for p in front.points]
        got = [(p["controller"], p["discomfort"], p["energy"], p["efficient"]) for p in f["front"]]
        if len(want) != len(got) or any(
            a[0] != b[0] or not _same(a[1], b[1]) or not _same(a[2], b[2]) or a[3] != b[3] for a, b in zip(got, want)
        ):
            out.append(f"{where}: the front does not recompute from its points")
        bounds[f["seed"]] = front
    return bounds, out


def check_results(doc: Any) -> list[str]:
    """All problems of a parsed results document (empty list: valid ceco-benchmark/2)."""
    errors = _schema_errors(doc) or _non_finite(doc)  # nothing recomputes from NaN: stop at either
    if errors:
        return errors
    out: list[str] = []  # (at least one case: the JSON Schema's minItems)
    listed = doc["settings"].get("strategies", [])  # not required by the JSON Schema: nothing listed without it
    if not isinstance(listed, list) or not all(isinstance(n, str) and n for n in listed):
        out.append(f"settings/strategies: must be a list of controller names, got {listed!r}")
        listed = []
    first: dict = {}
    for i, case in enumerate(doc["cases"]):
        j = first.setdefault(case["case"], i)
        if j != i:
            out.append(f"cases/{i} ({case['case']}): duplicate case (also cases/{j})")
        out += _check_case(i, case, doc["settings"])
        out += _check_listed(f"cases/{i} ({case['case']})", case, listed)
    return out


def validate_results(doc: Any) -> None:
    """Raise :class:`ResultsError` listing every problem of ``doc`` (see :func:`check_results`)."""
    errors = check_results(doc)
    if errors:
        raise ResultsError(f"{len(errors)} problem(s) in the benchmark results:\n  " + "\n  ".join(errors))
