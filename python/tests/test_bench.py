"""`tensorscout.bench`: the folder `tensorscout bench` writes, Python planners beside built-in ones."""

from __future__ import annotations

import json
import os
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

import tensorscout
from conftest import ROOT, SMALL, jsonl, run_cli, without_wall_clock

sys.path.insert(0, str(ROOT / "python" / "examples"))
from nearest_frontier import NearestFrontier  # noqa: E402

CFG = {"sim.budget_s": 120}


class Raises:
    name = "raises"

    def plan(self, ctx: Any) -> Any:
        raise KeyError("lost")


def test_bench_folder_rows_and_summary(tmp_path: Path, cli: Path) -> None:
    out = tmp_path / "py"
    rows = tensorscout.bench(SMALL, ["thp", NearestFrontier, Raises], seeds=1, out=out, config=CFG, jobs=2)
    for f in ("results.jsonl", "results.csv", "curves.csv", "summary.md", "summary.json"):
        assert (out / f).is_file(), f
    assert (out / "plots").is_dir() and any((out / "plots").iterdir())
    assert rows == jsonl(out / "results.jsonl")
    by = {r["planner"]: r for r in rows}
    assert set(by) == {"thp", "py-nearest", "raises"}
    assert by["py-nearest"]["status"] == "ok"
    # A planner that raises gives a failed row with its traceback; the batch went on.
    assert by["raises"]["status"] == "failed"
    assert "KeyError: 'lost'" in by["raises"]["error"] and "Traceback" in by["raises"]["error"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reference"] == "thp"
    assert "py-nearest" in (out / "summary.md").read_text()
    # The THP row is the one `tensorscout bench` writes.
    cli_out = tmp_path / "cli"
    run_cli(cli, "bench", "--quiet", "--scenes", str(SMALL), "--planners", "thp", "--seeds", "1",
            "--set", "sim.budget_s=120", "--out", str(cli_out))
    (cli_row,) = jsonl(cli_out / "results.jsonl")
    assert {**cli_row, "result": without_wall_clock(cli_row["result"])} == {
        **by["thp"], "result": without_wall_clock(by["thp"]["result"])}
    # An existing folder is refused unless resumed (then nothing is run again) or forced.
    with pytest.raises(tensorscout.UsageError, match="already exists"):
        tensorscout.bench(SMALL, ["thp"], seeds=1, out=out, config=CFG)
    again = tensorscout.bench(SMALL, ["thp", NearestFrontier, Raises], seeds=1, out=out, config=CFG, resume=True)
    assert len(again) == 3


def test_nearest_frontier_completes_without_collisions() -> None:
    r = tensorscout.Simulation(SMALL, planner=NearestFrontier()).run()
    assert r["termination"] == "complete", r["termination"]
    assert r["collisions"] == 0 and r["completeness"] > 0.9


def test_ctrl_c_in_bench_keeps_finished_rows_and_resumes(tmp_path: Path) -> None:
    """SIGINT during `bench()` raises KeyboardInterrupt; the rows finished by then stay whole in
    results.jsonl, and `resume=True` runs only the rest."""
    out = tmp_path / "int"
    jsonl_path = out / "results.jsonl"

    def interrupt_after_first_row() -> None:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            if jsonl_path.is_file() and jsonl_path.read_text().count("\n") >= 1:
                os.kill(os.getpid(), signal.SIGINT)
                return
            time.sleep(0.02)

    watcher = threading.Thread(target=interrupt_after_first_row, daemon=True)
    watcher.start()
    with pytest.raises(KeyboardInterrupt):
        tensorscout.bench(SMALL, ["greedy"], seeds=6, out=out, config=CFG, jobs=1)
    watcher.join()
    kept = jsonl(jsonl_path)
    assert 1 <= len(kept) < 6
    assert all(r["status"] == "ok" and r["result"]["termination"] != "interrupted" for r in kept)
    rows = tensorscout.bench(SMALL, ["greedy"], seeds=6, out=out, config=CFG, jobs=1, resume=True)
    assert sorted(r["seed"] for r in rows) == [1, 2, 3, 4, 5, 6]
    assert [r for r in rows if r["seed"] in {k["seed"] for k in kept}] == kept
