"""A reinforcement-learning task with the Gymnasium API (reset(seed) -> obs, info;
step(action) -> obs, reward, terminated, truncated, info), without depending on gymnasium
(not in Debian): its spaces are small classes with the same attributes (shape, low, high,
dtype, sample, contains).

CutAlongLineEnv: the scalpel cuts through the default liver block (4 x 6 x 4 cm, mass-spring,
held at its left and right faces) along y; the target is a line x = x_target across the block,
drawn anew for each episode's seed. Each action moves the blade by (dx, dy) (at most
`max_step` m each); the reward is minus the tip's distance to the line (m), plus a bonus for
reaching the far side. An episode resets through Simulation.restore, so it costs a state
restore, not a scene build, and is deterministic for a seed."""

import numpy as np

from ._incise import Simulation

# The default scene (scenes/default.json) without its scripted blade: the agent moves it.
_BLOCK_SCENE = {
    "description": "CutAlongLineEnv: the default liver block, cut by an agent's blade",
    "mesh": {"box": {"cells": [4, 6, 4], "size": [0.04, 0.06, 0.04], "tets_per_cell": 6}},
    "material": "liver",
    "model": {"type": "mass-spring", "spring_damping_ratio": 0.3, "prestrain": 0.05},
    "damping": {"penalty": 10.0},
    "integrator": {"type": "rk4-hierarchical", "dt": 0.01, "iterations": 8, "max_depth": 4},
    "fixed": [{"box": [[-1, -1, -1], [0.0001, 1, 1]]}, {"box": [[0.0399, -1, -1], [1, 1, 1]]}],
    "gravity": [0, 0, -9.81],
    "cutter": {"type": "subdivision"},
    "frame_dt": 0.01,
    "frames": 100,
}


class Box:
    """A box of real vectors: the space of Gymnasium's spaces.Box, without gymnasium."""

    def __init__(self, low, high, shape, dtype=np.float64):
        self.shape = tuple(shape)
        self.dtype = np.dtype(dtype)
        self.low = np.broadcast_to(np.asarray(low, dtype=self.dtype), self.shape).copy()
        self.high = np.broadcast_to(np.asarray(high, dtype=self.dtype), self.shape).copy()

    def sample(self, rng=None):
        rng = rng if rng is not None else np.random.default_rng()
        if self.dtype.kind == "u":
            return rng.integers(self.low, self.high, endpoint=True, dtype=self.dtype)
        low = np.where(np.isfinite(self.low), self.low, -1.0)
        high = np.where(np.isfinite(self.high), self.high, 1.0)
        return rng.uniform(low, high).astype(self.dtype)

    def contains(self, value):
        value = np.asarray(value)
        return value.shape == self.shape and bool(np.all(value >= self.low) and
                                                  np.all(value <= self.high))

    def __repr__(self):
        return f"Box({self.low.min()}, {self.high.max()}, {self.shape}, {self.dtype})"


class CutAlongLineEnv:
    """Cut along a target line. observation="state" (default): a float64 vector of the blade's
    tip (x, y, z in m, rest frame), the target's x (m), the tip's signed distance to the line
    (m), and the current positions of the `nearby` vertices nearest the tip at reset, relative
    to the tip (m, flattened). observation="pixels": an (height, width, 3) uint8 picture.

    action: (dx, dy) in [-1, 1], scaled by max_step (m). reward: minus the distance to the line
    (m) after the move, plus 0.05 for reaching the block's far side (terminated). truncated
    after max_steps actions."""

    metadata = {"render_modes": ["rgb_array"]}

    def __init__(self, observation="state", max_steps=40, max_step=0.002, frames_per_action=1,
                 nearby=16, width=96, height=72):
        if observation not in ("state", "pixels"):
            raise ValueError(f"observation: {observation!r} is neither 'state' nor 'pixels'")
        self.observation_kind = observation
        self.max_steps = int(max_steps)
        self.max_step = float(max_step)
        self.frames_per_action = int(frames_per_action)
        self.nearby = int(nearby)
        self.width, self.height = int(width), int(height)
        self.render_mode = "rgb_array"
        self.sim = Simulation(_BLOCK_SCENE)
        self._start = self.sim.save_state()
        self.action_space = Box(-1.0, 1.0, (2,))
        if observation == "state":
            self.observation_space = Box(-np.inf, np.inf, (5 + 3 * self.nearby,))
        else:
            self.observation_space = Box(0, 255, (self.height, self.width, 3), np.uint8)
        self._rng = np.random.default_rng()
        self._tip = np.zeros(3)
        self._target_x = 0.02
        self._neighbours = np.arange(self.nearby)
        self._steps = 0

    # The blade spans the block's height (z from -1.2 to 6 cm) like the default scene's.
    _Z_LOW, _Z_HIGH, _Y_START, _Y_END = -0.012, 0.06, -0.008, 0.064

    def reset(self, seed=None, options=None):
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self.sim.restore(self._start)
        self._target_x = float(self._rng.uniform(0.012, 0.028))
        start_x = self._target_x + float(self._rng.uniform(-0.004, 0.004))
        self._tip = np.array([start_x, self._Y_START, self._Z_LOW])
        self._steps = 0
        rest = self.sim.rest_positions
        order = np.argsort(np.linalg.norm(rest[:, :2] - self._tip[:2], axis=1), kind="stable")
        self._neighbours = order[: self.nearby]
        self.sim.set_blade(self._tip, self._base())
        self.sim.step(self.frames_per_action)
        return self._observation(), self._info()

    def step(self, action):
        action = np.clip(np.asarray(action, dtype=np.float64).reshape(2), -1.0, 1.0)
        self._tip[0] = np.clip(self._tip[0] + self.max_step * action[0], 0.001, 0.039)
        self._tip[1] = self._tip[1] + self.max_step * action[1]
        self.sim.set_blade(self._tip, self._base())
        self.sim.step(self.frames_per_action)
        self._steps += 1
        distance = abs(self._tip[0] - self._target_x)
        terminated = bool(self._tip[1] >= self._Y_END)
        truncated = bool(not terminated and self._steps >= self.max_steps)
        reward = -distance + (0.05 if terminated else 0.0)
        return self._observation(), float(reward), terminated, truncated, self._info()

    def render(self):
        return self.sim.render(self.width, self.height)

    def close(self):
        self.sim = None

    def _base(self):
        return np.array([self._tip[0], self._tip[1], self._Z_HIGH])

    def _observation(self):
        if self.observation_kind == "pixels":
            return self.render()
        nearby = self.sim.positions[self._neighbours] - self._tip
        head = [*self._tip, self._target_x, self._tip[0] - self._target_x]
        return np.concatenate([np.array(head), nearby.reshape(-1)])

    def _info(self):
        return {"target_x": self._target_x, "tip": self._tip.copy(), "steps": self._steps,
                "tets": len(self.sim.tets), "frame": self.sim.frame}
