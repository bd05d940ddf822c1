#!/usr/bin/env python3
"""Interactive planning's wait: a plan prepared once (incise.PlanSession), then one bone segment
nudged step by step, each nudge predicted warm from the last, as `incise plan --view` does:
after each prediction the Hessian is factorised where it ended (PlanSession.prepare_next_nudge,
which the viewer runs while the user looks and moves the hand), so that the next nudge needs no
factorisation of its own. Prints per nudge the seconds from the move to the prediction (the
wait after releasing the mouse), Newton steps, factorisations, the conjugate gradient iterations
with the factor in hand and the residual force, and the seconds of the factorisation that
followed it (--no-prepare: none, each nudge predicted with
whatever factor the last left, refactorised when it no longer serves).

usage: PYTHONPATH=build/ci/python /usr/bin/python3 bench/plan_nudge.py
           [--plan scenes/plan_neonatal_head.json] [--layers 2] [--near -90 -142 512]
           [--step -1 0 0] [--nudges 3] [--no-prepare]

--near (mm) picks the segment; --step (mm) is each nudge's translation; the plan's own moves
are dropped so that the first prediction is of the scanned state.
"""
import argparse
import json
import os
import statistics
import time

import incise


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--plan", default="scenes/plan_neonatal_head.json")
    parser.add_argument("--layers", type=int, default=2)
    parser.add_argument("--near", type=float, nargs=3, default=[-90, -142, 512])
    parser.add_argument("--step", type=float, nargs=3, default=[-1, 0, 0])
    parser.add_argument("--nudges", type=int, default=3)
    parser.add_argument("--no-prepare", action="store_true")
    args = parser.parse_args()
    with open(args.plan) as f:
        plan = json.load(f)
    plan["moves"] = []
    plan["layers"] = args.layers
    start = time.perf_counter()
    session = incise.PlanSession(plan, plan_file=os.path.abspath(args.plan))
    prepared = time.perf_counter() - start
    first = session.predict(warm=False)
    segment = session.segment_near(args.near)
    points = len(session.skin_before) * (args.layers + 1)  # a column of points per skin point
    print(f"plan {args.plan}, {args.layers} layers, {points} points: prepared in {prepared:.2f} s; "
          "scanned state "
          f"predicted in {first['seconds']:.2f} s ({first['iterations']} steps)")
    print("| nudge | moved mm | predict s | Newton steps | factorisations | lagged | lagged CG | "
          "assembly / factorisation / solve / line search s | residual N | then prepared s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    times = []
    for k in range(1, args.nudges + 1):
        translate = [k * c for c in args.step]
        refused = session.move(segment, translate_mm=translate)
        if refused:
            raise SystemExit(f"nudge {k} refused: {refused}")
        result = session.predict(warm=True)
        times.append(result["seconds"])
        prepared = 0.0 if args.no_prepare else session.prepare_next_nudge()
        print(f"| {k} | {translate} | {result['seconds']:.3f} | {result['iterations']} | "
              f"{result['factorizations']} | {result['lagged_steps']} | "
              f"{sum(step['lagged_iterations'] for step in result['steps'])} | "
              + " / ".join(f"{v:.3f}" for v in result["stage_seconds"].values())
              + f" | {result['residual_force']:.2g} | {prepared:.3f} |")
    print(f"median nudge: {statistics.median(times):.3f} s")


if __name__ == "__main__":
    main()
