"""Fixtures of the Python package's tests: the repository's scenes and the command-line binary."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path
from typing import Any, Dict, List

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"
SMALL = SCENES / "apartment_small.obj"
#: Two shipped scenes and two real plans for the parity test.
PARITY_SCENES = [
    SMALL,
    SCENES / "corridor_rooms.obj",
    SCENES / "floorplans/plan_052ce6767b.obj",
    SCENES / "floorplans/plan_06dec58b2b.obj",
]
#: Fields of a result that hold wall-clock times, or the build (not deterministic).
WALL_CLOCK = ("wall_time_s", "real_time_factor", "timings_ms")


def cli_binary() -> Path:
    """The release binary (`cargo build --release`): TENSORSCOUT_BIN, else the build's target dir."""
    env = os.environ.get("TENSORSCOUT_BIN")
    if env:
        return Path(env)
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    return target / "release" / "tensorscout"


@pytest.fixture(scope="session")
def cli() -> Path:
    b = cli_binary()
    if not b.is_file():
        pytest.fail(f"{b} missing: build it with `cargo build --release` or set TENSORSCOUT_BIN")
    return b


def run_cli(cli: Path, *args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(cli), *args], capture_output=True, text=True, check=check, cwd=ROOT
    )


def without_wall_clock(result: Dict[str, Any]) -> Dict[str, Any]:
    return {k: v for k, v in result.items() if k not in WALL_CLOCK}


def cli_json(cli: Path, *args: str) -> Dict[str, Any]:
    out = run_cli(cli, "explore", "--json", "--quiet", *args)
    r: Dict[str, Any] = json.loads(out.stdout)
    return r


def jsonl(path: Path) -> List[Dict[str, Any]]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
