"""Record warm NLP instances of the long-horizon NMPC for tests/test_long_horizon.py.

For each strategy and horizon (default Np = 24 and 60: the multiple-shooting NLP, solved by the SQP
with HPIPM's QPs), a closed-loop SC03 run with the product settings (in-process functions) records
every ``--every``-th control step's NLP instance as the controller's solve chain saw it: the
parameter vector p and the warm start (the last solution shifted: primal point and both multiplier
vectors). Written to ``tests/data/nlp_instances.npz`` (numpy arrays only, no pickles), keys
``<strategy>_np<N>_<p|x0|lam_x0|lam_g0|k>`` and ``provenance`` (this command, the commit is not
stored: regenerate when the NLP changes; the test says so when the sizes differ).

    python tools/record_nlp_instances.py [--horizons 24,60] [--strategies ceco,ceco-e,ceco-c,ceco-ioch,ceco-pmv]
        [--every 20] [--out tests/data/nlp_instances.npz]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from ceco_controller import closed_loop as cl
from ceco_controller.strategies import CECO_STRATEGIES
from ceco_v2x_preview.scenario import load_scenario


def record(strategy: str, horizon: int, every: int, scenario: str = "sc03") -> dict[str, np.ndarray]:
    """The warm instances of every ``every``-th step (from step 1: step 0 is a cold solve) of one run."""
    sc = load_scenario(scenario)
    ctrl = cl.make_controller(strategy, sc, sc.control.control_period_s, horizon)
    rows: dict[str, list] = {"k": [], "p": [], "x0": [], "lam_x0": [], "lam_g0": []}
    compute = ctrl.compute

    def recording(obs, t_start=None):
        out = compute(obs, t_start)
        data = ctrl.last_nlp()
        if obs.k >= 1 and obs.k % every == 0 and data is not None and data.lam_x0 is not None:
            rows["k"].append(obs.k)
            rows["p"].append(data.p)
            rows["x0"].append(data.x0)
            rows["lam_x0"].append(data.lam_x0)
            rows["lam_g0"].append(data.lam_g0)
        return out

    ctrl.compute = recording  # type: ignore[method-assign]
    cl.simulate(sc, strategy, cl.SimSettings(horizon_steps=horizon, progress=False), controller=ctrl)
    return {key: np.array(v) for key, v in rows.items()}


def main(argv=None) -> int:
    """CLI entry."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--horizons", default="24,60")
    ap.add_argument("--strategies", default=",".join(CECO_STRATEGIES))
    ap.add_argument("--every", type=int, default=20, help="record every N-th control step (from step N)")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "tests" / "data" / "nlp_instances.npz"))
    args = ap.parse_args(argv)
    out: dict[str, np.ndarray] = {}
    for np_ in (int(h) for h in args.horizons.split(",")):
        for strat in args.strategies.split(","):
            rec = record(strat, np_, args.every)
            for key, arr in rec.items():
                out[f"{strat}_np{np_}_{key}"] = arr
            print(f"{strat} Np={np_}: {rec['k'].size} instances (steps {rec['k'].tolist()})", flush=True)
    out["provenance"] = np.array(
        "python tools/record_nlp_instances.py "
        + " ".join(argv if argv is not None else sys.argv[1:])
        + f" (SC03, product settings, in-process functions; every {args.every}th warm instance)"
    )
    np.savez_compressed(args.out, **out)
    print(f"written {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
