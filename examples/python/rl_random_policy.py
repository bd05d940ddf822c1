"""The cutting task with the Gymnasium API, driven by a random policy for a few episodes: each
episode resets through a state restore and is deterministic for its seed.

    PYTHONPATH=build/release/python python3 examples/python/rl_random_policy.py [--episodes N]
"""

import argparse
import time

import numpy as np

import incise

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--episodes", type=int, default=5)
parser.add_argument("--max-steps", type=int, default=40)
args = parser.parse_args()

env = incise.CutAlongLineEnv(max_steps=args.max_steps)
rng = np.random.default_rng(0)
for episode in range(args.episodes):
    started = time.perf_counter()
    obs, info = env.reset(seed=episode)
    reset_ms = 1e3 * (time.perf_counter() - started)
    total, steps = 0.0, 0
    while True:
        action = env.action_space.sample(rng)
        action[1] = abs(action[1])  # forward, at a random pace
        obs, reward, terminated, truncated, info = env.step(action)
        total += reward
        steps += 1
        if terminated or truncated:
            break
    print(f"episode {episode}: target x {1e3 * info['target_x']:.1f} mm, {steps} steps, "
          f"return {total:.4f}, {info['tets']} tetrahedra at the end, reset {reset_ms:.1f} ms")
