//! The end of a run: once no reachable frontier is left, the looks through gaps too narrow to pass,
//! the volume views and the reopening of given-up frontiers, in that order, each switchable.

use super::viewpoints::line_of_sight;
use crate::config::Additions;
use crate::grid::{Cell, GridSpec};
use crate::map::Map;
use crate::plan::search::DistanceField;
use crate::plan::Action;

/// What a frontier planner does once no reachable frontier is left to visit.
#[derive(Clone, Debug, PartialEq)]
pub enum Ending<V> {
    /// Look at a frontier seen through a gap too narrow to pass (`additions.distant_views`).
    DistantView(DistantView),
    /// Drive to a view of unknown volume that no frontier shows (`additions.volume_views`).
    VolumeView(V),
    /// Given-up frontier cells were reopened (`additions.reopen_max`): look, then plan again.
    Reopened,
    /// Nothing is left: the map is complete.
    Complete,
}

/// The end-of-run sequence, the one place its order and switches live (GREEDY and THP; NBV-TSP
/// without volume views): distant views, then volume views, then reopening, then `Complete`. Each
/// step is asked of `state` (the planner) only if the steps before it gave nothing and its switch
/// in `rules` is on: `distant` gives the next distant view, `volume` the next volume view (`None`
/// when the planner has none), `reopen` reopens what it can and says whether it reopened anything.
pub fn end_of_run<S, V>(
    rules: &Additions,
    state: &mut S,
    distant: impl FnOnce(&S) -> Option<DistantView>,
    volume: impl FnOnce(&mut S) -> Option<V>,
    reopen: impl FnOnce(&mut S) -> bool,
) -> Ending<V> {
    if rules.distant_views {
        if let Some(view) = distant(state) {
            return Ending::DistantView(view);
        }
    }
    if rules.volume_views {
        if let Some(view) = volume(state) {
            return Ending::VolumeView(view);
        }
    }
    if rules.reopen_max > 0 && reopen(state) {
        return Ending::Reopened;
    }
    Ending::Complete
}

/// A place to look at a frontier the robot cannot reach, typically one seen through a gap narrower
/// than the robot: `viewpoint` is the least-cost reachable traversable cell `view_m` to `2·view_m`
/// from a frontier cell (`aim`, of segment `segment`) with a clear line of sight to it, so that the
/// camera sees the floor there and the space behind it. Without this, a run called the map complete
/// while space it could see from where it can drive was left unseen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DistantView {
    pub viewpoint: usize,
    pub segment: usize,
    pub aim: usize,
}

/// The cheapest [`DistantView`] over the frontier cells (flat indices, per segment) that `df` does not
/// reach and for which `given_up` is false; ties go to the lower viewpoint, then aim index.
pub fn distant_view(
    map: &Map,
    df: &DistanceField,
    segments: &[Vec<usize>],
    given_up: impl Fn(usize) -> bool,
    view_m: f64,
) -> Option<DistantView> {
    let grid = map.grid();
    let reach = (2.0 * view_m / grid.res).ceil() as i32;
    let mut best: Option<(f32, usize, usize, usize)> = None;
    for (k, seg) in segments.iter().enumerate() {
        for &aim in seg {
            let c = grid.cell(aim);
            if given_up(aim) || df.cost_to(aim).is_some() {
                continue;
            }
            let f = grid.center(c);
            for dy in -reach..=reach {
                for dx in -reach..=reach {
                    let Some(v) = grid.checked_index(Cell::new(c.x + dx, c.y + dy)) else {
                        continue;
                    };
                    let Some(cost) = df.cost_to(v) else {
                        continue;
                    };
                    if best.is_some_and(|(bc, bv, ba, _)| (cost, v, aim) >= (bc, bv, ba)) {
                        continue;
                    }
                    let d = (grid.center(grid.cell(v)) - f).norm();
                    if d < view_m || d > 2.0 * view_m || !map.is_traversable(v) {
                        continue;
                    }
                    if line_of_sight(map, grid, v, aim) {
                        best = Some((cost, v, aim, k));
                    }
                }
            }
        }
    }
    best.map(|(_, viewpoint, aim, segment)| DistantView {
        viewpoint,
        segment,
        aim,
    })
}

/// The action that drives along `df`'s least-cost path to `cell` (which `df` reaches) and, if
/// `look_on_arrival`, turns once there (`exact_arrival`: see [`Action::Follow`]); with the
/// path's cells after the robot's, which the planner checks for blockage. A path of one cell (the
/// robot is there) is a look around.
pub fn follow_to(
    grid: &GridSpec,
    df: &DistanceField,
    cell: usize,
    look_on_arrival: bool,
    exact_arrival: bool,
) -> (Action, Vec<usize>) {
    let path = df.path_to(grid, cell).expect("reachable by construction");
    if path.cells.len() < 2 {
        return (Action::LookAround, Vec::new());
    }
    let cells = path.cells.iter().skip(1).map(|c| grid.index(*c)).collect();
    let action = Action::Follow {
        path: path.cells.iter().map(|c| grid.center(*c)).collect(),
        look_on_arrival,
        exact_arrival,
    };
    (action, cells)
}
