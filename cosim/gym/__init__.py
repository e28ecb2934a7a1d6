"""A Gymnasium environment around cosim's closed loop (optional extra: ``pip install
'cosim-testbed[gym]'``, or ``.[gym]`` from a checkout).

    import gymnasium
    import cosim.gym

    cosim.gym.register_envs()                 # registers cosim/LaneChange-v0
    env = gymnasium.make("cosim/LaneChange-v0")
    observation, info = env.reset(seed=0)

The environment is :class:`cosim.gym.env.CosimEnv`; its observation, action and reward are
documented there. Registration is a function call, not an import side effect.
"""

from __future__ import annotations

ENV_IDS: dict[str, str] = {"cosim/LaneChange-v0": "lane-change"}
"""Registered environment ids and the built-in scenario each one runs."""


def register_envs() -> None:
    """Register :data:`ENV_IDS` with Gymnasium (again is harmless)."""
    import gymnasium

    for env_id, scenario in ENV_IDS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point="cosim.gym.env:CosimEnv",
                               kwargs={"scenario": scenario})
