"""The cabin CO2 balance identified by ``ceco identify`` and used by the controllers' door (issue 21).

The balance (docs/plant.md "Cabin air quality") has three car parameters: the cabin's air mass and the leakage at
rest and its growth with speed. ``ceco identify`` fits them from a drive with the door, blower and set-point moved
at random (committed as ``data/identification/co2_train.csv``), validates them on another drive, and writes them
into the control model's file; the NMPC's door and the baseline's CO2-holding door read them from there.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ceco_controller import identification as idn
from ceco_controller import model as cm
from ceco_controller.identification_data import (
    CO2_TRAIN_DRIVE,
    CO2_VALIDATION_DRIVE,
    generate_co2_excitation,
)
from ceco_plant_sim.plant_params import PlantParams

DATA = idn.DEFAULT_DATA_DIR


def _committed(name: str) -> dict:
    return idn._co2_series_from_csv(DATA / name)


def test_the_committed_co2_data_is_what_the_excitation_gives():
    """``generate_co2_excitation`` reproduces the committed CSVs (to their 9 and 6 significant digits): the door
    covers 0.01..1.0, the speed 0..25 m/s, 4 and 2 occupants, CO2 up to 1391 and 888 ppm."""
    for drive, name, co2_max in (
        (CO2_TRAIN_DRIVE, "co2_train.csv", 1391.0),
        (CO2_VALIDATION_DRIVE, "co2_validation.csv", 887.9),
    ):
        fresh = generate_co2_excitation(drive)
        stored = _committed(name)
        assert stored["n_occupants"] == drive[1] == fresh["n_occupants"]
        assert fresh["t_s"].size == stored["t_s"].size
        np.testing.assert_allclose(stored["co2_cab_ppm"], fresh["co2_cab_ppm"], rtol=1e-8)
        for c in ("w_cab_kgkg", "t_evap_c"):
            np.testing.assert_allclose(stored[c], fresh[c], rtol=1e-8)
        for c in ("recirc_share", "mdot_bl_kgps", "speed_mps", "t_amb_c", "rh_amb"):
            np.testing.assert_allclose(stored[c], fresh[c], rtol=1e-5, atol=1e-9)
        assert fresh["co2_cab_ppm"].max() == pytest.approx(co2_max, abs=1.0)
    train = _committed("co2_train.csv")
    assert np.ptp(train["recirc_share"]) > 0.95 and np.ptp(train["speed_mps"]) > 20.0


def test_the_shipped_model_holds_the_co2_balance_fitted_from_the_committed_data():
    """The committed data fitted by the same code gives the shipped file's values; they are the plant's cabin air
    mass within 0.2 %, its leakage at rest within 4 % and its growth with speed within 2 %; the balance run free
    with them stays within 2 ppm of the plant's CO2 on the training drive and 1 ppm on the validation drive."""
    train, valid = _committed("co2_train.csv"), _committed("co2_validation.csv")
    fit = idn.fit_co2_balance(train, train["n_occupants"], train["co2_amb_ppm"])
    shipped = cm.load_params()
    # ceco identify fits the simulated series; the CSV holds them to 6 significant digits (door, flow, speed)
    assert shipped.co2_m_air_kg == pytest.approx(fit.m_air_kg, rel=1e-5)
    assert shipped.co2_leak_0_kgps == pytest.approx(fit.leak_0_kgps, rel=1e-4)
    assert shipped.co2_leak_per_mps_kgps == pytest.approx(fit.leak_per_mps_kgps, rel=1e-4)
    pp = PlantParams()
    assert fit.m_air_kg == pytest.approx(pp.rho_air_kgm3 * pp.cabin_volume_m3, rel=0.002)
    assert fit.leak_0_kgps == pytest.approx(pp.infiltration_0_kgps, rel=0.04)
    assert fit.leak_per_mps_kgps == pytest.approx(pp.infiltration_per_mps_kgps, rel=0.02)
    assert fit.free_run_max_err_ppm < 2.0
    err = idn.co2_free_run_max_err_ppm(
        valid, valid["n_occupants"], valid["co2_amb_ppm"], fit.m_air_kg, fit.leak_0_kgps, fit.leak_per_mps_kgps
    )
    assert err < 1.0
    # the door's position read at the interval's start instead of its mean biases the leakage at rest (+22 %)
    start = dict(train, recirc_share=np.r_[train["recirc_share"][:1], train["recirc_share"][:-1]])
    biased = idn.fit_co2_balance(start, train["n_occupants"], train["co2_amb_ppm"])
    assert abs(biased.leak_0_kgps / pp.infiltration_0_kgps - 1.0) > 0.1


def test_the_shipped_model_holds_the_water_balance_fitted_from_the_committed_data():
    """The water balance fitted from the committed data (the CO2 fit's air mass and leakage) gives the shipped
    file's occupants' latent heat and coil bypass factor; they are the plant's 55 W within 10 % and inside the
    plant's own bypass range at the excitation's flows (exp(-UA/(mdot c_p)): 0.04-0.09); the balance run free with
    them stays within 0.15 g/kg of the plant's humidity on both drives; data without condensation are refused."""
    train, valid = _committed("co2_train.csv"), _committed("co2_validation.csv")
    air = idn.fit_co2_balance(train, train["n_occupants"], train["co2_amb_ppm"])
    args = (air.m_air_kg, air.leak_0_kgps, air.leak_per_mps_kgps)
    fit = idn.fit_moisture_balance(train, train["n_occupants"], *args)
    shipped = cm.load_params()
    assert shipped.moist_occ_latent_w == pytest.approx(fit.occ_latent_w, rel=1e-4)
    assert shipped.moist_coil_bypass_factor == pytest.approx(fit.bypass_factor, rel=1e-4)
    pp = PlantParams()
    assert fit.occ_latent_w == pytest.approx(pp.occ_latent_w, rel=0.1)
    assert 0.04 < fit.bypass_factor < 0.09
    assert fit.free_run_max_err_kgkg < 0.15e-3
    err = idn.moisture_free_run_max_err_kgkg(valid, valid["n_occupants"], *args, fit.occ_latent_w, fit.bypass_factor)
    assert err < 0.15e-3
    # a wrong latent heat (the nominal 55 W doubled) runs off by more than the fit's error
    bad = idn.moisture_free_run_max_err_kgkg(valid, valid["n_occupants"], *args, 110.0, fit.bypass_factor)
    assert bad > 3 * err
    dry = dict(train, t_evap_c=np.full_like(train["t_evap_c"], 30.0))  # a wall above every dew point
    with pytest.raises(ValueError, match="condense"):
        idn.fit_moisture_balance(dry, train["n_occupants"], *args)


def test_the_controllers_doors_use_the_identified_balance():
    """The NMPC's door (``door_control`` nlp) and the baseline's CO2-holding door run the control model's CO2
    balance; a parameter file from before the balance was identified loads with the nominal values."""
    from ceco_controller.factory import make_controller
    from ceco_v2x_preview.scenario import load_scenario

    sc = load_scenario("udds")
    mp = dataclasses.replace(cm.load_params(), co2_m_air_kg=4.1, co2_leak_0_kgps=0.002, co2_leak_per_mps_kgps=3e-4)
    base = make_controller("baseline", sc, 5.0, 6, mp, {"door_mode": "co2_hold"})
    law = base.co2_door
    assert (law.model.m_air_kg, law.model.leak_0_kgps, law.model.leak_per_mps_kgps) == (4.1, 0.002, 3e-4)
    shipped = cm.load_params()
    default_base = make_controller("baseline", sc, 5.0, 6, None, {"door_mode": "co2_hold"})
    assert default_base.co2_door.model.m_air_kg == shipped.co2_m_air_kg != 3.48
    nmpc = make_controller("ceco-pmv", sc, 5.0, 6, mp, {"door_control": "nlp"})
    assert nmpc.door.model.m_air_kg == 4.1 and nmpc.door.nlp_parameters(600.0, 1500.0, 4)["m_air"] == 4.1
    old = {k: v for k, v in shipped.to_dict().items() if not k.startswith(("co2_", "moist_"))}
    older = cm.ControlModelParams.from_dict(old)
    assert (older.co2_m_air_kg, older.co2_leak_0_kgps, older.co2_leak_per_mps_kgps) == (3.48, 0.0015, 0.0002)
    assert (older.moist_coil_bypass_factor, older.moist_occ_latent_w) == (0.06, 55.0)
    with pytest.raises(ValueError, match="co2_leak_0_kgps must be > 0"):
        dataclasses.replace(shipped, co2_leak_0_kgps=0.0).validate()


def test_identify_fits_the_co2_balance_from_csv_or_keeps_the_nominal_values(tmp_path, capsys):
    """``ceco identify --from-csv`` with ``--co2-csv`` fits the balance from the CSV and writes it with its report;
    without it the nominal values stay and the provenance says so; a CSV whose occupants column changes is refused
    with one line naming the column."""
    train = str(DATA / "train.csv")
    valid = str(DATA / "validation.csv")
    args = ["--from-csv", train, "--validation-csv", valid, "--co2-csv", str(DATA / "co2_train.csv")]
    args += ["--co2-validation-csv", str(DATA / "co2_validation.csv")]
    assert idn.main([*args, "--out", str(tmp_path / "a")]) == 0
    import yaml

    doc = yaml.safe_load((tmp_path / "a" / "model_params.yaml").read_text())
    shipped = cm.load_params()
    assert doc["params"]["co2_m_air_kg"] == pytest.approx(shipped.co2_m_air_kg, rel=1e-5)
    assert doc["fit_report"]["co2_balance_fit"]["free_run_max_err_validation_ppm"] < 1.0
    assert doc["fit_report"]["co2_balance_fit"]["moisture_free_run_max_err_validation_g_per_kg"] < 0.15
    assert doc["params"]["moist_occ_latent_w"] == pytest.approx(shipped.moist_occ_latent_w, rel=1e-4)
    assert "co2_train.csv" in doc["params"]["provenance"]
    assert idn.main(["--from-csv", train, "--validation-csv", valid, "--out", str(tmp_path / "b")]) == 0
    doc = yaml.safe_load((tmp_path / "b" / "model_params.yaml").read_text())
    assert doc["params"]["co2_m_air_kg"] == 3.48 and "CO2 balance not identified" in doc["params"]["provenance"]
    assert doc["params"]["moist_occ_latent_w"] == 55.0
    bad = (DATA / "co2_train.csv").read_text().splitlines()
    bad[5] = bad[5].rsplit(",", 2)[0] + ",3,425"
    (tmp_path / "bad.csv").write_text("\n".join(bad) + "\n")
    capsys.readouterr()
    code = idn.main(
        [
            "--from-csv",
            train,
            "--validation-csv",
            valid,
            "--co2-csv",
            str(tmp_path / "bad.csv"),
            "--out",
            str(tmp_path / "c"),
        ]
    )
    assert code == 2 and "column 'n_occupants' must hold one value on every row" in capsys.readouterr().err
