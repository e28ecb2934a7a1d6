"""``cosim.gym``: the environment passes Gymnasium's checker, a random policy runs, and the
built-in MPC as the policy reproduces ``cosim run`` (same seed, same max CTE within 1 %)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

from gymnasium.utils.env_checker import check_env  # noqa: E402

import cosim  # noqa: E402
import cosim.gym  # noqa: E402
from cosim.gym.env import OBS_NAMES, CosimEnv  # noqa: E402
from cosim.log.reader import read_summary  # noqa: E402
from tracker.registry import make_tracker  # noqa: E402


@pytest.mark.slow
def test_registered_and_passes_the_checker() -> None:
    cosim.gym.register_envs()
    env = gymnasium.make("cosim/LaneChange-v0")
    assert isinstance(env.unwrapped, CosimEnv)
    check_env(env.unwrapped, skip_render_check=True)
    observation, _ = env.reset(seed=3)
    assert observation.shape == (len(OBS_NAMES),)
    env.close()


def test_a_random_policy_runs_and_logs(tmp_path: Path) -> None:
    env = CosimEnv(overrides=("sim.duration_s=3",), log_dir=tmp_path)
    env.action_space.seed(0)
    env.reset(seed=1)
    rewards, done, info = [], False, {}
    while not done:
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        rewards.append(reward)
        done = terminated or truncated
    assert all(r <= 0.0 for r in rewards) and len(rewards) <= 60
    assert "cte_max_m" in info["metrics"]
    (log,) = tmp_path.glob("*.mcap")
    summary = read_summary(log)
    assert not summary.truncated and summary.metrics is not None
    assert summary.metrics["cte_max_m"] == info["metrics"]["cte_max_m"]
    env.close()


@pytest.mark.slow
def test_the_mpc_as_policy_matches_cosim_run(tmp_path: Path) -> None:
    seed = 2
    config = cosim.load_config("lane-change", seed=seed)
    reference_run = cosim.run(config, out=tmp_path / "run.mcap")
    env = CosimEnv("lane-change")
    mpc = make_tracker(config.tracker, config.manoeuvre)
    env.reset(seed=seed)
    done, info = False, {}
    while not done:
        assert env.estimate is not None
        command, _ = mpc.step(env.estimate.t_s, env.estimate, env.reference)
        _, _, terminated, truncated, info = env.step(env.action_of(command))
        done = terminated or truncated
    assert not terminated
    expected = reference_run.metrics["cte_max_m"]
    assert info["metrics"]["cte_max_m"] == pytest.approx(expected, rel=0.01)
    assert np.isfinite(expected) and expected > 0.0


@pytest.mark.slow
def test_the_docs_random_policy_example_runs(tmp_path: Path) -> None:
    text = (Path(__file__).resolve().parents[2] / "docs" / "gym.md").read_text()
    first = re.findall(r"```python\n(.*?)```", text, flags=re.DOTALL)[0]
    done = subprocess.run([sys.executable, "-c", first], cwd=tmp_path, capture_output=True,
                          text=True, timeout=600, env={"MUJOCO_GL": "disable",
                                                       "PATH": "/usr/bin:/bin"})
    assert done.returncode == 0, done.stderr
    cte_max_m, outcome = done.stdout.split()
    assert float(cte_max_m) > 0.0 and outcome in ("ok", "off_road", "spun", "end_of_path")


@pytest.mark.parametrize(("action", "fragment"), [
    (np.zeros(3), "action of shape (3,): expected shape (2,)"),
    (np.zeros((1, 2)), "action of shape (1, 2): expected shape (2,)"),
    (np.array([np.nan, 0.0]), "action [nan, 0.0]: expected finite numbers"),
    (np.array([0.0, np.inf]), "action [0.0, inf]: expected finite numbers"),
    ("left", "action 'left': expected 2 numbers"),
])
def test_a_malformed_action_is_named_not_clipped_or_blamed_on_the_brake(
        action: object, fragment: str) -> None:
    env = CosimEnv(overrides=("sim.duration_s=1",))
    env.reset(seed=0)
    with pytest.raises(ValueError) as error:
        env.step(action)  # type: ignore[arg-type]
    assert fragment in str(error.value)
    env.step(np.array([2.0, -3.0], dtype=np.float32))  # out of the box: clipped, as before
    env.close()


def _steer_to_path(observations: np.ndarray) -> np.ndarray:
    """A policy of the observation alone: steer against the lateral and heading errors,
    hold a light throttle (works on a batch of observations or a single one)."""
    obs = np.atleast_2d(observations)
    lateral = obs[:, OBS_NAMES.index("lateral_error_m")]
    heading = obs[:, OBS_NAMES.index("heading_error_rad")]
    steer = np.clip(-0.5 * lateral - 1.5 * heading, -1.0, 1.0)
    actions = np.stack([steer, np.full_like(steer, 0.55)], axis=1).astype(np.float32)
    return actions if np.ndim(observations) == 2 else actions[0]


def test_observations_are_finite_and_inside_the_space() -> None:
    env = CosimEnv(overrides=("sim.duration_s=2",))
    space = env.observation_space
    assert np.all(np.isfinite(space.low)) and np.all(np.isfinite(space.high))
    observation, _ = env.reset(seed=4)
    done = False
    while not done:  # full left lock: the car leaves the path, errors grow
        assert space.contains(observation), observation
        observation, _, terminated, truncated, _ = env.step(np.array([1.0, 1.0], np.float32))
        done = terminated or truncated
    assert space.contains(observation)
    env.close()


@pytest.mark.slow
def test_a_vector_env_runs_several_cars_as_single_envs_would() -> None:
    """``gymnasium.make_vec`` in subprocesses: each car is the single environment of its
    seed, step for step."""
    cosim.gym.register_envs()
    steps, seeds = 30, (5, 6)
    vector = gymnasium.make_vec("cosim/LaneChange-v0", num_envs=2,
                                vectorization_mode="async")
    observations, _ = vector.reset(seed=list(seeds))
    batched = [observations]
    for _ in range(steps):
        observations, *_ = vector.step(_steer_to_path(observations))
        batched.append(observations)
    vector.close()
    for car, seed in enumerate(seeds):
        env = CosimEnv("lane-change")
        observation, _ = env.reset(seed=seed)
        single = [observation]
        for _ in range(steps):
            observation, *_ = env.step(_steer_to_path(observation))
            single.append(observation)
        env.close()
        np.testing.assert_array_equal(np.array(single), np.array(batched)[:, car])
    assert not np.array_equal(np.array(batched)[:, 0], np.array(batched)[:, 1])
