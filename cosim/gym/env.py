"""``CosimEnv``: one scenario of cosim as a Gymnasium environment (Towers et al., "Gymnasium:
a standard interface for reinforcement learning environments", arXiv:2407.17032, 2024).

The loop is the run's own (:class:`cosim.simulation.runner.RunState`): MuJoCo plant, noisy
sensors, the filter, the actuator delay line, outcome events. The agent replaces the tracker:
one :meth:`CosimEnv.step` is one control period (``sim.control_period_s``).

Observation (``float64``, :data:`OBS_NAMES`, bounded by :data:`OBS_BOUNDS`): what a
tracker may know, never the truth: the filter's estimate of ``vx_mps``, ``vy_mps``,
``yaw_rate_radps``, ``steer_rad``, ``ax_mps2``; the estimated position relative to the path
(``lateral_error_m``, positive left of it, ``heading_error_rad``); the reference speed
there; the path's curvature at :data:`PREVIEW_M` ahead.

Action (``float32`` Box ``[-1, 1]^2``): ``[steer, accel]`` normalised, ``steer_rad = a0
tracker.max_steer_rad`` and ``accel_mps2`` affine from ``[-1, 1]`` onto
``[tracker.accel_min_mps2, tracker.accel_max_mps2]``; values outside are clipped, an action
of another shape or with NaN is a ``ValueError`` (:meth:`CosimEnv.command_of`).

Reward per step: ``-(cte_m^2 + heading_err_rad^2 + 0.1 (v - v_ref)^2 + 0.1 steer_rate^2)``
with the simulator's true tracking errors (the reward is the experimenter's, not the
agent's, knowledge) and ``steer_rate`` the change of commanded steering per second.
Terminated on an outcome event (off the road, spun, rolled over, end of the path);
truncated at ``sim.duration_s``. ``info["metrics"]`` at the episode's end holds the run's
metrics (:data:`cosim.simulation.metric_keys.METRIC_KEYS`), as ``cosim run`` prints them.
``reset(seed=s)`` runs seed ``s`` (the same noise as ``cosim run --seed s``).
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np

from cosim.core.records import Command, Estimate, Plan
from cosim.log.recorder import McapRecorder, NoLog
from cosim.simulation.run_control import WallClock
from cosim.simulation.runner import RunState, finish_run
from cosim.simulation.scenario_config import ScenarioConfig, load_config
from tracker.paths.reference_path import ReferencePath

ESTIMATE_NAMES = ("vx_mps", "vy_mps", "yaw_rate_radps", "steer_rad", "ax_mps2")
PREVIEW_M = (0.0, 10.0, 20.0, 30.0)
OBS_NAMES: tuple[str, ...] = (
    *ESTIMATE_NAMES, "lateral_error_m", "heading_error_rad", "ref_speed_mps",
    *(f"curvature_{int(d)}m_1pm" for d in PREVIEW_M),
)
"""The observation vector's layout."""

OBS_BOUNDS: dict[str, float] = {
    "vx_mps": 100.0,           # 360 km/h, beyond any car of the scenarios
    "vy_mps": 50.0,
    "yaw_rate_radps": 10.0,    # a spinning car turns at a few rad/s
    "steer_rad": 1.6,          # the road wheel's mechanical limit is below pi/2
    "ax_mps2": 50.0,           # 5 g: only a crash is harder
    "lateral_error_m": 100.0,  # a car this far off the path is long off the road
    "heading_error_rad": float(np.pi),
    "ref_speed_mps": 100.0,
    **{f"curvature_{int(d)}m_1pm": 1.0 for d in PREVIEW_M},  # a 1 m radius
}
"""Each observation lies in ``[-bound, bound]`` (``ref_speed_mps`` in ``[0, bound]``): a
value beyond (a diverging filter, a car far off its path) is clipped to it, so the
observation space is finite, as learning code expects (Gymnasium's checker warns on
infinite bounds)."""

TERMINAL_EVENTS = ("off_road", "spun", "rolled_over", "end_of_path")


class _ActionTracker:
    """The tracker seat of the loop, filled by the agent's last action."""

    def __init__(self) -> None:
        self.command = Command(0.0, 0.0, 0.0)

    def step(self, t_s: float, estimate: Estimate,
             reference: ReferencePath) -> tuple[Command, Plan]:
        command = dataclasses.replace(self.command, t_s=t_s)
        plan = Plan(t_s=t_s, dt_s=0.0, state_names=(), states=np.zeros((1, 0)),
                    input_names=("accel_mps2", "steer_rad"),
                    inputs=np.array([[command.accel_mps2, command.steer_rad]]), cost=0.0,
                    solve_time_s=0.0, iterations=0, status="agent", success=True,
                    fallback=False)
        return command, plan


class CosimEnv(gymnasium.Env[np.ndarray, np.ndarray]):
    """A cosim scenario as a Gymnasium environment (see the module docstring)."""

    metadata = {"render_modes": []}

    def __init__(self, scenario: str = "lane-change", overrides: tuple[str, ...] = (),
                 log_dir: str | Path | None = None) -> None:
        self.base_config: ScenarioConfig = load_config(scenario, overrides=list(overrides))
        self.log_dir = None if log_dir is None else Path(log_dir)
        tracker = self.base_config.tracker
        self._steer_max_rad = tracker.max_steer_rad
        self._accel_mid = 0.5 * (tracker.accel_max_mps2 + tracker.accel_min_mps2)
        self._accel_half = 0.5 * (tracker.accel_max_mps2 - tracker.accel_min_mps2)
        self.action_space = gymnasium.spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        high = np.array([OBS_BOUNDS[name] for name in OBS_NAMES])
        low = np.where(np.array(OBS_NAMES) == "ref_speed_mps", 0.0, -high)
        self.observation_space = gymnasium.spaces.Box(low, high, dtype=np.float64)
        self._state: RunState | None = None
        self._recorder: Any = None
        self._k = 0
        self._episode = 0
        self._last_steer_rad = 0.0
        self._clock = WallClock(0.0, 0.0)
        self.estimate: Estimate | None = None
        """The filter's estimate at the current control step (what a tracker would see)."""

    @property
    def reference(self) -> ReferencePath:
        """The episode's reference path."""
        assert self._state is not None, "call reset() first"
        return self._state.reference

    def command_of(self, action: np.ndarray) -> Command:
        """The command an action stands for (clipped to the action space).

        An action of another shape, or with a NaN or infinite entry, is a ``ValueError``
        naming it: clipping would hide an agent's bug (NaN passes through ``clip`` and came
        out as a NaN brake torque deep in the plant)."""
        try:
            a = np.asarray(action, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"action {action!r}: expected 2 numbers [steer, accel] in "
                             "[-1, 1]") from None
        if a.shape != self.action_space.shape:
            raise ValueError(f"action of shape {a.shape}: expected shape "
                             f"{self.action_space.shape}, [steer, accel] in [-1, 1]")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"action {a.tolist()}: expected finite numbers [steer, accel] "
                             "in [-1, 1] (the agent produced NaN or infinity)")
        a = np.clip(a, -1.0, 1.0)
        return Command(0.0, self._accel_mid + self._accel_half * float(a[1]),
                       self._steer_max_rad * float(a[0]))

    def action_of(self, command: Command) -> np.ndarray:
        """The action of a command (a tracker as the policy)."""
        return np.array([command.steer_rad / self._steer_max_rad,
                         (command.accel_mps2 - self._accel_mid) / self._accel_half],
                        dtype=np.float32).clip(-1.0, 1.0)

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self._close_episode()
        called_s = time.perf_counter()
        run_seed = seed if seed is not None else int(self.np_random.integers(2**31))
        config = dataclasses.replace(self.base_config, seed=run_seed)
        self._episode += 1
        if self.log_dir is not None:
            path = self.log_dir / f"{config.name}-seed{run_seed}-episode{self._episode}.mcap"
            self._recorder = McapRecorder(path, epoch_ns=config.sim.epoch_ns)
        else:
            self._recorder = NoLog()
        self._state = RunState(config, self._recorder, _ActionTracker())
        self._recorder.publish()
        self._k, self._last_steer_rad = 0, 0.0
        self._clock = WallClock(called_s, time.perf_counter())
        self._advance_to_control()
        return self._observation(), {"t_s": 0.0}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        state = self._state
        assert state is not None, "call reset() first"
        command = self.command_of(action)
        assert isinstance(state.tracker, _ActionTracker)
        state.tracker.command = command
        events_before = len(state.monitor.events)
        ended = not self._advance_to_control(observed=True)
        m = state.metrics
        ref_speed = m.last_ref_speed_mps
        speed_err = 0.0 if ref_speed is None else state.truth.speed_mps - ref_speed
        steer_rate = (command.steer_rad - self._last_steer_rad) / state.config.sim.control_period_s
        self._last_steer_rad = command.steer_rad
        reward = -(m.last_cte_m ** 2 + m.last_heading_err_rad ** 2 + 0.1 * speed_err ** 2
                   + 0.1 * steer_rate ** 2)
        new_events = state.monitor.events[events_before:]
        terminated = any(e.kind in TERMINAL_EVENTS for e in new_events)
        info: dict[str, Any] = {"t_s": self._k * state.clock.dt_s,
                                "events": [e.kind for e in new_events]}
        observation = self._observation()
        if terminated or ended:  # an event ends the episode early: its kind is the outcome
            info["metrics"] = self._close_episode(completed=not terminated, abort="")
        return observation, float(reward), terminated, ended and not terminated, info

    def _advance_to_control(self, observed: bool = False) -> bool:
        """Run to the next control instant (the run's own :meth:`RunState.advance`, from
        the current one, whose log and sensing are ``observed`` already); False at the
        end of the run."""
        state = self._state
        assert state is not None
        self._k, ended = state.advance(self._k, observed=observed, pause_at_control=True)
        if ended:
            return False
        k = self._k
        self.estimate = state.current_estimate(k * state.clock.dt_s)
        return True

    def _observation(self) -> np.ndarray:
        assert self._state is not None and self.estimate is not None
        estimate, reference = self.estimate, self._state.reference
        projection = reference.project(estimate["x_m"], estimate["y_m"])
        heading = estimate["yaw_rad"] - projection.path_yaw_rad
        preview = reference.sample(projection.s_m + np.asarray(PREVIEW_M))
        values = [estimate[name] for name in ESTIMATE_NAMES] + [
            projection.lateral_error_m, float(np.arctan2(np.sin(heading), np.cos(heading))),
            reference.speed_ref_at(projection.s_m, estimate.t_s),
            *preview["curvature_1pm"].tolist()]
        observation = np.asarray(values, dtype=np.float64)
        # A NaN (a filter that diverged) becomes the bound's middle, 0: still in the space.
        observation = np.nan_to_num(observation, nan=0.0)
        return np.clip(observation, self.observation_space.low, self.observation_space.high)

    def _close_episode(self, completed: bool = False,
                       abort: str = "interrupted") -> dict[str, Any] | None:
        """Finish the running episode's log (one left unfinished by ``reset`` or ``close``:
        ``interrupted``); its metrics (None when none was running)."""
        if self._state is None:
            return None
        metrics = finish_run(self._state, self._clock, completed, abort, abort)
        self._recorder.close()
        self._state = None
        return metrics

    def close(self) -> None:
        self._close_episode()
        super().close()
