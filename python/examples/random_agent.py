"""A random agent on tensorscout/Explore-v0 (the shipped sample scene unless a scene is given).

Usage: python random_agent.py [SCENE] [ACTION_TYPE]
"""

from __future__ import annotations

import sys

import gymnasium as gym

import tensorscout

scene = sys.argv[1] if len(sys.argv) > 1 else tensorscout.SAMPLE_SCENE
action_type = sys.argv[2] if len(sys.argv) > 2 else "discrete"
env = gym.make("tensorscout/Explore-v0", scene=scene, action_type=action_type,
               config={"sim.budget_s": 120})
env.action_space.seed(0)
obs, info = env.reset(seed=0)
total, steps = 0.0, 0
while True:
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    total += float(reward)
    steps += 1
    if terminated or truncated:
        break
print(f"{steps} steps, {info['time_s']:.1f} s simulated: return {total:.2f} m³, "
      f"completeness {info['completeness']:.3f}, {info['collisions']} collisions, "
      f"{'terminated' if terminated else 'truncated'}")
env.close()
