"""Actions a Python planner answers, and the shape of a planner.

A planner is any object with ``plan(ctx) -> Action``. The step loop calls it through the same
``Planner`` trait as the built-in planners, with the same sensor, map, motion executor and metrics.
Optional methods: ``action_finished(reached: bool)``, told when the action ended (reached, or
blocked/abandoned); ``is_outdated(ctx) -> bool``, asked every step while an action runs (True
abandons it for a new plan); ``stats() -> dict[str, float]``, the run's ``planner_stats``. The name
in results is the planner's ``name`` attribute, else its class name.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, List, Protocol, Sequence, Tuple, Union

if TYPE_CHECKING:
    from ._native import PlanContext


@dataclass(frozen=True)
class Follow:
    """Follow ``path`` (world points (x, y), the first near the robot) to its end.

    The robot counts as arrived within ``motion.goal_tolerance_m`` of the end; with
    ``exact_arrival`` it drives on to within 2 cm. With ``look_on_arrival`` it then turns once in
    place.
    """

    path: Sequence[Tuple[float, float]]
    look_on_arrival: bool = False
    exact_arrival: bool = False
    kind: str = field(default="follow", init=False)


@dataclass(frozen=True)
class LookAround:
    """Turn once in place."""

    kind: str = field(default="look_around", init=False)


@dataclass(frozen=True)
class Complete:
    """Nothing reachable is left to explore: the run ends ``complete``."""

    kind: str = field(default="complete", init=False)


@dataclass(frozen=True)
class Stuck:
    """The planner cannot go on: the run ends ``stuck``."""

    kind: str = field(default="stuck", init=False)


Action = Union[Follow, LookAround, Complete, Stuck]


class Planner(Protocol):
    """What the step loop calls: ``plan(ctx)`` whenever the previous action is done."""

    def plan(self, ctx: "PlanContext") -> Action: ...


__all__: List[str] = ["Action", "Complete", "Follow", "LookAround", "Planner", "Stuck"]
