"""The results format ceco-benchmark/2 (JSON Schema + semantic checks) on a hand-made document."""

import copy
import json
import math
from pathlib import Path

import jsonschema
import pytest

from ceco_bringup.benchmark import cli as bench_cli
from ceco_bringup.benchmark import front as fr
from ceco_bringup.benchmark import runner
from ceco_bringup.benchmark import schema as bs


def _kpis(d, e, **extra):
    k = {key: 0.0 for key in bs.REQUIRED_KPIS}
    k.update(discomfort_pmvh=d, energy_kwh=e, draught_pct=None, **extra)
    return k


def _run(controller, kind, seed, d, e, setpoint=None):
    return {
        "controller": controller,
        "kind": kind,
        "seed": seed,
        "setpoint_c": setpoint,
        "source": "simulator",
        "status": "ok",
        "error": "",
        "kpis": _kpis(d, e),
        "kpi_notes": {"draught_pct": "run has no dr_pct column"},
    }


FAMILY_POINTS = {
    "plain": {"baseline@24.0": (0.06, 0.40), "baseline@25.0": (0.04, 0.37), "baseline@26.0": (0.05, 0.33)},
    "allowance": {"baseline-allowance@25.0": (0.07, 0.33), "baseline-allowance@26.0": (0.09, 0.29)},
    "tuned": {"baseline-tuned@25.0": (0.04, 0.35), "baseline-tuned@26.0": (0.06, 0.31)},
    "tuned-allowance": {"baseline-tuned-allowance@25.0": (0.07, 0.31)},
    "pmv": {"baseline-pmv@+0.00": (0.045, 0.36), "baseline-pmv@+0.40": (0.08, 0.29)},
    "pmv-allowance": {},
}
LEVELS = [0.04, 0.05, 0.06, 0.08]
ORACLE = {
    0: [(0.04, 0.33), (0.05, 0.30), (0.06, 0.285), (0.08, 0.27)],
    1: [(0.04, 0.335), None, (0.06, 0.29), (0.08, 0.272)],
}


def _oracle():
    rows = []
    for seed, pts in ORACLE.items():
        points = [
            {
                "level": x,
                "kpis": None,
                "error": "not solved (Maximum_WallTime_Exceeded, 57 iterations, 900 s)",
                "solver": {"status": "Maximum_WallTime_Exceeded", "iterations": 57, "wall_time_s": 900.4},
            }
            if p is None
            else {"level": x, "kpis": {"discomfort_pmvh": p[0], "energy_kwh": p[1]}, "error": ""}
            for x, p in zip(LEVELS, pts)
        ]
        rows.append({"seed": seed, "status": "ok", "error": "", "points": points})
    return runner.oracle_entry("ok", "", LEVELS, rows)


def make_doc():
    runs = []
    fronts, fobj = {}, {}
    for fam, pts in FAMILY_POINTS.items():
        kind = bs.FAMILIES[fam]
        for n, (d, e) in pts.items():
            sp = float(n.split("@")[1])
            runs.append(_run(n, kind, None, d, e, None if "pmv" in fam else sp))
            if "pmv" in fam:
                runs[-1]["setpoint_pmv"] = sp
        f = fr.build_front(pts) if pts else None
        fobj[fam] = f
        fronts[fam] = (
            []
            if f is None
            else [
                {"controller": p.name, "discomfort": p.discomfort, "energy": p.energy, "efficient": p.efficient}
                for p in f.points
            ]
        )
    runs += [
        _run("ceco", "strategy", 0, 0.08, 0.30),
        _run("ceco", "strategy", 1, 0.085, 0.305),
        _run("baseline-compensated", "compensated", None, 0.045, 0.35),
    ]
    env = fr.Envelope.of(fobj)
    oracle = _oracle()
    bounds = {
        f["seed"]: fr.build_front([(p["controller"], p["discomfort"], p["energy"]) for p in f["front"]])
        for f in oracle["fronts"]
    }
    matched = {}
    for name, pts in (
        ("ceco", [(0, 0.08, 0.30), (1, 0.085, 0.305)]),
        ("baseline-compensated", [(None, 0.045, 0.35)]),
    ):
        de = [(d, e) for _, d, e in pts]
        strongest = fr.match_seeds(env, de)
        strongest["family"] = env.family_at(sum(d for d, _ in de) / len(de))
        matched[name] = {
            **fr.match_seeds(fobj["plain"], de),
            "allowance": fr.match_seeds(fobj["allowance"], de),
            "strongest": strongest,
            "headroom": fr.headroom_seeds(env, bounds, pts),
            "by_phase": fr.by_phase(
                env,
                bounds,
                [
                    (seed, d, next(r["kpis"] for r in runs if r["controller"] == name and r["seed"] == seed))
                    for seed, d, _ in pts
                ],
                {r["controller"]: r["kpis"] for r in runs if r["kind"] in bs.FAMILIES.values()},
                bs.oracle_point_kpis(oracle),
            ),
        }
    case = {
        "case": "sc03-medium",
        "version": 1,
        "case_sha": "0123456789abcdef",
        "scenario": "sc03",
        "forecast_uncertainty": "medium",
        "seeds": [0, 1],
        "duration_s": 600.0,
        "control_period_s": 5.0,
        "horizon_steps": 6,
        "runs": runs,
        "fronts": fronts,
        "strongest": {"families": [n for n, _ in env.fronts], **fr.strongest_by_level(env, LEVELS)},
        "oracle": oracle,
        "matched": matched,
    }
    return {
        "schema": bs.SCHEMA,
        "ceco_version": "0.1.0",
        "benchmark_version": bs.BENCHMARK_VERSION,
        "created_utc": "2026-11-23T10:00:00Z",
        "code_fingerprint": "abcdef0123456789",
        "command": "ceco benchmark",
        "quick": False,
        "settings": {
            "band": [-0.5, 0.5],
            "front_axis": "discomfort_pmvh",
            "energy_axis": "energy_kwh",
            "setpoints_c": [24.0, 25.0, 26.0],
            "setpoints_pmv": [0.0, 0.4],
            "families": {f: {"kind": k} for f, k in bs.FAMILIES.items()},
            "oracle": {"requested": True, "entry_point": runner.ORACLE_ENTRY},
            "strategies": ["ceco"],
        },
        "timing": {"wall_s": 1.0, "runs": 16, "ran_now": 16},
        "cases": [case],
    }


def test_a_valid_document_passes_and_survives_json():
    doc = make_doc()
    assert bs.check_results(doc) == []
    bs.validate_results(json.loads(json.dumps(doc)))
    case = doc["cases"][0]
    # 24 degC is on the cold branch
    eff = {p["controller"]: p["efficient"] for p in case["fronts"]["plain"]}
    assert eff == {"baseline@24.0": False, "baseline@25.0": True, "baseline@26.0": True}
    # the hand-made numbers: ceco's mean point (0.0825, 0.3025); the strongest at 0.0825 is the pmv family's
    # end (0.08, 0.29) [its energy past its least comfortable vertex]; saving (0.29 - 0.3025) / 0.29
    m = case["matched"]["ceco"]
    assert m["strongest"]["family"] == "pmv"
    assert m["strongest"]["energy_saving_pct"] == pytest.approx(100.0 * (0.29 - 0.3025) / 0.29)
    # seed 1's oracle did not solve 0.05; at 0.0825 both oracles are past their ends: no headroom there
    assert m["headroom"]["headroom_captured"] is None
    # the compensated law at 0.045: envelope = tuned (0.35 at 0.04 -> 0.34 at 0.045) vs pmv's 0.36; oracles
    # 0.315 and 0.32375 (seed 1 from 0.04 to 0.06) -> mean 0.319375; saving 0.34 - 0.35 = -0.01 of 0.020625
    h = case["matched"]["baseline-compensated"]["headroom"]
    assert h["strongest"] == "tuned"
    assert h["headroom_captured"] == pytest.approx(-0.01 / (0.34 - 0.319375))
    # by_phase reads the same energies on the same fronts (the band-phase KPIs are absent here: None)
    p = case["matched"]["baseline-compensated"]["by_phase"]
    assert p["families"] == ["tuned"] and p["n_seeds"] == 1
    assert p["controller"]["energy_kwh"] == 0.35 and p["strongest"]["energy_kwh"] == pytest.approx(0.34)
    assert p["bound"]["energy_kwh"] == pytest.approx(0.319375) and p["bound"]["energy_band_kwh"] is None
    assert case["matched"]["ceco"]["by_phase"]["bound"]["energy_kwh"] is None  # past both oracles' ends
    # at 0.05 plain and tuned both spend 0.33: a tie goes to the first family in the order of FAMILIES
    assert [x["family"] for x in case["strongest"]["levels"]] == ["tuned", "plain", "tuned", "pmv"]
    assert case["strongest"]["family"] == "tuned"


def _broken(mutate):
    doc = make_doc()
    mutate(doc)
    return bs.check_results(doc)


def _case(doc):
    return doc["cases"][0]


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda d: d.update(schema="ceco-benchmark/1"), "schema"),
        (lambda d: _case(d)["fronts"].pop("pmv"), "pmv"),
        (lambda d: _case(d)["matched"]["ceco"]["strongest"].update(family="plain"), "strongest.family"),
        (lambda d: _case(d)["matched"]["ceco"]["strongest"].update(energy_saving_pct=1.0), "strongest.energy_saving"),
        (
            lambda d: _case(d)["matched"]["baseline-compensated"]["headroom"].update(headroom_captured=0.5),
            "headroom.headroom_captured",
        ),
        (lambda d: _case(d)["matched"]["ceco"].update(headroom=None), "headroom: missing"),
        (
            lambda d: _case(d)["matched"]["baseline-compensated"]["by_phase"]["bound"].update(energy_kwh=0.3),
            "by_phase.bound.energy_kwh",
        ),
        (
            lambda d: _case(d)["matched"]["baseline-compensated"]["by_phase"].update(families=["pmv"]),
            "by_phase.families",
        ),
        (lambda d: _case(d)["strongest"].update(family="plain"), "strongest: families/family"),
        (lambda d: _case(d)["strongest"]["levels"][0].update(family="pmv"), "strongest/levels"),
        (
            lambda d: _case(d)["oracle"]["fronts"][0]["front"][0].update(energy=0.1),
            "does not recompute from its points",
        ),
        (lambda d: _case(d)["oracle"].update(levels=[0.04, 0.05]), "at least 4 levels"),
        (lambda d: _case(d)["oracle"].update(status="maybe"), "status"),
        (lambda d: _case(d)["oracle"]["fronts"][1]["points"][1]["solver"].update(iterations=-1), "iterations"),
        (lambda d: _case(d)["oracle"]["fronts"][1]["points"][1]["solver"].pop("status"), "status"),
        (lambda d: _case(d)["oracle"]["fronts"][1]["points"][1]["solver"].update(evaluation=""), "evaluation"),
        (lambda d: _case(d)["oracle"].update(status="skipped"), "with fronts"),
        (lambda d: _case(d)["runs"][0]["kpis"].pop("peak_comp_kw"), "peak_comp_kw"),
        (lambda d: _case(d)["runs"][0]["kpis"].update(peak_comp_kw="high"), "peak_comp_kw"),
        (lambda d: _case(d)["runs"][0].update(kind="heuristic"), "kind"),
        (lambda d: _case(d)["runs"][0].update(kpi_notes={}), "null without a note"),
        (lambda d: _case(d)["runs"][0].update(seed=0), "seed must be null"),
        (lambda d: _case(d)["runs"][10].update(seed=7), "one of the case's seeds"),
        (lambda d: _case(d)["runs"].append(copy.deepcopy(_case(d)["runs"][10])), "duplicate run"),
        (lambda d: _case(d)["fronts"]["plain"][1].update(energy=0.36), "values differ"),
        (lambda d: _case(d)["fronts"]["plain"][0].update(efficient=True), "efficient flag"),
        (
            lambda d: _case(d)["fronts"]["plain"].append(
                {"controller": "ceco", "discomfort": 0.08, "energy": 0.3, "efficient": True}
            ),
            "not a run of kind 'baseline' with status ok",
        ),
        (lambda d: _case(d)["matched"]["ceco"].update(energy_saving_pct=12.0), "does not recompute"),
        (lambda d: _case(d)["matched"]["ceco"]["allowance"].update(dominated=True), "allowance.dominated"),
        (lambda d: _case(d)["matched"]["ceco"]["seeds"].update(dominated=[False]), "seeds.dominated"),
        (lambda d: _case(d)["matched"].update({"ceco-x": _case(d)["matched"]["ceco"]}), "no run of this controller"),
        (lambda d: _case(d)["runs"][11].update(status="error", error=""), "without an error message"),
        (lambda d: _case(d)["runs"][11].update(status="failed", error=""), "status failed without an error message"),
        # a failed run is never matched: a matched entry built on one does not validate
        (
            lambda d: [r.update(status="failed", error="did not control") for r in _case(d)["runs"][10:12]],
            "matched/ceco: no run",
        ),
        # ... nor a front member
        (
            lambda d: _case(d)["runs"][1].update(status="failed", error="did not control"),
            "baseline@25.0): not a run of kind",
        ),
        (lambda d: d.update(created_utc="yesterday"), "created_utc"),
        # numbers are finite: Python's json reads NaN and Infinity, JSON Schema's "number" takes them
        (lambda d: _case(d).update(duration_s=math.nan), "cases/0/duration_s: nan is not a finite number"),
        (lambda d: _case(d).update(duration_s=math.inf), "cases/0/duration_s: inf is not a finite number"),
        (lambda d: _case(d)["runs"][10]["kpis"].update(i_pmv=math.nan), "runs/10/kpis/i_pmv: nan is not a finite"),
        (lambda d: _case(d)["runs"][0]["kpis"].update(energy_kwh=math.inf), "kpis/energy_kwh: inf is not a finite"),
        (lambda d: _case(d)["runs"][11]["kpis"].update(peak_comp_kw=-math.inf), "peak_comp_kw: -inf is not a"),
        (lambda d: d["timing"].update(wall_s=math.nan), "timing/wall_s: nan is not a finite number"),
        # the KPI ranges (KPI_RANGES) and at least one case: the JSON Schema's (test_the_json_schema_...)
        (
            lambda d: _case(d)["runs"][10]["kpis"].update(otc_violation_pct=100.5),
            "cases/0/runs/10/kpis/otc_violation_pct: 100.5 is greater than the maximum of 100.0",
        ),
        (
            lambda d: _case(d)["runs"][10]["kpis"].update(otc_violation_pct=-1.0),
            "cases/0/runs/10/kpis/otc_violation_pct: -1.0 is less than the minimum of 0.0",
        ),
        (lambda d: d.update(cases=[]), "cases: [] should be non-empty"),
        (lambda d: d["cases"].append(copy.deepcopy(_case(d))), "cases/1 (sc03-medium): duplicate case (also cases/0)"),
        (lambda d: _case(d)["seeds"].append(2), "ceco has no run for seed(s) [2] of the case's seeds [0, 1, 2]"),
        # a seed listed twice (the validator's coverage reads the seeds as a set: [0, 1, 0] passed)
        (lambda d: _case(d)["seeds"].append(0), "cases/0/seeds: [0, 1, 0] has non-unique elements"),
        # a strategy the document says it compares but no case ran (the seed coverage looks at runs that exist)
        (
            lambda d: d["settings"].update(strategies=["ceco", "ceco-pmv"]),
            "cases/0 (sc03-medium): controller 'ceco-pmv' has no run (settings.strategies lists it)",
        ),
        (
            lambda d: _case(d).update(runs=[r for r in _case(d)["runs"] if r["controller"] != "ceco"]),
            "cases/0 (sc03-medium): controller 'ceco' has no run (settings.strategies lists it)",
        ),
        (
            lambda d: d["settings"].update(strategies="ceco"),
            "settings/strategies: must be a list of controller names, got 'ceco'",
        ),
    ],
)
def test_each_violation_is_reported(mutate, message):
    errors = _broken(mutate)
    assert errors and any(message in e for e in errors), errors
    with pytest.raises(bs.ResultsError, match="problem"):
        doc = make_doc()
        mutate(doc)
        bs.validate_results(doc)


def test_a_listed_strategy_whose_runs_all_errored_still_validates():
    """``settings.strategies`` asks for a run of each listed strategy, of any status: ``ceco benchmark`` records a
    run it could not make (interrupted, the simulator raised) as ``error`` with the reason, which the report lists.
    Only a listed strategy without any run is refused; a document without the key lists none."""
    doc = make_doc()
    for r in _case(doc)["runs"]:
        if r["controller"] == "ceco":
            r.update(status="error", error="not run (interrupted?)")
    del _case(doc)["matched"]["ceco"]
    assert bs.check_results(doc) == []
    del doc["settings"]["strategies"]
    _case(doc)["runs"] = [r for r in _case(doc)["runs"] if r["controller"] != "ceco"]
    assert bs.check_results(doc) == []


def test_a_failed_run_keeps_its_kpis_and_is_left_out_of_matching():
    """A run whose controller did not control it (ceco_core.run_status) is ``failed``: its KPIs are kept
    (and must be explained where null) but it is on no front and in no ``matched`` entry."""
    doc = make_doc()
    runs, case = _case(doc)["runs"], _case(doc)
    failed = _run("external:nan", "external", 0, 0.05, 0.33)
    failed.update(status="failed", error="the controller did not control the run: 12 of 12 control steps in fallback")
    runs.append(failed)
    runs.append(dict(copy.deepcopy(failed), seed=1))  # a seeded controller runs on every seed of the case
    assert bs.check_results(doc) == []  # kept with its numbers, not matched
    assert "external:nan" not in case["matched"]
    failed["kpi_notes"] = {}
    assert any("external:nan" in e and "null without a note" in e for e in bs.check_results(doc))
    failed["kpi_notes"] = {"draught_pct": "run has no dr_pct column"}
    # a matched entry for it (what a +0.0 % 'saving' of the plant's fallback law looked like) is refused
    case["matched"]["external:nan"] = copy.deepcopy(case["matched"]["baseline-compensated"])
    errors = bs.check_results(doc)
    assert any("matched/external:nan" in e and "status ok" in e for e in errors), errors


def test_a_door_family_can_be_the_strongest_and_its_case_document_validates():
    """A hot-commute-4p case assembled by the runner from hand-made rows: the PMV PI with the door held at 0.8
    spends less than the one with the door logic at ceco's discomfort, so the strongest family there is
    ``pmv-door80``; the door-100 member, cheaper still but above the CO2 limit, is on no front and listed as
    broken; the document passes the JSON Schema and the semantic checks (door fronts included)."""
    from ceco_bringup.benchmark.cases import load_case

    def row(controller, kind, seed, d, e, met=1.0, sp_pmv=None):
        return {
            "controller": controller,
            "kind": kind,
            "seed": seed,
            "setpoint_c": None,
            "setpoint_pmv": sp_pmv,
            "source": "simulator",
            "status": "ok",
            "error": "",
            "kpis": _kpis(d, e, air_quality_met=met),
            "kpi_notes": {"draught_pct": "run has no dr_pct column"},
        }

    rows = [
        row("baseline@25.0", "baseline", None, 0.04, 0.40),
        row("baseline@26.0", "baseline", None, 0.06, 0.36),
        row("baseline-pmv@+0.40", "baseline-pmv", None, 0.05, 0.37, sp_pmv=0.4),
        row("baseline-pmv-door80@+0.40", "baseline-pmv-door80", None, 0.05, 0.35, sp_pmv=0.4),
        row("baseline-pmv-door100@+0.40", "baseline-pmv-door100", None, 0.05, 0.30, met=0.0, sp_pmv=0.4),
        *(row("ceco-pmv-aq", "strategy", seed, 0.05, 0.33) for seed in load_case("hot-commute-4p").seeds),
    ]
    levels = runner.oracle_levels([runner._run_entry(r) for r in rows])  # as the CLI records a skipped oracle
    case = runner.assemble_case(
        load_case("hot-commute-4p"), rows, oracle=runner.oracle_entry("skipped", "not requested", levels, [])
    )
    assert [p["controller"] for p in case["fronts"]["pmv-door80"]] == ["baseline-pmv-door80@+0.40"]
    assert case["fronts"]["pmv-door100"] == [] and case["air_quality"]["broken"] == ["baseline-pmv-door100@+0.40"]
    m = case["matched"]["ceco-pmv-aq"]["strongest"]
    assert m["family"] == "pmv-door80" and m["energy_saving_pct"] == pytest.approx(100.0 * (0.35 - 0.33) / 0.35)
    doc = make_doc()
    doc["cases"] = [case]
    doc["settings"]["strategies"] = ["ceco-pmv-aq"]  # as --strategy ceco-pmv-aq records it
    assert bs.check_results(doc) == []
    bs.validate_results(json.loads(json.dumps(doc)))


SCHEMA_FILE = Path(bs.__file__).resolve().parent.parent / "data" / "benchmark" / "results.schema.json"
"""The shipped JSON Schema, read as another tool reads it (a file, no ceco code)."""


def test_the_shipped_json_schema_holds_the_kpi_ranges_of_the_one_table():
    """results.schema.json's ``$defs/kpis`` has a minimum and maximum for each KPI of KPI_RANGES and no other
    (it is what ``kpi_range_properties`` makes of the table: they cannot drift), and ``cases`` at least one item.
    After a change to KPI_RANGES, write the new ``kpi_range_properties()`` into the file's ``$defs/kpis/properties``."""
    doc = json.loads(SCHEMA_FILE.read_text(encoding="utf-8"))
    assert doc == bs.load_json_schema()  # the file the validator loads
    props = doc["$defs"]["kpis"]["properties"]
    assert props == bs.kpi_range_properties()
    assert {k: (v["minimum"], v["maximum"]) for k, v in props.items()} == bs.KPI_RANGES
    assert props["otc_violation_pct"] == {"type": ["number", "null"], "minimum": 0.0, "maximum": 100.0}
    assert doc["properties"]["cases"]["minItems"] == 1


def _out_of_range(k, above):
    lo, hi = bs.KPI_RANGES[k]
    return hi + 0.5 * (hi - lo) if above else lo - 0.5 * (hi - lo)


@pytest.mark.parametrize("kpi", sorted(bs.KPI_RANGES))
def test_a_json_schema_validator_refuses_a_kpi_out_of_its_range(kpi):
    """The shipped file alone (jsonschema, Draft 2020-12) refuses each KPI of KPI_RANGES just outside either end
    of its range, at its place in the document, and takes both ends and null; the hand-made document passes."""
    validator = jsonschema.Draft202012Validator(json.loads(SCHEMA_FILE.read_text(encoding="utf-8")))
    assert validator.is_valid(make_doc())
    for above in (True, False):
        doc = make_doc()
        _case(doc)["runs"][10]["kpis"][kpi] = _out_of_range(kpi, above)
        errors = list(validator.iter_errors(doc))
        assert [list(e.absolute_path) for e in errors] == [["cases", 0, "runs", 10, "kpis", kpi]]
        assert errors[0].validator == ("maximum" if above else "minimum")
    for value in (*bs.KPI_RANGES[kpi], None):
        doc = make_doc()
        _case(doc)["runs"][10]["kpis"][kpi] = value
        _case(doc)["runs"][10]["kpi_notes"][kpi] = "not defined"
        assert validator.is_valid(doc), value


def test_a_json_schema_validator_refuses_a_document_without_cases():
    validator = jsonschema.Draft202012Validator(json.loads(SCHEMA_FILE.read_text(encoding="utf-8")))
    doc = make_doc()
    doc["cases"] = []
    assert [(list(e.absolute_path), e.validator) for e in validator.iter_errors(doc)] == [(["cases"], "minItems")]


def test_ceco_benchmark_validate_refuses_an_out_of_range_kpi_and_no_cases(tmp_path, capsys):
    """``ceco benchmark --validate FILE``: 0 and "valid" for the hand-made document; 1 naming the problem for one
    with ``air_quality_met`` 2 (a 0/1 KPI) or ``co2_above_limit_pct`` above 100, and for one without cases."""
    good = tmp_path / "good.json"
    good.write_text(json.dumps(make_doc()))
    assert bench_cli.main(["--validate", str(good)]) == 0
    assert capsys.readouterr().out.strip() == f"{good}: valid ceco-benchmark/2"
    cases = {
        "met": (lambda d: _case(d)["runs"][11]["kpis"].update(air_quality_met=2.0), "air_quality_met: 2.0 is greater"),
        "co2": (
            lambda d: _case(d)["runs"][0]["kpis"].update(co2_above_limit_pct=100.01),
            "cases/0/runs/0/kpis/co2_above_limit_pct: 100.01 is greater than the maximum of 100.0",
        ),
        "empty": (lambda d: d.update(cases=[]), "cases: [] should be non-empty"),
    }
    for name, (mutate, message) in cases.items():
        doc = make_doc()
        mutate(doc)
        bad = tmp_path / f"{name}.json"
        bad.write_text(json.dumps(doc))
        assert bench_cli.main(["--validate", str(bad)]) == 1, name
        out = capsys.readouterr()
        assert message in out.err and out.out.strip() == f"{bad}: 1 problem(s)", (name, out)


def test_a_runs_energy_is_the_sum_of_its_parts_and_never_negative():
    """`ceco benchmark --validate` called a file valid whose run had energy_comp_kwh 1.0 under energy_kwh 0.39, and
    named a negative energy_kwh only as savings that do not recompute. Energy is compressor + blower + condenser fan:
    each part and the total are >= 0 and the total is their sum (to the recompute tolerance)."""
    doc = make_doc()
    kpis = _case(doc)["runs"][10]["kpis"]
    e = kpis["energy_kwh"]
    kpis.update(energy_comp_kwh=0.8 * e, energy_blower_kwh=0.15 * e, energy_fan_kwh=0.05 * e)
    assert bs.check_results(doc) == []  # the parts add up
    run = _case(doc)["runs"][10]
    where = f"cases/0 ({_case(doc)['case']})/runs/10 ({run['controller']}, seed {run['seed']})"
    kpis["energy_comp_kwh"] = 1.0
    errors = bs.check_results(doc)
    assert len(errors) == 1 and errors[0].startswith(f"{where}: KPI energy_kwh {e!r} is not energy_comp_kwh + ")
    kpis["energy_comp_kwh"] = 0.8 * e
    kpis["energy_fan_kwh"] = -0.05 * e
    assert f"{where}: KPI energy_fan_kwh is {-0.05 * e!r}: an energy is never negative" in bs.check_results(doc)
    assert where == "cases/0 (sc03-medium)/runs/10 (ceco, seed 0)"
    kpis["energy_fan_kwh"] = 0.05 * e
    kpis["time_ratio_mean"] = -0.068  # (an external controller that published ahead of the states)
    assert bs.check_results(doc) == [f"{where}: KPI time_ratio_mean is -0.068: a time ratio is never negative"]
