//! Planners and the searches they share.
//!
//! Every planner reads the same [`Map`] (and, for the tensor-field planners, the same field) through
//! a [`PlanContext`] and answers with an [`Action`]; the simulator's one motion executor carries it
//! out, so that comparisons between planners are fair.

pub mod greedy;
pub mod search;

use crate::config::Config;
use crate::map::Map;
use crate::{Pose2, Result};
use nalgebra::Point2;
use search::Search;

/// What a planner sees: read-only views of the map and the robot, plus a reusable search workspace.
pub struct PlanContext<'a> {
    pub map: &'a Map,
    pub pose: Pose2,
    pub time_s: f64,
    pub cfg: &'a Config,
    pub search: &'a mut Search,
}

impl PlanContext<'_> {
    /// Whether a cell may be entered by the robot under the search settings.
    pub fn passable(&self, cell: usize) -> bool {
        passable(self.map, self.cfg.search.unknown_is_free, cell)
    }
}

/// The passability rule every search uses: traversable, or unknown (and not within the inflation of
/// a known obstacle) when searches are optimistic.
pub fn passable(map: &Map, unknown_is_free: bool, cell: usize) -> bool {
    map.is_traversable(cell) || (unknown_is_free && map.is_unknown(cell) && !map.is_inflated(cell))
}

/// What the robot should do next.
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    /// Follow `path` (world points, the first near the robot) to its end; then, if `look_on_arrival`,
    /// turn once in place.
    Follow {
        path: Vec<Point2<f64>>,
        look_on_arrival: bool,
    },
    /// Turn once in place where the robot stands.
    LookAround,
    /// Nothing reachable is left to explore.
    Complete,
}

/// A planner: turns what is known into the next action.
pub trait Planner {
    /// The name used on the command line and in results.
    fn name(&self) -> &'static str;

    /// Chooses the next action. Called when the previous one is done, blocked or outdated.
    fn plan(&mut self, ctx: &mut PlanContext) -> Result<Action>;

    /// Whether the action in progress should be abandoned for a new plan (checked every step).
    fn is_outdated(&mut self, ctx: &PlanContext, action: &Action) -> bool;

    /// Told when the action ended: reached (`true`) or blocked/abandoned (`false`).
    fn action_finished(&mut self, ctx: &PlanContext, reached: bool);
}

/// The planners a run can use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PlannerKind {
    /// Tensor-field-driven hierarchical planning (THP).
    Thp,
    /// Time-varying tensor-field exploration (TENSOR).
    Tensor,
    /// Two-stage next-best-view planning with a TSP (NBV-TSP).
    Nbv,
    /// Nearest frontier (Yamauchi 1997).
    Greedy,
}

impl PlannerKind {
    /// The name used on the command line and in results.
    pub fn name(self) -> &'static str {
        match self {
            PlannerKind::Thp => "thp",
            PlannerKind::Tensor => "tensor",
            PlannerKind::Nbv => "nbv",
            PlannerKind::Greedy => "greedy",
        }
    }

    /// A fresh planner of this kind.
    pub fn build(self, _cfg: &Config) -> Result<Box<dyn Planner>> {
        match self {
            PlannerKind::Greedy => Ok(Box::new(greedy::Greedy::new())),
            other => Err(crate::Error::usage(format!(
                "planner `{}` is not available in this version; available: greedy",
                other.name()
            ))),
        }
    }
}
