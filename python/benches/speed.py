"""Speed of the Python package: run() against the command line, environment steps per second, and
vector-environment scaling from 1 to 2 threads. Prints a Markdown table (BENCHMARKS.md).

These VMs drift by a fifth from one minute to the next, so every comparison is made in pairs timed
back to back, in the order A B B A, and the figure reported is the median of the pairs' ratios with
their range. Every rate is the median of several timings.

Usage: python python/benches/speed.py [--bin target/release/tensorscout] [--pairs 9] [--repeat 5]
       [--threads T]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import time
from pathlib import Path
from typing import Any, Callable, Dict, List, Tuple

ROOT = Path(__file__).resolve().parents[2]
OFFICE = ROOT / "scenes/office_large.obj"
SCENE = ROOT / "scenes/apartment_small.obj"


def _timed(f: Callable[[], Any], children: bool) -> Tuple[float, float]:
    """Wall and CPU seconds of `f()`: the CPU of this process, or of its children for a command."""
    who = resource.RUSAGE_CHILDREN if children else resource.RUSAGE_SELF
    r0, t0 = resource.getrusage(who), time.perf_counter()
    f()
    t1, r1 = time.perf_counter(), resource.getrusage(who)
    return t1 - t0, (r1.ru_utime + r1.ru_stime) - (r0.ru_utime + r0.ru_stime)


def paired(a: Callable[[], Any], a_child: bool, b: Callable[[], Any], b_child: bool,
           pairs: int) -> Dict[str, List[float]]:
    """Wall and CPU times of `a` and `b` in pairs, ordered A B, B A, A B, ..., so that a steady drift
    of the machine's speed falls on both alike."""
    out: Dict[str, List[float]] = {"a_wall": [], "b_wall": [], "a_cpu": [], "b_cpu": []}
    for i in range(pairs):
        order = ((a, a_child, "a"), (b, b_child, "b"))
        for f, child, key in order if i % 2 == 0 else order[::-1]:
            wall, cpu = _timed(f, child)
            out[f"{key}_wall"].append(wall)
            out[f"{key}_cpu"].append(cpu)
    return out


def ratio_summary(num: List[float], den: List[float]) -> str:
    r = sorted(n / d for n, d in zip(num, den))
    return f"{statistics.median(r):.3f} (range {r[0]:.3f}–{r[-1]:.3f})"


def free_goals(obs: Dict[str, Any], rng: Any, map_size_m: float, n: int) -> Any:
    """`n` goals on cells the robot's map holds as free, 1 m or more from the robot, drawn from the
    robot-centred map crop (row 0 is the lowest y); on cells not known to be obstacles when none is
    free yet (the first view can be of a wall)."""
    import numpy as np

    crop = obs["map"]
    s = crop.shape[0]
    res = map_size_m / s
    x, y = float(obs["pose"][0]), float(obs["pose"][1])
    for layer in (crop[..., 0], 1 - crop[..., 1]):
        rows, cols = np.nonzero(layer)
        dx, dy = (cols - s // 2) * res, (rows - s // 2) * res
        far = np.hypot(dx, dy) >= 1.0
        if far.any():
            break
    pick = rng.choice(np.flatnonzero(far), size=n)
    return np.stack([x + dx[pick], y + dy[pick]], axis=1).astype(np.float32)


def env_rate(tensorscout: Any, num_envs: int, action_type: str, steps: int, threads: int | None,
             repeat: int) -> float:
    """Median environment steps per second (all environments' steps) over `repeat` timings of
    `steps` steps each: the time spent in `step` (choosing the actions is the agent's time, not the
    environment's; resets are excluded). Every environment starts at the scene's own start (a
    random one can face a wall, from where no goal is reachable yet); goals are drawn from each
    robot's known free floor."""
    import numpy as np

    cfg = {"sim.budget_s": 100000}
    rng = np.random.default_rng(0)
    rates = []
    if num_envs == 1:
        env = tensorscout.ExploreEnv(SCENE, action_type=action_type, config=cfg, spawn=None)
        env.action_space.seed(0)
        obs, _ = env.reset(seed=0)
        for _ in range(repeat):
            spent = 0.0
            for _ in range(steps):
                if action_type == "goal":
                    a = free_goals(obs, rng, 8.0, 1)[0]
                else:
                    a = env.action_space.sample()
                t = time.perf_counter()
                obs, _, term, trunc, _ = env.step(a)
                spent += time.perf_counter() - t
                if term or trunc:
                    obs, _ = env.reset()
            rates.append(steps / spent)
        return statistics.median(rates)
    vec = tensorscout.ExploreVectorEnv(num_envs, SCENE, action_type=action_type, config=cfg,
                                       spawn=None, num_threads=threads)
    vec.action_space.seed(0)
    obs, _ = vec.reset(seed=0)
    for _ in range(repeat):
        spent = 0.0
        for _ in range(steps):
            if action_type == "goal":
                a = np.concatenate([
                    free_goals({"map": obs["map"][i], "pose": obs["pose"][i]}, rng, 8.0, 1)
                    for i in range(num_envs)])
            else:
                a = vec.action_space.sample()
            t = time.perf_counter()
            obs, *_ = vec.step(a)
            spent += time.perf_counter() - t
        rates.append(num_envs * steps / spent)
    return statistics.median(rates)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bin", default=str(ROOT / "target/release/tensorscout"))
    ap.add_argument("--pairs", type=int, default=9, help="run() / command-line pairs (default 9)")
    ap.add_argument("--repeat", type=int, default=5, help="timings per environment rate (default 5)")
    ap.add_argument("--planner", default="greedy")
    ap.add_argument("--threads", type=int, default=None,
                    help="RAYON_NUM_THREADS for run() and the command line (default: one per core)")
    ap.add_argument("--skip-run", action="store_true", help="only the environment figures")
    ap.add_argument("--skip-env", action="store_true", help="only run() against the command line")
    a = ap.parse_args()
    if a.threads is not None:
        # Before the extension starts its global rayon pool, and inherited by the command line.
        os.environ["RAYON_NUM_THREADS"] = str(a.threads)
    import tensorscout

    def run_cli() -> None:
        subprocess.run([a.bin, "explore", "--json", "--quiet", "--scene", str(OFFICE), "--planner",
                        a.planner], check=True, capture_output=True)

    if not a.skip_run:
        # Untimed once each first: the observable set is computed and cached by whichever runs first.
        run_cli()
        tensorscout.Simulation(OFFICE, planner=a.planner).run()
        t = paired(run_cli, True, lambda: tensorscout.Simulation(OFFICE, planner=a.planner).run(),
                   False, a.pairs)
        threads = a.threads if a.threads is not None else os.cpu_count()
        print(f"| run() ÷ command line, office_large, {a.planner}, {threads} threads, "
              f"{a.pairs} pairs | wall {ratio_summary(t['b_wall'], t['a_wall'])}; "
              f"CPU {ratio_summary(t['b_cpu'], t['a_cpu'])}; command line median "
              f"{statistics.median(t['a_wall']):.2f} s |", flush=True)
    if a.skip_env:
        return
    for action_type, steps in (("discrete", 300), ("goal", 40)):
        for n in (1, 2, 8):
            r = env_rate(tensorscout, n, action_type, steps if n == 1 else max(steps // n * 2, 8),
                         None, a.repeat)
            print(f"| env steps/s, {action_type}, {'1 env' if n == 1 else f'vector of {n}'} | "
                  f"{r:.0f} |", flush=True)
    for action_type, steps in (("discrete", 150), ("goal", 20)):
        ratios = []
        for _ in range(a.repeat):
            one = env_rate(tensorscout, 8, action_type, steps, 1, 1)
            two = env_rate(tensorscout, 8, action_type, steps, 2, 1)
            ratios.append(two / one)
        r = sorted(ratios)
        print(f"| vector of 8, {action_type}: 2 threads ÷ 1 thread, {a.repeat} pairs | "
              f"{statistics.median(r):.2f}× (range {r[0]:.2f}–{r[-1]:.2f}) |", flush=True)


if __name__ == "__main__":
    main()
