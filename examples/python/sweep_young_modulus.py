"""Sweep Young's modulus of a 10 cm cube of soft tissue (corotational FEM, held at its base,
sagging under gravity) on a local Dask cluster and plot the sag against the modulus.

    PYTHONPATH=build/release/python python3 examples/python/sweep_young_modulus.py [--cells N] [--workers W]
"""

import argparse
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import incise  # noqa: E402



def main():
    # Dask's local cluster starts worker processes that import this file again: the work runs
    # under the __main__ guard only.
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=10, help="cells along each side")
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=pathlib.Path, default=pathlib.Path("out/python"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    scene = {
        "mesh": {"box": {"cells": [args.cells] * 3, "size": [0.1, 0.1, 0.1]}},
        "material": {"young_modulus": 3000, "poisson_ratio": 0.45, "density": 1000},
        "model": {"type": "corotational-fem"},
        "integrator": {"type": "backward-euler", "dt": 0.01},
        "fixed": [{"box": [[-1, -1, -1], [1, 1, 0.0001]]}],
        "gravity": [0, 0, -9.81],
        "frames": args.frames,
    }
    moduli = [1500.0, 3000.0, 6000.0, 12000.0]
    table = incise.sweep(scene, {"material.young_modulus": moduli}, workers=args.workers)
    print(table[["material.young_modulus", "max_displacement", "rx", "error"]].to_string(index=False))
    figure, axes = plt.subplots(figsize=(5, 4))
    axes.loglog(table["material.young_modulus"], 1e3 * table["max_displacement"], "o-")
    axes.set_xlabel("Young's modulus (Pa)")
    axes.set_ylabel("largest displacement (mm)")
    figure.tight_layout()
    figure.savefig(args.out / "sag_vs_modulus.png", dpi=100)


if __name__ == "__main__":
    main()
