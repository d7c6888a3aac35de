"""Type stubs of the native module (the Rust bindings)."""

import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Path = Union[str, "os.PathLike[str]"]
_Config = Union[None, Dict[str, Any], _Path]
_Spawn = Union[None, str, Sequence[float]]

class GridSpec:
    """The grid the 2D layers and the voxels share."""

    @property
    def origin_x(self) -> float: ...
    @property
    def origin_y(self) -> float: ...
    @property
    def origin(self) -> Tuple[float, float]: ...
    @property
    def resolution(self) -> float: ...
    @property
    def nx(self) -> int: ...
    @property
    def ny(self) -> int: ...
    @property
    def nz(self) -> int: ...

class Simulation:
    """One exploration of a scene by a planner, the step loop ``tensorscout explore`` runs."""

    def __init__(
        self,
        scene: _Path,
        planner: Any = "thp",
        seed: Optional[int] = None,
        spawn: _Spawn = None,
        config: _Config = None,
    ) -> None: ...
    def log(self, path: _Path) -> None:
        """Log the run to an MCAP file, as ``explore --log`` does (before the first step)."""
    def step(self, n: int = 1) -> bool:
        """Run ``n`` steps (fewer if the run ends); whether the run goes on."""
    def run(self) -> Dict[str, Any]:
        """Run to the end; the result ``explore --json`` prints."""
    @property
    def result(self) -> Optional[Dict[str, Any]]: ...
    @property
    def done(self) -> bool: ...
    @property
    def termination(self) -> Optional[str]: ...
    @property
    def pose(self) -> Tuple[float, float, float]: ...
    @property
    def time_s(self) -> float: ...
    @property
    def steps(self) -> int: ...
    @property
    def grid(self) -> GridSpec: ...
    def depth(self) -> npt.NDArray[np.float32]:
        """The last depth frame, (H, W) metres along the optical axis, 0 where no reading."""
    def map_layers(self) -> Dict[str, npt.NDArray[Any]]:
        """``state`` uint8 (0 unknown, 1 free, 2 obstacle), ``known_fraction`` float32,
        ``frontier`` and ``traversable`` bool, each (ny, nx)."""
    def voxels(self) -> npt.NDArray[np.uint8]:
        """Occupancy voxels (nz, ny, nx): 0 unknown, 1 free, 2 occupied."""

class PlanContext:
    """What a Python planner sees during ``plan(ctx)``; valid only during that call."""

    @property
    def pose(self) -> Tuple[float, float, float]: ...
    @property
    def time_s(self) -> float: ...
    @property
    def grid(self) -> GridSpec: ...
    def cell_states(self) -> npt.NDArray[np.uint8]: ...
    def traversable(self) -> npt.NDArray[np.bool_]: ...
    def frontier(self) -> npt.NDArray[np.bool_]: ...
    def frontier_groups(self) -> List[Dict[str, Any]]: ...
    def cell_of(self, x: float, y: float) -> Optional[Tuple[int, int]]: ...
    def cell_center(self, ix: int, iy: int) -> Tuple[float, float]: ...
    def step_cost(self, ix: int, iy: int) -> Optional[float]: ...
    def distance_field(self) -> npt.NDArray[np.float32]: ...
    def astar(self, x: float, y: float) -> Optional[List[Tuple[float, float]]]: ...

class EnvCore:
    def __init__(
        self,
        scene: _Path,
        action_type: str = "discrete",
        config: _Config = None,
        spawn: _Spawn = None,
        map_size_m: float = 8.0,
        completeness_target: float = 0.95,
        collision_penalty: float = 0.1,
        seed: Optional[int] = None,
    ) -> None: ...
    def describe(self) -> Dict[str, Any]: ...
    def reset(
        self, seed: Optional[int] = None
    ) -> Tuple[Dict[str, npt.NDArray[Any]], Dict[str, Any]]: ...
    def step(
        self, action: Any
    ) -> Tuple[Dict[str, npt.NDArray[Any]], float, bool, bool, Dict[str, Any]]: ...

class VecEnvCore:
    def __init__(
        self,
        scene: _Path,
        num_envs: int,
        action_type: str = "discrete",
        config: _Config = None,
        spawn: _Spawn = None,
        map_size_m: float = 8.0,
        completeness_target: float = 0.95,
        collision_penalty: float = 0.1,
        seed: Optional[int] = None,
        num_threads: Optional[int] = None,
    ) -> None: ...
    @property
    def num_envs(self) -> int: ...
    def describe(self) -> Dict[str, Any]: ...
    def reset(
        self,
        seeds: Optional[Sequence[Optional[int]]] = None,
        mask: Optional[Sequence[bool]] = None,
    ) -> Tuple[Dict[str, npt.NDArray[Any]], List[Optional[Dict[str, Any]]]]: ...
    def step(
        self, actions: Any, mask: Optional[Sequence[bool]] = None
    ) -> Tuple[
        Dict[str, npt.NDArray[Any]],
        List[float],
        List[bool],
        List[bool],
        List[Optional[Dict[str, Any]]],
    ]: ...

def bench(
    scenes: List[str],
    planners: List[Any],
    seeds: int,
    out: str,
    config: _Config,
    jobs: Optional[int],
    reference: Optional[str],
    scene_spawn: bool,
    resume: bool,
    force: bool,
) -> List[Dict[str, Any]]: ...
def _panic_inside_guard(message: str) -> None:
    """Test hook: panics inside the guard every entry point runs in (raises InternalError)."""
    ...
