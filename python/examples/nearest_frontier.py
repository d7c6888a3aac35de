"""A nearest-frontier planner in Python, benchmarked against GREEDY and THP.

Usage: python nearest_frontier.py [OUT_DIR] [SCENE ...]
(default: scenes/apartment_small.obj and three real plans of scenes/floorplans/).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import List, Tuple

import numpy as np

import tensorscout
from tensorscout import Action, Complete, Follow, PlanContext


class NearestFrontier:
    """Drive to the nearest reachable frontier cell and look around there; a frontier within
    0.5 m of a place already looked from is given up (the camera could not see past it)."""

    name = "py-nearest"

    def __init__(self) -> None:
        self.looked: List[Tuple[float, float]] = []
        self.goal: Tuple[float, float] | None = None

    def plan(self, ctx: PlanContext) -> Action:
        if not self.looked:  # the run began with a look around from the start
            self.looked.append(ctx.pose[:2])
        dist = ctx.distance_field()
        candidates = ctx.frontier() & np.isfinite(dist)
        for iy, ix in zip(*np.nonzero(candidates)):
            x, y = ctx.cell_center(int(ix), int(iy))
            if any(math.dist((x, y), p) < 0.5 for p in self.looked):
                candidates[iy, ix] = False
        if not candidates.any():
            return Complete()
        iy, ix = np.unravel_index(np.argmin(np.where(candidates, dist, np.inf)), dist.shape)
        self.goal = ctx.cell_center(int(ix), int(iy))
        path = ctx.astar(*self.goal)
        assert path is not None, "a cell with a finite distance has a path"
        return Follow(path, look_on_arrival=True)

    def action_finished(self, reached: bool) -> None:
        if self.goal is not None:
            self.looked.append(self.goal)


def main() -> None:
    root = Path(__file__).resolve().parents[2]
    out = sys.argv[1] if len(sys.argv) > 1 else "bench-nearest-frontier"
    scenes = sys.argv[2:] or [
        str(root / "scenes/apartment_small.obj"),
        *(str(root / f"scenes/floorplans/{p}.obj") for p in ("plan_052ce6767b", "plan_06dec58b2b", "plan_0ae54bc5c4")),
    ]
    rows = tensorscout.bench(scenes, ["thp", "greedy", NearestFrontier], seeds=1, out=out, force=True)
    for r in rows:
        res = r.get("result") or {}
        print(f"{r['planner']:12} {Path(r['scene_path']).stem:18} {r['status']:6} "
              f"completeness {res.get('completeness', 0):.3f} collisions {res.get('collisions')}")
    print(f"summary: {out}/summary.md")


if __name__ == "__main__":
    main()
