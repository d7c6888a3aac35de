"""The Gymnasium environment: the checker, determinism, rewards, the vector form."""

from __future__ import annotations

from typing import Any, Dict, List, Tuple

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import tensorscout
from conftest import SMALL

CFG = {"sim.budget_s": 30}


@pytest.mark.parametrize("action_type", ["discrete", "velocity", "goal"])
def test_check_env(action_type: str) -> None:
    env = gym.make("tensorscout/Explore-v0", action_type=action_type, config=CFG)
    check_env(env.unwrapped, skip_render_check=True)


def episode(env: gym.Env[Any, Any], seed: int, actions: List[Any]) -> Tuple[List[Any], List[float]]:
    obs, _ = env.reset(seed=seed)
    frames, rewards = [obs], []
    for a in actions:
        obs, r, term, trunc, _ = env.step(a)
        frames.append(obs)
        rewards.append(r)
        if term or trunc:
            break
    return frames, rewards


def same(a: List[Dict[str, np.ndarray]], b: List[Dict[str, np.ndarray]]) -> bool:
    return len(a) == len(b) and all(
        all(np.array_equal(x[k], y[k]) for k in x) for x, y in zip(a, b)
    )


@pytest.mark.parametrize("action_type", ["discrete", "goal"])
def test_same_seed_and_actions_same_episode(action_type: str) -> None:
    env = tensorscout.ExploreEnv(SMALL, action_type=action_type, config=CFG, spawn="random")
    env.action_space.seed(3)
    actions = [env.action_space.sample() for _ in range(15)]
    f1, r1 = episode(env, 11, actions)
    f2, r2 = episode(env, 11, actions)
    assert same(f1, f2) and r1 == r2
    # Another seed starts elsewhere.
    f3, _ = episode(env, 12, actions[:1])
    assert not np.array_equal(f1[0]["pose"], f3[0]["pose"])


def test_discrete_actions_move_and_turn_by_their_amounts() -> None:
    env = tensorscout.ExploreEnv(SMALL, config=CFG)
    obs, _ = env.reset(seed=1)
    x0, y0, yaw0 = (float(v) for v in obs["pose"])
    obs, *_ = env.step(1)  # left 10 degrees
    assert float(obs["pose"][2]) - yaw0 == pytest.approx(np.radians(10), abs=1e-5)
    obs, *_ = env.step(2)
    obs, *_ = env.step(2)  # right 20 degrees in all
    assert float(obs["pose"][2]) - yaw0 == pytest.approx(-np.radians(10), abs=1e-5)
    before = obs["pose"].astype(np.float64)
    obs, reward, _, _, info = env.step(0)
    moved = np.hypot(*(obs["pose"][:2] - before[:2]))
    assert info["collisions"] == 0, "the start faces open floor"
    assert moved == pytest.approx(0.25, abs=1e-5)
    assert reward >= 0.0


def test_reward_is_the_newly_explored_volume() -> None:
    env = tensorscout.ExploreEnv(SMALL, action_type="goal", config=CFG, collision_penalty=0.0)
    _, info0 = env.reset(seed=1)
    total, vol = 0.0, info0["explored_volume_m3"]
    for a in [(3.0, 3.0), (1.0, 1.0), (4.0, 2.0)]:
        _, r, term, trunc, info = env.step(np.array(a, np.float32))
        total += r
        assert r == pytest.approx(info["explored_volume_m3"] - vol)
        vol = info["explored_volume_m3"]
        assert 0.0 <= info["completeness"] <= 1.0
        if term or trunc:
            break
    assert total > 0


def test_walls_block_and_cost_the_penalty() -> None:
    env = tensorscout.ExploreEnv(SMALL, action_type="velocity", config={"sim.budget_s": 200},
                                 collision_penalty=2.0)
    _, info = env.reset(seed=1)
    # Drive straight on until something is hit.
    for _ in range(1500):
        before = info["explored_volume_m3"]
        obs, r, term, trunc, info = env.step(np.array([1.0, 0.0], np.float32))
        if info["collisions"] > 0:
            break
    assert info["collisions"] == 1
    assert r == pytest.approx(info["explored_volume_m3"] - before - 2.0)
    pose = obs["pose"].copy()
    obs, *_ = env.step(np.array([1.0, 0.0], np.float32))
    assert np.array_equal(obs["pose"], pose), "a blocked move is not made"


def test_terminated_at_the_target_and_truncated_at_the_budget() -> None:
    env = tensorscout.ExploreEnv(SMALL, action_type="goal", config={"sim.budget_s": 3},
                                 completeness_target=1.0)
    env.reset(seed=1)
    trunc = term = False
    n = 0
    while not (term or trunc):
        _, _, term, trunc, info = env.step(np.array([3.0, 3.0], np.float32))
        n += 1
    assert trunc and not term and info["time_s"] == pytest.approx(3.0)
    with pytest.raises(tensorscout.UsageError, match="reset"):
        env.step(np.array([3.0, 3.0], np.float32))
    env2 = tensorscout.ExploreEnv(SMALL, action_type="discrete", completeness_target=0.01)
    env2.reset(seed=1)
    _, _, term, trunc, info = env2.step(1)
    assert term and not trunc and info["completeness"] >= 0.01


def test_bad_arguments_are_clear_errors() -> None:
    with pytest.raises(tensorscout.UsageError, match="action_type `jump`"):
        tensorscout.ExploreEnv(SMALL, action_type="jump")
    env = tensorscout.ExploreEnv(SMALL)
    env.reset(seed=0)
    with pytest.raises(tensorscout.UsageError, match="discrete action 7"):
        env.step(7)


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("action_type", ["discrete", "goal"])
def test_vector_env_equals_single_envs(threads: int, action_type: str) -> None:
    """A vector of 4 gives the episodes of 4 single environments, under 1 and 2 threads."""
    n, steps = 4, 12
    vec = tensorscout.ExploreVectorEnv(n, SMALL, action_type=action_type, config=CFG,
                                       spawn="random", num_threads=threads)
    vec.action_space.seed(5)
    actions = [vec.action_space.sample() for _ in range(steps)]
    obs, _ = vec.reset(seed=20)
    vframes = [obs]
    vrewards = []
    for a in actions:
        obs, r, term, trunc, _ = vec.step(a)
        assert not (term.any() or trunc.any())
        vframes.append(obs)
        vrewards.append(r)
    for i in range(n):
        env = tensorscout.ExploreEnv(SMALL, action_type=action_type, config=CFG, spawn="random")
        frames, rewards = episode(env, 20 + i, [a[i] for a in actions])
        assert same(frames, [{k: v[i] for k, v in f.items()} for f in vframes]), f"env {i}"
        assert rewards == [r[i] for r in vrewards]


def test_vector_env_with_more_threads_than_envs() -> None:
    """Threads beyond the number of environments stay idle; the episodes are the same."""
    runs = []
    for threads in (1, 5):
        vec = tensorscout.ExploreVectorEnv(2, SMALL, config=CFG, spawn="random", num_threads=threads)
        obs, _ = vec.reset(seed=3)
        for a in ([0, 1], [0, 0], [2, 0]):
            obs, r, *_ = vec.step(np.array(a))
        runs.append((obs["pose"].tolist(), obs["depth"].tobytes(), r.tolist()))
    assert runs[0] == runs[1]


def test_make_vec_uses_the_native_vector_env() -> None:
    envs = gym.make_vec("tensorscout/Explore-v0", num_envs=2, vectorization_mode="vector_entry_point",
                        config=CFG)
    assert isinstance(envs, tensorscout.ExploreVectorEnv)
    obs, info = envs.reset(seed=0)
    assert obs["depth"].shape[0] == 2
    obs, r, term, trunc, info = envs.step(envs.action_space.sample())
    assert r.shape == (2,) and "completeness" in info


def test_vector_env_resets_finished_envs_at_the_next_step() -> None:
    # A budget of 3 steps: reset takes one, a forward move two more.
    vec = tensorscout.ExploreVectorEnv(2, SMALL, config={"sim.budget_s": 0.3}, num_threads=1)
    vec.reset(seed=0)
    obs, r, term, trunc, info = vec.step(np.array([0, 0]))
    assert trunc.all() and info["time_s"] == pytest.approx([0.3, 0.3])
    obs, r, term, trunc, info = vec.step(np.array([0, 0]))
    assert not (term.any() or trunc.any()) and (r == 0).all()
    assert not info.get("_completeness", np.zeros(2, bool)).any()
    obs, r, term, trunc, info = vec.step(np.array([1, 1]))
    # A new episode: its reset step and the two steps of a 10° turn.
    assert info["time_s"] == pytest.approx([0.3, 0.3]) and trunc.all()
