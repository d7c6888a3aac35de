"""Reads a bench folder (``tensorscout bench`` or ``tensorscout.bench``) into pandas, if installed.

Usage: python bench_pandas.py BENCH_DIR
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any, Dict, List

folder = Path(sys.argv[1] if len(sys.argv) > 1 else "bench-nearest-frontier")
rows: List[Dict[str, Any]] = [
    json.loads(line) for line in (folder / "results.jsonl").read_text().splitlines() if line.strip()
]
flat = [
    {
        "scene": Path(r["scene_path"]).stem,
        "planner": r["planner"],
        "seed": r["seed"],
        "status": r["status"],
        **{k: (r.get("result") or {}).get(k) for k in (
            "termination", "completeness", "explored_volume_m3", "path_length_m", "sim_time_s",
            "collisions")},
    }
    for r in rows
]
try:
    import pandas as pd  # type: ignore[import-untyped, unused-ignore]
except ImportError:
    print("pandas is not installed (pip install pandas); the rows:")
    for f in flat:
        print(f)
    sys.exit(0)

df = pd.DataFrame(flat)
print(df.groupby(["scene", "planner"])[["completeness", "path_length_m", "sim_time_s"]].mean())
