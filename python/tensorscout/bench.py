"""``tensorscout.bench``: scenes × planners × seeds, the folder ``tensorscout bench`` writes."""

from __future__ import annotations

import os
from typing import Any, Dict, List, Optional, Sequence, Union

from ._native import bench as _bench

PathLike = Union[str, "os.PathLike[str]"]


def bench(
    scenes: Union[PathLike, Sequence[PathLike]],
    planners: Sequence[Any] = ("thp", "tensor", "nbv", "greedy"),
    seeds: int = 3,
    out: PathLike = "bench",
    config: Union[None, Dict[str, Any], PathLike] = None,
    jobs: Optional[int] = None,
    reference: Optional[str] = None,
    scene_spawn: bool = False,
    resume: bool = False,
    force: bool = False,
) -> List[Dict[str, Any]]:
    """Runs every planner on every scene (files, or folders of scene files) with ``seeds`` seeds
    and writes ``out`` as ``tensorscout bench --out`` does: ``results.jsonl``, ``results.csv``,
    ``curves.csv``, ``summary.md``/``summary.json`` with paired CIs against ``reference`` (THP by
    default) and ``plots/``. ``planners`` holds built-in names and Python planner classes (or
    zero-argument factories), called once per run. A run that fails (a Python planner that raises
    included) becomes a failed row with the error (and traceback); the batch goes on. Returns the
    rows of ``results.jsonl`` as dicts.
    """
    if isinstance(scenes, (str, os.PathLike)):
        scenes = [scenes]
    return _bench(
        [os.fspath(s) for s in scenes],
        list(planners),
        seeds,
        os.fspath(out),
        config,
        jobs,
        reference,
        scene_spawn,
        resume,
        force,
    )
