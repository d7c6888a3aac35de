"""Speed of the Python package: run() against the command line, environment steps per second, and
vector-environment scaling from 1 to 2 threads. Prints a Markdown table (BENCHMARKS.md).

Usage: python python/benches/speed.py [--bin target/release/tensorscout] [--repeat 3]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import time
from pathlib import Path
from typing import Any, Callable, List

import numpy as np

import tensorscout

ROOT = Path(__file__).resolve().parents[2]
OFFICE = ROOT / "scenes/office_large.obj"
SCENE = ROOT / "scenes/apartment_small.obj"


def paired_medians(a: Callable[[], Any], b: Callable[[], Any], repeat: int) -> tuple[float, float]:
    """Median wall times of `a` and `b`, run alternately, so that a drift of the machine's speed
    falls on both alike."""
    ta: List[float] = []
    tb: List[float] = []
    for _ in range(repeat):
        for f, times in ((a, ta), (b, tb)):
            t = time.perf_counter()
            f()
            times.append(time.perf_counter() - t)
    return statistics.median(ta), statistics.median(tb)


def env_rate(num_envs: int, action_type: str, steps: int, threads: int | None) -> float:
    """Environment steps per second (all environments' steps), resets excluded."""
    cfg = {"sim.budget_s": 100000}
    if num_envs == 1:
        env = tensorscout.ExploreEnv(SCENE, action_type=action_type, config=cfg, spawn="random")
        env.action_space.seed(0)
        env.reset(seed=0)
        acts = [env.action_space.sample() for _ in range(steps)]
        t = time.perf_counter()
        for a in acts:
            _, _, term, trunc, _ = env.step(a)
            if term or trunc:
                env.reset()
        return steps / (time.perf_counter() - t)
    vec = tensorscout.ExploreVectorEnv(num_envs, SCENE, action_type=action_type, config=cfg,
                                       spawn="random", num_threads=threads)
    vec.action_space.seed(0)
    vec.reset(seed=0)
    acts = [vec.action_space.sample() for _ in range(steps)]
    t = time.perf_counter()
    for a in acts:
        vec.step(a)
    return num_envs * steps / (time.perf_counter() - t)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default=str(ROOT / "target/release/tensorscout"))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--planner", default="greedy")
    a = ap.parse_args()
    cli, py = paired_medians(
        lambda: subprocess.run(
            [a.bin, "explore", "--json", "--quiet", "--scene", str(OFFICE), "--planner", a.planner],
            check=True, capture_output=True),
        lambda: tensorscout.Simulation(OFFICE, planner=a.planner).run(),
        a.repeat)
    print(f"| run() vs CLI, office_large, {a.planner} | CLI {cli:.2f} s, run() {py:.2f} s: "
          f"{100 * (py / cli - 1):+.1f} % |")
    for action_type, steps in (("discrete", 300), ("goal", 30)):
        for n in (1, 2, 8):
            r = env_rate(n, action_type, steps if n == 1 else max(steps // n * 2, 4), None)
            print(f"| env steps/s, {action_type}, {'1 env' if n == 1 else f'vector of {n}'} | {r:.1f} |")
    for action_type, steps in (("discrete", 60), ("goal", 8)):
        one = env_rate(8, action_type, steps, 1)
        two = env_rate(8, action_type, steps, 2)
        print(f"| vector of 8, {action_type}: 1 → 2 threads | {one:.1f} → {two:.1f} steps/s: "
              f"{two / one:.2f}× |")


if __name__ == "__main__":
    main()
