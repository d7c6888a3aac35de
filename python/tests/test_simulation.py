"""`tensorscout.Simulation`: the same runs as `explore`, the state as arrays, logs, errors."""

from __future__ import annotations

import os
import signal
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import tensorscout
from conftest import PARITY_SCENES, SMALL, cli_json, run_cli, without_wall_clock

PLANNERS = ["thp", "tensor", "nbv", "greedy"]


@pytest.mark.parametrize("scene", PARITY_SCENES, ids=lambda p: p.stem)
@pytest.mark.parametrize("planner", PLANNERS)
def test_run_equals_explore_json(cli: Path, scene: Path, planner: str) -> None:
    """`run()` gives exactly the result `explore --json` prints, apart from wall-clock fields."""
    expected = cli_json(cli, "--scene", str(scene), "--planner", planner)
    got = tensorscout.Simulation(scene, planner=planner).run()
    assert without_wall_clock(got) == without_wall_clock(expected)


def test_seed_spawn_and_config_as_on_the_command_line(cli: Path) -> None:
    args = ["--scene", str(SMALL), "--planner", "greedy", "--seed", "7", "--spawn", "random",
            "--set", "sim.budget_s=60", "--set", "camera.renderer=\"raycast\""]
    expected = cli_json(cli, *args)
    sim = tensorscout.Simulation(
        SMALL, planner="greedy", seed=7, spawn="random",
        config={"sim.budget_s": 60, "camera.renderer": "raycast"},
    )
    assert without_wall_clock(sim.run()) == without_wall_clock(expected)
    assert sim.termination == "budget" and sim.done
    # An explicit start pose, and a TOML file.
    expected = cli_json(cli, "--scene", str(SMALL), "--planner", "nbv", "--spawn", "2.0,2.0,0.5",
                        "--set", "sim.budget_s=30")
    got = tensorscout.Simulation(SMALL, "nbv", spawn=(2.0, 2.0, 0.5), config={"sim.budget_s": 30}).run()
    assert without_wall_clock(got) == without_wall_clock(expected)


def test_config_file(tmp_path: Path, cli: Path) -> None:
    toml = tmp_path / "c.toml"
    toml.write_text("[sim]\nbudget_s = 20.0\n")
    expected = cli_json(cli, "--scene", str(SMALL), "--planner", "greedy", "--config", str(toml))
    got = tensorscout.Simulation(SMALL, "greedy", config=toml).run()
    assert without_wall_clock(got) == without_wall_clock(expected)


def test_step_by_step_state() -> None:
    sim = tensorscout.Simulation(SMALL, planner="greedy", config={"sim.budget_s": 5})
    assert not sim.done and sim.termination is None and sim.steps == 0
    assert sim.step(3)
    assert sim.steps == 3 and sim.time_s == pytest.approx(0.3)
    depth = sim.depth()
    assert depth.dtype == np.float32 and depth.ndim == 2 and depth.max() > 0.5
    layers = sim.map_layers()
    g = sim.grid
    for k in ("state", "known_fraction", "frontier", "traversable"):
        assert layers[k].shape == (g.ny, g.nx), k
    assert set(np.unique(layers["state"])) <= {0, 1, 2} and (layers["state"] == 1).any()
    vox = sim.voxels()
    assert vox.shape == (g.nz, g.ny, g.nx) and vox.dtype == np.uint8
    # known_fraction is the share of known voxels per column.
    np.testing.assert_allclose(layers["known_fraction"], (vox > 0).mean(axis=0), rtol=1e-6)
    # The robot's cell lies on the map.
    x, y, _ = sim.pose
    ix, iy = int((x - g.origin_x) / g.resolution), int((y - g.origin_y) / g.resolution)
    assert 0 <= ix < g.nx and 0 <= iy < g.ny
    while sim.step(100):
        pass
    assert sim.done and sim.termination == "budget" and sim.steps == 50
    assert sim.result is not None and sim.result["steps"] == 50
    assert not sim.step()


def test_log_is_the_explore_log(tmp_path: Path, cli: Path) -> None:
    """The log of a Python run has the messages of `explore --log` (the same run)."""
    a, b = tmp_path / "py.mcap", tmp_path / "cli.mcap"
    sim = tensorscout.Simulation(SMALL, "greedy", config={"sim.budget_s": 10})
    sim.log(a)
    sim.run()
    run_cli(cli, "explore", "--quiet", "--scene", str(SMALL), "--planner", "greedy",
            "--set", "sim.budget_s=10", "--log", str(b))
    # Both verify against a fresh run (replay --verify re-runs the logged run and compares).
    for p in (a, b):
        out = run_cli(cli, "replay", str(p), "--verify", check=False)
        assert out.returncode == 0, out.stderr
    with pytest.raises(tensorscout.UsageError):
        sim.log(tmp_path / "again.mcap")


def test_errors_carry_the_command_line_message(cli: Path, tmp_path: Path) -> None:
    def cli_error(*args: str) -> str:
        out = run_cli(cli, "explore", "--quiet", *args, check=False)
        assert out.returncode != 0
        line: str = out.stderr.strip().splitlines()[-1]
        assert line.startswith("error: ")
        return line[len("error: "):]

    missing = tmp_path / "nope.obj"
    with pytest.raises(FileNotFoundError) as e:
        tensorscout.Simulation(missing)
    assert isinstance(e.value, tensorscout.Error)
    assert str(e.value) == cli_error("--scene", str(missing))

    with pytest.raises(ValueError) as v:
        tensorscout.Simulation(SMALL, config={"sim.budget_s": -1})
    assert isinstance(v.value, tensorscout.UsageError)
    assert str(v.value) == cli_error("--scene", str(SMALL), "--set", "sim.budget_s=-1")

    with pytest.raises(tensorscout.UsageError) as u:
        tensorscout.Simulation(SMALL, config={"sim.no_such_key": 1})
    assert str(u.value) == cli_error("--scene", str(SMALL), "--set", "sim.no_such_key=1")

    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nf 1 2 3\n")
    with pytest.raises(tensorscout.Error) as s:
        tensorscout.Simulation(bad)
    assert str(s.value) == cli_error("--scene", str(bad))

    with pytest.raises(tensorscout.UsageError, match="planner `astar`"):
        tensorscout.Simulation(SMALL, planner="astar")
    with pytest.raises(tensorscout.UsageError, match="spawn"):
        tensorscout.Simulation(SMALL, spawn=(1.0, float("nan")))


def test_ctrl_c_interrupts_run_and_leaves_a_valid_log(tmp_path: Path, cli: Path) -> None:
    """SIGINT during `run()` raises KeyboardInterrupt within a fraction of a second; the run ends
    `interrupted` and its log is finished (it reads back and verifies)."""
    log = tmp_path / "int.mcap"
    sim = tensorscout.Simulation(SCENE_LARGE, "thp")
    sim.log(log)
    timer = threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        sim.run()
    # The run stopped early, long before its end (thousands of steps).
    assert sim.done and sim.termination == "interrupted"
    assert 0 < sim.steps < 5000
    out = run_cli(cli, "replay", str(log), "--verify", check=False)
    assert out.returncode == 0, out.stderr


SCENE_LARGE = SMALL.parent / "office_large.obj"


def test_a_python_planner_that_raises_ends_the_run_in_error() -> None:
    class Broken:
        def plan(self, ctx: Any) -> Any:
            raise ZeroDivisionError("no plan today")

    r = tensorscout.Simulation(SMALL, planner=Broken()).run()
    assert r["termination"] == "error" and r["planner"] == "Broken"
    assert "ZeroDivisionError: no plan today" in r["error"]
    assert "Traceback (most recent call last)" in r["error"] and "in plan" in r["error"]


def test_a_python_planner_that_raises_in_is_outdated_ends_the_run_in_error() -> None:
    """`is_outdated` answers a bool to the step loop; its exception still ends the run `error`, at
    the plan that follows, with its own traceback."""

    class OutdatedFails:
        def __init__(self) -> None:
            self.calls: list[str] = []

        def plan(self, ctx: Any) -> Any:
            self.calls.append("plan")
            return tensorscout.LookAround()

        def is_outdated(self, ctx: Any) -> bool:
            self.calls.append("is_outdated")
            raise ArithmeticError("cannot tell")

    planner = OutdatedFails()
    r = tensorscout.Simulation(SMALL, planner=planner).run()
    assert r["termination"] == "error"
    assert "raised in is_outdated: cannot tell" in r["error"]
    assert "ArithmeticError: cannot tell" in r["error"] and "in is_outdated" in r["error"]
    # The first raise ended the run: no plan, and no other call, came after it.
    assert planner.calls.count("is_outdated") == 1 and planner.calls[-1] == "is_outdated"


def test_a_rust_panic_arrives_as_internal_error() -> None:
    with pytest.raises(tensorscout.InternalError, match="^panic: deliberately$"):
        tensorscout._native._panic_inside_guard("deliberately")
    # The interpreter and the package still work.
    assert tensorscout.Simulation(SMALL, config={"sim.budget_s": 2}).run()["termination"] == "budget"


def test_a_python_planner_gets_the_shared_searches() -> None:
    seen: dict[str, Any] = {}

    class Probe:
        name = "probe"

        def plan(self, ctx: tensorscout.PlanContext) -> tensorscout.Action:
            dist = ctx.distance_field()
            x, y, _ = ctx.pose
            cell = ctx.cell_of(x, y)
            assert cell is not None
            seen["dist_at_robot"] = float(dist[cell[1], cell[0]])
            reachable = np.isfinite(dist) & ctx.traversable()
            iy, ix = np.unravel_index(np.argmax(np.where(reachable, dist, -1)), dist.shape)
            goal = ctx.cell_center(int(ix), int(iy))
            path = ctx.astar(*goal)
            assert path is not None
            seen["path_end"] = path[-1]
            seen["goal"] = goal
            seen["groups"] = ctx.frontier_groups()
            seen["ctx"] = ctx
            return tensorscout.Complete()

    r = tensorscout.Simulation(SMALL, planner=Probe(), config={"sim.initial_look_around": False}).run()
    assert r["termination"] == "complete" and r["planner"] == "probe"
    assert seen["dist_at_robot"] == 0.0
    assert seen["path_end"] == pytest.approx(seen["goal"])
    # The context cannot be used after its call.
    with pytest.raises(RuntimeError, match="used after"):
        seen["ctx"].frontier()
