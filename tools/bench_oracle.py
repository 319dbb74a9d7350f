"""Cost of one oracle level in two forms of the NLP, measured in the same run.

    python tools/bench_oracle.py [--case mild-day] [--duration-s 120] [--level 0.036] [--repeat 1]
                                 [--max-iter N] [--cache-dir DIR] [--forms evaluation|energy]

``--forms evaluation`` (the default): CasADi's virtual machine against the compiled plant steps
(``OracleSettings.compiled`` ``no`` and ``yes``, both with the energy summed in the objective; docs/oracle.md
"Compiled plant steps"). ``--forms energy``:
the energy summed in the objective against the lifted energy (``OracleSettings.lift_energy`` False and True,
both compiled; docs/oracle.md "Lifted energy"). Builds the whole-drive NLP of the case's first
``--duration-s`` seconds (0: the whole drive) in both forms and solves the same level from the same initial
guess (the production law's run) with each, alternating, ``--repeat`` times. Prints per solve the IPOPT
status, iterations, wall time, time per iteration, the NLP functions' share (IPOPT's own timers: the
constraint Jacobian, the objective's gradient, the constraints and objective) and the 1-minute load average
before and after; then the ratio virtual machine / compiled (medians: per iteration and in total) and the
one-off cost of the compiled object (code generation and compilation, or the cache lookup). The solutions
are compared: iterations and the NLP's energy (the issue's "same solution" check). ``--cache-dir``: the
compiled objects' cache (default: a fresh temporary directory, so the compile is measured). ``--max-iter``:
IPOPT's iteration limit (a whole drive's cost per iteration without its 100-400 iterations; both evaluations
then stop at the same iterate, compared the same way). The same-solution check: ``evaluation``, the same
iterates (iterations within 1, NLP energy within 1e-9 relative); ``energy``, the same problem by another path
(both solved, discomfort within 1e-4 relative, the lifted optimum's energy not above the summed one's by more
than 1e-4 relative: it may end at a better local optimum); exit status 1 otherwise. Other processes
on the machine bias every figure: read the load next to it. Last line: one JSON object.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time

TIMERS = ('nlp_jac_g', 'nlp_grad_f', 'nlp_g', 'nlp_f')
"""IPOPT's per-function wall timers printed (``solver.stats()['t_wall_<name>']``)."""


FORMS = {
    # the summed form: the lifted form's IPOPT path is too sensitive to the derivatives' last digits for the
    # iterate-by-iterate equality this comparison checks (tests/test_oracle.py, the same reason)
    'evaluation': (
        ('vm', {'compiled': 'no', 'lift_energy': False}),
        ('compiled', {'compiled': 'yes', 'lift_energy': False}),
    ),
    'energy': (
        ('summed', {'compiled': 'yes', 'lift_energy': False}),
        ('lifted', {'compiled': 'yes', 'lift_energy': True}),
    ),
}
"""Per ``--forms``: (reference, candidate), each (tag, OracleSettings fields)."""


def _problem(scenario, form: dict, cache_dir: str, max_iter: int, case):
    from ceco_controller import oracle as orc

    t0 = time.perf_counter()
    settings = orc.OracleSettings(
        control_period_s=case.control_period_s,
        door_logic=tuple(case.baseline_door),
        cache_dir=cache_dir,
        max_iter=max_iter,
        lifted_max_iter=max_iter,  # one solve per form here, no fallback: the same budget for both
        stall_iter=0,  # and each runs to IPOPT's own end (the stall rule is the lifted form's only)
        **form,
    )
    pb = orc.OracleProblem(scenario, settings)
    return pb, time.perf_counter() - t0


def _solve(pb, level: float, w0) -> dict:
    load0 = os.getloadavg()[0]
    status, ok, it, wall, w, _ = pb.solve(level, w0)
    st = pb.solver.stats()
    energy, discomfort = pb.evaluate(w)
    return {
        'status': status,
        'success': ok,
        'iterations': it,
        'wall_s': wall,
        'per_iteration_s': wall / max(it, 1),
        'timers_s': {k: float(st.get(f't_wall_{k}', float('nan'))) for k in TIMERS},
        'nlp_energy_kwh': energy,
        'nlp_discomfort_pmvh': discomfort,
        'load': (load0, os.getloadavg()[0]),
    }


def main(argv=None) -> int:
    """Run the comparison; print the table and one JSON line."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--case', default='mild-day')
    p.add_argument('--duration-s', type=float, default=120.0, help='the first seconds of the drive (0: all of it)')
    p.add_argument('--level', type=float, default=0.036, help='discomfort level [PMV h]')
    p.add_argument('--repeat', type=int, default=1)
    p.add_argument('--max-iter', type=int, default=400, help='IPOPT iterations per solve')
    p.add_argument('--cache-dir', default=None, help='compiled objects (default: a fresh temporary directory)')
    p.add_argument('--forms', choices=sorted(FORMS), default='evaluation', help='the two forms compared')
    args = p.parse_args(argv)

    from ceco_bringup.benchmark.cases import load_case
    from ceco_controller import oracle as orc
    from ceco_v2x_preview.scenario import scenario_from_dict

    case = load_case(args.case)
    d = case.scenario_dict()
    if args.duration_s > 0:
        d['duration_s'] = args.duration_s
    scenario = scenario_from_dict(d)
    (ref, ref_form), (cand, cand_form) = FORMS[args.forms]
    with tempfile.TemporaryDirectory(prefix='ceco_bench_oracle_') as tmp:
        cache = args.cache_dir or tmp
        load0 = os.getloadavg()[0]
        pr, t_ref = _problem(scenario, ref_form, cache, args.max_iter, case)
        pc, t_cand = _problem(scenario, cand_form, cache, args.max_iter, case)
        c = pc.compiled
        print(
            f'{args.case} first {scenario.duration_s:g} s: {pc.n_control} intervals of {pc.steps_per_control} steps, '
            f'level {args.level:g} PMV h'
        )
        print(f'NLP built: {ref} {t_ref:.1f} s, {cand} {t_cand:.1f} s (load {load0:.1f})')
        print(
            f'compiled object: {"built" if c.built else "cache hit"} in {c.seconds:.1f} s '
            f'(flags {" ".join(pc.settings.compile_flags)}): {c.path}'
        )
        guess = orc.baseline_commands(scenario, pr.control_period_s, door_logic=pr.settings.door_logic)
        runs: dict[str, list[dict]] = {ref: [], cand: []}
        header = (
            f'{"form":<10} {"status":<22} {"iter":>4} {"wall [s]":>9} {"per it [s]":>10} '
            + ' '.join(f'{k[4:] + " [s]":>11}' for k in TIMERS)
            + f' {"E NLP [kWh]":>17} {"load":>9}'
        )
        print(header)
        for _ in range(args.repeat):
            for tag, pb in ((ref, pr), (cand, pc)):
                r = _solve(pb, args.level, pb.guess_from_commands(guess))
                runs[tag].append(r)
                print(
                    f'{tag:<10} {r["status"]:<22} {r["iterations"]:>4} {r["wall_s"]:>9.2f} '
                    f'{r["per_iteration_s"]:>10.4f} '
                    + ' '.join(f'{r["timers_s"][k]:>11.2f}' for k in TIMERS)
                    + f' {r["nlp_energy_kwh"]:>17.12f} {r["load"][0]:>4.1f}-{r["load"][1]:.1f}',
                    flush=True,
                )

    def med(tag, key):
        return statistics.median(r[key] for r in runs[tag])

    per_it = med(ref, 'per_iteration_s') / med(cand, 'per_iteration_s')
    total = med(ref, 'wall_s') / med(cand, 'wall_s')
    jac = statistics.median(r['timers_s']['nlp_jac_g'] for r in runs[ref]) / statistics.median(
        r['timers_s']['nlp_jac_g'] for r in runs[cand]
    )
    pairs = list(zip(runs[ref], runs[cand], strict=True))
    d_it = max(abs(a['iterations'] - b['iterations']) for a, b in pairs)
    d_e = max(abs(a['nlp_energy_kwh'] - b['nlp_energy_kwh']) / abs(a['nlp_energy_kwh']) for a, b in pairs)
    d_d = max(
        abs(a['nlp_discomfort_pmvh'] - b['nlp_discomfort_pmvh']) / max(abs(a['nlp_discomfort_pmvh']), 1e-12)
        for a, b in pairs
    )
    solved = all(a['success'] and b['success'] for a, b in pairs)
    print(
        f'{ref} / {cand}: {per_it:.2f}x per iteration, {total:.2f}x in total, {jac:.2f}x in the '
        f'constraint Jacobian; iterations differ by {d_it}, NLP energy by {d_e:.1e} relative, discomfort by '
        f'{d_d:.1e}; one-off compiled object {c.seconds:.1f} s ({"built" if c.built else "cache hit"})'
    )
    no_worse = all(b['nlp_energy_kwh'] <= a['nlp_energy_kwh'] * (1 + 1e-4) for a, b in pairs)
    same = (d_it <= 1 and d_e <= 1e-9) if args.forms == 'evaluation' else (solved and no_worse and d_d <= 1e-4)
    print(
        json.dumps(
            {
                'case': args.case,
                'duration_s': scenario.duration_s,
                'level_pmvh': args.level,
                'forms': args.forms,
                'reference': ref,
                'candidate': cand,
                'intervals': pc.n_control,
                'steps_per_interval': pc.steps_per_control,
                'build_s': {ref: t_ref, cand: t_cand},
                'compile': {'built': c.built, 'seconds': c.seconds, 'flags': list(pc.settings.compile_flags)},
                'runs': runs,
                'ratio_per_iteration': per_it,
                'ratio_total': total,
                'ratio_jac_g': jac,
                'iterations_max_difference': d_it,
                'energy_max_rel_difference': d_e,
                'discomfort_max_rel_difference': d_d,
                'check_passed': same,
            }
        )
    )
    return 0 if same else 1


if __name__ == '__main__':
    sys.exit(main())
