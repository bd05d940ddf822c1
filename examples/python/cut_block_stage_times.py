"""Cut the default liver block (the seed's Fig. 10) and plot where each frame's time goes:
collision detection (cd), topology and geometry changes (gc), relaxation (rx), output (rd).

    PYTHONPATH=build/release/python python3 examples/python/cut_block_stage_times.py [--frames N] [--out DIR]
"""

import argparse
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import incise  # noqa: E402

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--frames", type=int, default=150)
parser.add_argument("--out", type=pathlib.Path, default=pathlib.Path("out/python"))
args = parser.parse_args()
args.out.mkdir(parents=True, exist_ok=True)

sim = incise.Simulation()  # the default scene: scenes/default.json, built in
frames = sim.step(args.frames)
stages = ("cd", "gc", "rx", "rd")
times = {stage: [1e3 * getattr(f, stage) for f in frames] for stage in stages}
bottom = [0.0] * len(frames)
figure, axes = plt.subplots(figsize=(8, 4))
for stage in stages:
    axes.bar([f.frame for f in frames], times[stage], bottom=bottom, width=1.0, label=stage)
    bottom = [b + t for b, t in zip(bottom, times[stage])]
axes.set_xlabel("frame")
axes.set_ylabel("ms")
axes.set_title(f"default block: {frames[0].tets} -> {frames[-1].tets} tetrahedra")
axes.legend()
figure.tight_layout()
figure.savefig(args.out / "stage_times.png", dpi=100)
cut = sum(f.edited for f in frames)
print(f"{len(frames)} frames, {cut} of them edited the mesh, {frames[-1].tets} tetrahedra; "
      f"mean rx {sum(times['rx']) / len(frames):.2f} ms; plot: {args.out / 'stage_times.png'}")
