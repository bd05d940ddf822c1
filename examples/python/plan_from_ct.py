"""Plan from the example CT (scenes/plan_headsq.json): the face predicted after the bone move,
its displacement plotted on the skin.

    PYTHONPATH=build/release/python python3 examples/python/plan_from_ct.py [--plan PLAN] [--out DIR]
"""

import argparse
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import incise  # noqa: E402

here = pathlib.Path(__file__).resolve().parent
parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--plan", type=pathlib.Path, default=here.parents[1] / "scenes" / "plan_headsq.json")
parser.add_argument("--out", type=pathlib.Path, default=pathlib.Path("out/python/plan"))
args = parser.parse_args()


def progress(stage, fraction):
    print(f"\r{stage:<24} {100 * fraction:5.1f} %", end="", flush=True)


result = incise.plan(args.plan, out_dir=args.out, progress=progress)
print()
before, after = result["skin_before"], result["skin_after"]
moved_mm = 1e3 * np.linalg.norm(after - before, axis=1)
figure = plt.figure(figsize=(6, 5))
axes = figure.add_subplot(projection="3d")
points = axes.scatter(before[:, 0], before[:, 1], before[:, 2], c=moved_mm, s=2, cmap="viridis")
figure.colorbar(points, label="predicted skin displacement (mm)")
axes.set_title(f"{result['points']} points, largest move {result['max_displacement_mm']:.2f} mm")
figure.savefig(args.out / "predicted_displacement.png", dpi=100)
print(f"skin {len(before)} points, largest displacement {moved_mm.max():.2f} mm, "
      f"{result['seconds']:.1f} s; files in {result['out_dir']}")
