"""Environment steps per second of ``cosim/LaneChange-v0``: one environment, and a vector
of several in subprocesses (``gymnasium.make_vec``, ``vectorization_mode="async"``).

    .venv/bin/python bench/gym_steps.py [--steps 2000] [--envs 2]

Two policies: random actions (episodes end early, off the road, so resets count), and a
proportional steering law on the observation that keeps the car on the path (steps are
the loop's own cost). A step is one control period (50 ms of simulated time); the figure
is wall-clock steps per second including resets, and for the vector env the steps of all
its cars.
"""

from __future__ import annotations

import argparse
import time

import gymnasium
import numpy as np

import cosim.gym
from cosim.gym.env import OBS_NAMES


def steer_to_path(observations: np.ndarray) -> np.ndarray:
    """Steer against the lateral and heading errors; a light throttle."""
    obs = np.atleast_2d(observations)
    lateral = obs[:, OBS_NAMES.index("lateral_error_m")]
    heading = obs[:, OBS_NAMES.index("heading_error_rad")]
    steer = np.clip(-0.5 * lateral - 1.5 * heading, -1.0, 1.0)
    actions = np.stack([steer, np.full_like(steer, 0.55)], axis=1).astype(np.float32)
    return actions if np.ndim(observations) == 2 else actions[0]


def single(steps: int, policy: str) -> float:
    env = gymnasium.make("cosim/LaneChange-v0")
    env.action_space.seed(0)
    observation, _ = env.reset(seed=0)
    episode = 0
    start = time.perf_counter()
    for _ in range(steps):
        action = env.action_space.sample() if policy == "random" else steer_to_path(observation)
        observation, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            episode += 1
            observation, _ = env.reset(seed=episode)
    rate = steps / (time.perf_counter() - start)
    env.close()
    return rate


def vector(steps: int, envs: int, policy: str) -> float:
    vec = gymnasium.make_vec("cosim/LaneChange-v0", num_envs=envs, vectorization_mode="async")
    vec.action_space.seed(0)
    observations, _ = vec.reset(seed=list(range(envs)))
    start = time.perf_counter()
    for _ in range(steps // envs):
        actions = vec.action_space.sample() if policy == "random" else steer_to_path(observations)
        observations, *_ = vec.step(actions)  # sub-envs reset themselves at an episode's end
    rate = (steps // envs) * envs / (time.perf_counter() - start)
    vec.close()
    return rate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--envs", type=int, default=2)
    options = parser.parse_args()
    cosim.gym.register_envs()
    for policy in ("random", "steer-to-path"):
        one = single(options.steps, policy)
        many = vector(options.steps, options.envs, policy)
        print(f"{policy:>14}: one env {one:7.1f} steps/s; {options.envs} envs async "
              f"{many:7.1f} steps/s (x{many / one:.2f}); {options.steps} steps each")


if __name__ == "__main__":
    main()
