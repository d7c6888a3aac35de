"""The Gymnasium environment ``tensorscout/Explore-v0`` and its native vector form.

Observations are a ``Dict``: ``depth`` (H, W, 1) float32 metres along the optical axis (0: no
reading), ``pose`` (x, y, yaw) float32, and ``map``, a robot-centred, axis-aligned crop of the map,
(S, S, 4) uint8 channels free/obstacle/unknown/frontier (0 or 1; row 0 is the lowest y).

Actions (``action_type``): ``"discrete"`` 0 forward 0.25 m, 1 turn left 10°, 2 turn right 10°;
``"velocity"`` a Box (v, w) within the robot's limits, held for one step of ``sim.dt_s``;
``"goal"`` a Box (x, y) in the world frame, driven to by the shared motion executor along the A*
path (one ``step`` is one goal). Under discrete and velocity actions a move that would touch the
scene is not made and counts as a collision.

Reward: the newly explored band volume in m³, minus ``collision_penalty`` per collision.
``terminated`` when completeness (against the ground truth's observable set) reaches
``completeness_target``; ``truncated`` when the budget (``sim.budget_s``) is spent.
"""

from __future__ import annotations

import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ._native import EnvCore, VecEnvCore

ENV_ID = "tensorscout/Explore-v0"

#: A small shipped scene (a furnished apartment), the default of the environments.
SAMPLE_SCENE = os.path.join(os.path.dirname(__file__), "data", "apartment_small.obj")

Config = Union[None, Dict[str, Any], str, "os.PathLike[str]"]
Spawn = Union[None, str, Sequence[float]]


def register() -> None:
    """Registers ``tensorscout/Explore-v0`` (done on import)."""
    if ENV_ID not in gym.registry:
        gym.register(
            id=ENV_ID,
            entry_point="tensorscout.env:ExploreEnv",
            vector_entry_point="tensorscout.env:ExploreVectorEnv",
        )


def _spaces(d: Dict[str, Any], action_type: str) -> Tuple[spaces.Dict, spaces.Space[Any]]:
    h, w = d["depth_shape"]
    s = d["crop_cells"]
    x0, y0, x1, y1 = d["bounds"]
    obs = spaces.Dict(
        {
            "depth": spaces.Box(0.0, float(d["max_range_m"]), (h, w, 1), np.float32),
            "pose": spaces.Box(
                np.array([x0, y0, -np.pi], np.float32),
                np.array([x1, y1, np.pi], np.float32),
                dtype=np.float32,
            ),
            "map": spaces.Box(0, 1, (s, s, 4), np.uint8),
        }
    )
    act: spaces.Space[Any]
    if action_type == "discrete":
        act = spaces.Discrete(3)
    elif action_type == "velocity":
        vmax, wmax = d["max_speed_mps"], d["max_turn_rate_rps"]
        act = spaces.Box(
            np.array([0.0, -wmax], np.float32), np.array([vmax, wmax], np.float32), dtype=np.float32
        )
    else:
        act = spaces.Box(
            np.array([x0, y0], np.float32), np.array([x1, y1], np.float32), dtype=np.float32
        )
    return obs, act


class ExploreEnv(gym.Env[Dict[str, np.ndarray], Any]):
    """One exploration as a Gymnasium environment (see the module doc)."""

    metadata: Dict[str, Any] = {"render_modes": []}

    def __init__(
        self,
        scene: Union[str, "os.PathLike[str]"] = SAMPLE_SCENE,
        action_type: str = "discrete",
        config: Config = None,
        spawn: Spawn = None,
        map_size_m: float = 8.0,
        completeness_target: float = 0.95,
        collision_penalty: float = 0.1,
        render_mode: Optional[str] = None,
    ) -> None:
        if render_mode is not None:
            raise ValueError(f"render_mode {render_mode!r}: this environment does not render")
        self._core = EnvCore(
            scene,
            action_type,
            config,
            spawn,
            map_size_m,
            completeness_target,
            collision_penalty,
        )
        self.settings: Dict[str, Any] = dict(self._core.describe())
        obs_space, self.action_space = _spaces(self.settings, action_type)
        self.observation_space = obs_space  # type: ignore[assignment]
        self.action_type = action_type

    def reset(
        self, *, seed: Optional[int] = None, options: Optional[Dict[str, Any]] = None
    ) -> Tuple[Dict[str, np.ndarray], Dict[str, Any]]:
        super().reset(seed=seed)
        obs, info = self._core.reset(seed)
        return obs, info

    def step(
        self, action: Any
    ) -> Tuple[Dict[str, np.ndarray], float, bool, bool, Dict[str, Any]]:
        return self._core.step(action)


def _seeds(seed: Union[None, int, Sequence[Optional[int]]], n: int) -> List[Optional[int]]:
    if seed is None:
        return [None] * n
    if isinstance(seed, (int, np.integer)):
        return [int(seed) + i for i in range(n)]
    seeds = list(seed)
    if len(seeds) != n:
        raise ValueError(f"seed: expected {n} seeds, got {len(seeds)}")
    return [None if s is None else int(s) for s in seeds]


class ExploreVectorEnv(VectorEnv[Dict[str, np.ndarray], np.ndarray, np.ndarray]):
    """``num_envs`` explorations stepped in parallel on ``num_threads`` threads (default: one per
    core) without the GIL. Episodes do not depend on the number of threads.
    Finished environments reset at their next step (Gymnasium's ``NEXT_STEP`` autoreset)."""

    metadata: Dict[str, Any] = {"autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        num_envs: int = 1,
        scene: Union[str, "os.PathLike[str]"] = SAMPLE_SCENE,
        action_type: str = "discrete",
        config: Config = None,
        spawn: Spawn = None,
        map_size_m: float = 8.0,
        completeness_target: float = 0.95,
        collision_penalty: float = 0.1,
        num_threads: Optional[int] = None,
        render_mode: Optional[str] = None,
    ) -> None:
        if render_mode is not None:
            raise ValueError(f"render_mode {render_mode!r}: this environment does not render")
        self._core = VecEnvCore(
            scene,
            num_envs,
            action_type,
            config,
            spawn,
            map_size_m,
            completeness_target,
            collision_penalty,
            None,
            num_threads,
        )
        self.num_envs = num_envs
        self.settings: Dict[str, Any] = dict(self._core.describe())
        self.single_observation_space, self.single_action_space = _spaces(
            self.settings, action_type
        )
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._autoreset = np.zeros(num_envs, dtype=np.bool_)

    def _infos(self, infos: List[Optional[Dict[str, Any]]]) -> Dict[str, Any]:
        out: Dict[str, Any] = {}
        for i, info in enumerate(infos):
            if info is not None:
                out = self._add_info(out, info, i)
        return out

    def reset(
        self,
        *,
        seed: Union[None, int, Sequence[Optional[int]]] = None,
        options: Optional[Dict[str, Any]] = None,
    ) -> Tuple[Dict[str, np.ndarray], Dict[str, Any]]:
        seeds = _seeds(seed, self.num_envs)
        super().reset(seed=seeds[0])
        obs, infos = self._core.reset(seeds, None)
        self._autoreset[:] = False
        return obs, self._infos(infos)

    def step(
        self, actions: Any
    ) -> Tuple[Dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, Dict[str, Any]]:
        auto = self._autoreset.copy()
        if auto.any():
            self._core.reset(None, auto.tolist())
        obs, rew, term, trunc, infos = self._core.step(actions, (~auto).tolist())
        terminated = np.array(term, dtype=np.bool_)
        truncated = np.array(trunc, dtype=np.bool_)
        self._autoreset = terminated | truncated
        return obs, np.array(rew, dtype=np.float64), terminated, truncated, self._infos(infos)
