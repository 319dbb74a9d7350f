"""The results format ceco-benchmark/1 (JSON Schema + semantic checks)."""

import copy
import json

import pytest

from ceco_bringup.benchmark import front as fr
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


def make_doc():
    plain = {"baseline@24.0": (0.06, 0.40), "baseline@25.0": (0.04, 0.37), "baseline@26.0": (0.05, 0.33)}
    allow = {"baseline-allowance@25.0": (0.07, 0.33), "baseline-allowance@26.0": (0.09, 0.29)}
    runs = [_run(n, "baseline", None, d, e, float(n.split("@")[1])) for n, (d, e) in plain.items()]
    runs += [_run(n, "baseline-allowance", None, d, e, float(n.split("@")[1])) for n, (d, e) in allow.items()]
    runs += [
        _run("ceco", "strategy", 0, 0.08, 0.30),
        _run("ceco", "strategy", 1, 0.085, 0.305),
        _run("baseline-compensated", "compensated", None, 0.045, 0.35),
    ]
    fronts, fobj = {}, {}
    for fam, pts in (("plain", plain), ("allowance", allow)):
        f = fr.build_front(pts)
        fobj[fam] = f
        fronts[fam] = [
            {"controller": p.name, "discomfort": p.discomfort, "energy": p.energy, "efficient": p.efficient}
            for p in f.points
        ]
    matched = {}
    for name, pts in (("ceco", [(0.08, 0.30), (0.085, 0.305)]), ("baseline-compensated", [(0.045, 0.35)])):
        matched[name] = {**fr.match_seeds(fobj["plain"], pts), "allowance": fr.match_seeds(fobj["allowance"], pts)}
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
        },
        "timing": {"wall_s": 1.0, "runs": 8, "ran_now": 8},
        "cases": [case],
    }


def test_a_valid_document_passes_and_survives_json():
    doc = make_doc()
    assert bs.check_results(doc) == []
    bs.validate_results(json.loads(json.dumps(doc)))
    # 24 degC is on the cold branch
    eff = {p["controller"]: p["efficient"] for p in doc["cases"][0]["fronts"]["plain"]}
    assert eff == {"baseline@24.0": False, "baseline@25.0": True, "baseline@26.0": True}


def _broken(mutate):
    doc = make_doc()
    mutate(doc)
    return bs.check_results(doc)


def _case(doc):
    return doc["cases"][0]


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda d: d.update(schema="ceco-benchmark/2"), "schema"),
        (lambda d: _case(d)["runs"][0]["kpis"].pop("peak_comp_kw"), "peak_comp_kw"),
        (lambda d: _case(d)["runs"][0]["kpis"].update(peak_comp_kw="high"), "peak_comp_kw"),
        (lambda d: _case(d)["runs"][0].update(kind="heuristic"), "kind"),
        (lambda d: _case(d)["runs"][0].update(kpi_notes={}), "null without a note"),
        (lambda d: _case(d)["runs"][0].update(seed=0), "seed must be null"),
        (lambda d: _case(d)["runs"][5].update(seed=7), "one of the case's seeds"),
        (lambda d: _case(d)["runs"].append(copy.deepcopy(_case(d)["runs"][5])), "duplicate run"),
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
        (lambda d: _case(d)["runs"][6].update(status="error", error=""), "without an error message"),
        (lambda d: _case(d)["runs"][6].update(status="failed", error=""), "status failed without an error message"),
        # a failed run is never matched: a matched entry built on one does not validate
        (
            lambda d: [r.update(status="failed", error="did not control") for r in _case(d)["runs"][5:7]],
            "matched/ceco: no run",
        ),
        # ... nor a front member
        (
            lambda d: _case(d)["runs"][1].update(status="failed", error="did not control"),
            "baseline@25.0): not a run of kind",
        ),
        (lambda d: d.update(created_utc="yesterday"), "created_utc"),
    ],
)
def test_each_violation_is_reported(mutate, message):
    errors = _broken(mutate)
    assert errors and any(message in e for e in errors), errors
    with pytest.raises(bs.ResultsError, match="problem"):
        doc = make_doc()
        mutate(doc)
        bs.validate_results(doc)


def test_a_failed_run_keeps_its_kpis_and_is_left_out_of_matching():
    """A run whose controller did not control it (ceco_core.run_status) is ``failed``: its KPIs are kept
    (and must be explained where null) but it is on no front and in no ``matched`` entry."""
    doc = make_doc()
    runs, case = _case(doc)["runs"], _case(doc)
    failed = _run("external:nan", "external", 0, 0.05, 0.33)
    failed.update(status="failed", error="the controller did not control the run: 12 of 12 control steps in fallback")
    runs.append(failed)
    assert bs.check_results(doc) == []  # kept with its numbers, not matched
    assert "external:nan" not in case["matched"]
    failed["kpi_notes"] = {}
    assert any("external:nan" in e and "null without a note" in e for e in bs.check_results(doc))
    failed["kpi_notes"] = {"draught_pct": "run has no dr_pct column"}
    # a matched entry for it (what a +0.0 % 'saving' of the plant's fallback law looked like) is refused
    case["matched"]["external:nan"] = copy.deepcopy(case["matched"]["baseline-compensated"])
    errors = bs.check_results(doc)
    assert any("matched/external:nan" in e and "status ok" in e for e in errors), errors
