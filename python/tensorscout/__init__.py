"""tensorscout from Python: simulations, a Gymnasium environment, planners written in Python and
the benchmark. See python/README.md for the API."""

from ._errors import (
    Error,
    FileError,
    InternalError,
    MissingFileError,
    RunError,
    SceneError,
    UsageError,
)
from ._native import GridSpec, PlanContext, Simulation, __version__
from .bench import bench
from .env import ExploreEnv, ExploreVectorEnv, SAMPLE_SCENE, register
from .planner import Action, Complete, Follow, LookAround, Planner, Stuck

register()

__all__ = [
    "Action",
    "Complete",
    "Error",
    "ExploreEnv",
    "ExploreVectorEnv",
    "FileError",
    "Follow",
    "GridSpec",
    "InternalError",
    "LookAround",
    "MissingFileError",
    "PlanContext",
    "Planner",
    "RunError",
    "SAMPLE_SCENE",
    "SceneError",
    "Simulation",
    "Stuck",
    "UsageError",
    "__version__",
    "bench",
]
