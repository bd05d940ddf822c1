#!/usr/bin/env python3
"""The layered tissue as layers are added, with both elasticities: a plan run with 1 to 8
layers (everything else as written), through `incise plan`. Prints the seed's table (points,
springs, prisms or tetrahedra, peak memory, Newton steps, seconds) with the skin's largest and
mean displacement, so convergence (or drift) as layers are added shows in one table.

usage: bench/plan_layers.py [--incise build/ci/apps/incise] [--plan scenes/plan_neonatal_head.json]
                            [--layers 1,2,3,4,6,8] [--elasticity continuum,springs]
                            [--repeats 1]

Times are the median of --repeats runs of each plan.
"""
import argparse
import json
import os
import statistics
import subprocess
import tempfile


def run(incise, plan, out):
    """The plan's report and the run's peak memory (MB)."""
    child = subprocess.Popen([incise, "plan", plan, "--out", out], stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(child.pid, 0)
    if status != 0:
        raise SystemExit(f"incise plan {plan} failed ({status})")
    with open(os.path.join(out, "report.json")) as f:
        return json.load(f), usage.ru_maxrss / 1024.0  # KiB -> MB


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--incise", default="build/ci/apps/incise")
    parser.add_argument("--plan", default="scenes/plan_neonatal_head.json")
    parser.add_argument("--layers", default="1,2,3,4,6,8")
    parser.add_argument("--elasticity", default="continuum,springs")
    parser.add_argument("--repeats", type=int, default=1)
    args = parser.parse_args()
    plan_dir = os.path.dirname(os.path.abspath(args.plan))
    with open(args.plan) as f:
        base = json.load(f)
    print("| elasticity | layers | points | springs | elements | peak MB | steps (factorisations) "
          "| equilibrium s | predict s | largest mm | mean mm | converged |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as work:
        for elasticity in args.elasticity.split(","):
            for layers in [int(n) for n in args.layers.split(",")]:
                plan = dict(base, layers=layers, elasticity=elasticity)
                if elasticity == "springs":
                    plan.pop("skin_thickness", None)
                # The plan's relative paths stay valid: the copy sits in the plan's folder.
                path = os.path.join(plan_dir, f".plan_layers_{elasticity}_{layers}.json")
                with open(path, "w") as f:
                    json.dump(plan, f)
                try:
                    runs = [run(args.incise, path, os.path.join(work, f"{elasticity}{layers}"))
                            for _ in range(args.repeats)]
                finally:
                    os.remove(path)
                report, peak = runs[-1]
                elements = report.get("tetrahedra", report["prisms"])
                steps = f"{report['iterations']} ({report.get('newton', {}).get('factorizations', '-')})"
                eq = statistics.median(r["seconds"]["equilibrium"] for r, _ in runs)
                predict = statistics.median(r["seconds"]["predict"] for r, _ in runs)
                print(f"| {elasticity} | {layers} | {report['points']:,} | {report['springs']:,} | "
                      f"{elements:,} {'tets' if 'tetrahedra' in report else 'prisms'} | "
                      f"{peak:.0f} | {steps} | {eq:.2f} | {predict:.2f} | "
                      f"{report['max_displacement']:.3f} | {report['mean_displacement']:.4f} | "
                      f"{'yes' if report['converged'] else 'no'} |", flush=True)


if __name__ == "__main__":
    main()
