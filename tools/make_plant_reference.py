#!/usr/bin/env python3
"""Recorded closed-loop command sequences and the plant's reference trajectories: tests/data/plant_reference.npz.

Usage (from the repository root, workspace sourced):

    python tools/make_plant_reference.py            # record the runs' commands, replay them, write the file
    python tools/make_plant_reference.py --check    # replay the recorded commands on the current plant, compare
    python tools/make_plant_reference.py --show     # print the file's provenance

For each run of ``RUNS`` (scenario, strategy) the in-process closed loop
(``ceco_controller.closed_loop.simulate``, perfect previews, the scenario's seed) is run once and the
command it applied at every plant step is recorded. The commands are then replayed open loop on the
plant (``ceco_plant_sim.replay.replay_commands``), and the file keeps, per run: the commands (every
step), the replayed series every ``SAMPLE_EVERY`` steps and at the last step, the run's energy and
the SHA-256 of every per-step series (float64 bytes, :data:`~ceco_plant_sim.replay.REPLAY_SERIES`
order), with the provenance (ceco commit, date, machine, command).

The file was written with the plant of commit 8546529 (before its equations were written once,
docs/plant.md "The model written once"): ``--check`` and tests/test_plant_model.py compare the
current plant with it (the brief: equal to 1e-9 relative; ``--check`` also says whether the replay is
bit-identical). The commands also drive the smooth symbolic model's replay test. Regenerating the file
re-records the commands and makes the current plant the reference: do it only for a deliberate change
of the plant's numbers, and say so in the commit.
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import json
import os
import pathlib
import platform
import sys

import numpy as np
from make_refrigerant_tables import _commit  # the same provenance helper

ROOT = pathlib.Path(__file__).resolve().parents[1]
OUT = ROOT / "tests" / "data" / "plant_reference.npz"
RUNS = (
    ("sc03", "baseline"),
    ("sc03", "ceco"),
    ("udds", "baseline"),
    ("udds", "ceco"),
    ("sc03_hotsoak", "baseline"),
    ("sc03_mild", "ceco-e"),
)
"""(scenario, strategy) of the recorded runs: the paper's case and the city cycle with the baseline and
the CECO NMPC, the one-hour hot soak (MOP valve and inverter power limit), the mild day (compressor
duty-cycling below its minimum speed)."""
SAMPLE_EVERY = 10
"""Replayed series kept every this many plant steps (and the last step)."""
FORMAT = 1


def run_key(scenario: str, strategy: str) -> str:
    """The key prefix of one run's arrays in the file."""
    return f"{scenario}__{strategy}"


def sample_index(n: int) -> np.ndarray:
    """Indices of the kept samples of an n-step run: every SAMPLE_EVERY steps and the last."""
    return np.unique(np.append(np.arange(0, n, SAMPLE_EVERY), n - 1))


def series_digest(series: dict, names=None) -> str:
    """SHA-256 of the per-step series ``names`` (default every REPLAY_SERIES, float64 bytes in that order)."""
    from ceco_plant_sim.replay import REPLAY_SERIES

    h = hashlib.sha256()
    for k in REPLAY_SERIES if names is None else names:
        h.update(np.ascontiguousarray(series[k], dtype=np.float64).tobytes())
    return h.hexdigest()


def load(path=OUT) -> tuple[dict, dict]:
    """(provenance, arrays) of the reference file."""
    with np.load(path, allow_pickle=False) as z:
        prov = json.loads(str(z["provenance"]))
        arrays = {k: z[k] for k in z.files if k != "provenance"}
    if prov.get("format") != FORMAT:
        raise ValueError(f"{path}: format {prov.get('format')!r}, this tool reads {FORMAT}")
    return prov, arrays


def record() -> dict:
    """Run every closed loop of RUNS, replay its commands on the plant; the file's arrays and run notes."""
    from ceco_controller.closed_loop import SimSettings, simulate
    from ceco_plant_sim.replay import REPLAY_SERIES, replay_commands

    arrays, notes = {}, []
    for scenario, strategy in RUNS:
        run = simulate(scenario, strategy, SimSettings(progress=False))
        ts = run.timeseries
        m, t = ts["mdot_bl_kgps"], ts["t_evap_sp_c"]
        rep = replay_commands(scenario, m, t)
        for k, r in (("pmv", "pmv"), ("p_comp_w", "p_comp_w"), ("t_cab_c", "meas_t_cab_c")):
            if not np.array_equal(ts[k], rep.series[r]):  # the replay is the closed loop's plant, to the bit
                raise RuntimeError(f"{scenario}/{strategy}: the replay differs from the closed loop in {k}")
        key = run_key(scenario, strategy)
        idx = sample_index(m.size)
        arrays[f"{key}__mdot_bl_kgps"] = m
        arrays[f"{key}__t_evap_sp_c"] = t
        arrays[f"{key}__sample_index"] = idx
        arrays[f"{key}__samples"] = np.stack([rep.series[k][idx] for k in REPLAY_SERIES])
        arrays[f"{key}__energy_j"] = np.array(rep.energy_j())
        notes.append(
            {
                "scenario": scenario,
                "strategy": strategy,
                "steps": int(m.size),
                "sha256": series_digest(rep.series),
                "energy_kwh": rep.energy_j() / 3.6e6,
                "n_fallback": int(run.metrics["n_fallback_shifted"] + run.metrics["n_fallback_baseline"]),
            }
        )
        print(f"recorded {scenario}/{strategy}: {m.size} steps, {rep.energy_j() / 3.6e6:.4f} kWh", flush=True)
    return {"arrays": arrays, "runs": notes, "series": list(REPLAY_SERIES)}


def compare(path=OUT) -> list[dict]:
    """Replay the file's commands on the current plant; per run: bit-identical?, largest relative difference."""
    from ceco_plant_sim.replay import REPLAY_SERIES, replay_commands

    prov, arrays = load(path)
    names = list(prov["series"])  # the series the file recorded; the code may record more (issue 21: CO2, door)
    missing = [k for k in names if k not in REPLAY_SERIES]
    if missing:
        raise ValueError(f"{path}: recorded series {missing} are not among the code's {list(REPLAY_SERIES)}")
    rows = []
    for note in prov["runs"]:
        key = run_key(note["scenario"], note["strategy"])
        rep = replay_commands(note["scenario"], arrays[f"{key}__mdot_bl_kgps"], arrays[f"{key}__t_evap_sp_c"])
        idx = arrays[f"{key}__sample_index"]
        ref = arrays[f"{key}__samples"]
        got = np.stack([rep.series[k][idx] for k in names])
        scale = np.maximum(np.max(np.abs(ref), axis=1, keepdims=True), 1e-300)
        rel = np.abs(got - ref) / scale
        worst = int(np.argmax(np.max(rel, axis=1)))
        e_ref = float(arrays[f"{key}__energy_j"])
        rows.append(
            {
                "run": f"{note['scenario']}/{note['strategy']}",
                "bit_identical": series_digest(rep.series, names) == note["sha256"],
                "max_rel": float(np.max(rel)),
                "worst_series": names[worst],
                "energy_rel": abs(rep.energy_j() - e_ref) / e_ref,
            }
        )
    return rows


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=str(OUT), help="file to write or check")
    p.add_argument("--check", action="store_true", help="replay the recorded commands on the current plant")
    p.add_argument("--show", action="store_true", help="print the provenance")
    args = p.parse_args(argv)
    if args.show:
        print(json.dumps(load(args.out)[0], indent=2, sort_keys=True))
        return 0
    if args.check:
        rows = compare(args.out)
        for r in rows:
            print(
                f"{r['run']:24s} bit-identical {str(r['bit_identical']):5s}  max relative difference "
                f"{r['max_rel']:.3g} ({r['worst_series']})  energy {r['energy_rel']:.3g}"
            )
        return 0 if all(r["max_rel"] <= 1e-9 for r in rows) else 1
    rec = record()
    prov = {
        "format": FORMAT,
        "runs": rec["runs"],
        "series": rec["series"],
        "sample_every": SAMPLE_EVERY,
        "settings": "ceco_controller.closed_loop.SimSettings() defaults: perfect previews, plant step 1 s",
        "command": "python tools/make_plant_reference.py",
        "ceco_commit": _commit(),
        "date_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": f"{platform.machine()} {platform.system()}, Python {platform.python_version()}, "
        f"numpy {np.__version__}",
    }
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "wb") as f:
        np.savez_compressed(f, provenance=np.array(json.dumps(prov, sort_keys=True)), **rec["arrays"])
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
