//! Frontier visits, shared by the frontier-driven planners (GREEDY and THP).
//!
//! A forward camera cannot see the floor right in front of it, so a frontier is approached in two
//! tries: first the robot stops `view_m` short of it (along the path) and turns once in place to look
//! into the unknown; if the frontier survives, the next approach goes all the way. A frontier that is
//! still a frontier after the robot stood on it and looked, or that the robot failed to reach twice, is
//! marked unobservable and skipped from then on (THP §3.4: "done after the robot has looked at it").

use super::search::DistanceField;
use crate::grid::{Cell, GridSpec};
use crate::map::Map;
use nalgebra::Point2;

/// Failed attempts after which a frontier is given up.
const MAX_ATTEMPTS: u32 = 2;

/// Radius around an aim the robot failed to reach within which the frontier is given up, metres:
/// about the robot's diameter, so that the next aim is a place the robot might fit.
const UNREACHED_GIVE_UP_M: f64 = 0.5;

/// One frontier being visited.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Visit {
    /// Cells of the frontier segment.
    pub target: Vec<Cell>,
    /// The cell the robot aims at.
    pub aim: usize,
    /// The frontier lies in the camera's blind zone and the robot steps back to see it.
    pub near_view: bool,
}

impl Visit {
    /// Whether any cell of the target is still a frontier.
    pub fn is_open(&self, map: &Map) -> bool {
        let grid = map.grid();
        self.target.iter().any(|c| map.is_frontier(grid.index(*c)))
    }
}

/// What the planner remembers about frontier cells across plans.
#[derive(Clone, Default)]
pub struct FrontierVisits {
    unobservable: Vec<bool>,
    approached: Vec<bool>,
    /// Failed attempts per aimed-at cell.
    attempts: Vec<(usize, u32)>,
}

impl FrontierVisits {
    /// Sizes the memory for `grid` (a no-op once sized).
    pub fn ensure(&mut self, grid: &GridSpec) {
        if self.unobservable.len() != grid.cells() {
            self.unobservable = vec![false; grid.cells()];
            self.approached = vec![false; grid.cells()];
            self.attempts.clear();
        }
    }

    /// Whether the frontier cell was given up on.
    pub fn is_unobservable(&self, cell: usize) -> bool {
        self.unobservable.get(cell).copied().unwrap_or(false)
    }

    /// Whether the robot stopped short of the frontier cell and looked at it (its next approach goes
    /// all the way).
    pub fn was_approached(&self, cell: usize) -> bool {
        self.approached.get(cell).copied().unwrap_or(false)
    }

    /// The cells of `path` (start first, ending at `aim`) to drive: all of them if `aim` was approached
    /// before, otherwise those up to `view_m` (measured along the path) short of the end.
    pub fn cut_short<'a>(
        &self,
        grid: &GridSpec,
        path: &'a [Cell],
        aim: usize,
        view_m: f64,
    ) -> &'a [Cell] {
        let view_m = if self.approached.get(aim).copied().unwrap_or(false) {
            0.0
        } else {
            view_m
        };
        let mut keep = path.len();
        let mut remaining = 0.0;
        while keep > 1 && remaining < view_m {
            remaining += (grid.center(path[keep - 1]) - grid.center(path[keep - 2])).norm();
            keep -= 1;
        }
        &path[..keep]
    }

    /// Records how an attempt at `visit` ended: `reached` its (cut-short) goal and looked, or not.
    pub fn finished(&mut self, map: &Map, visit: &Visit, reached: bool) {
        if !visit.is_open(map) {
            return;
        }
        let grid = map.grid();
        if reached {
            if self.approached[visit.aim] || visit.near_view {
                // Looked from the frontier itself and it is still one: nothing more can be seen.
                self.give_up(grid, visit);
            } else {
                for c in &visit.target {
                    self.approached[grid.index(*c)] = true;
                }
            }
            return;
        }
        let entry = match self.attempts.iter_mut().find(|(c, _)| *c == visit.aim) {
            Some(e) => e,
            None => {
                self.attempts.push((visit.aim, 0));
                self.attempts.last_mut().expect("just pushed")
            }
        };
        entry.1 += 1;
        if entry.1 >= MAX_ATTEMPTS {
            self.give_up_near_aim(grid, visit);
        }
    }

    /// Marks the target cells within [`UNREACHED_GIVE_UP_M`] of the aim unobservable: the robot could
    /// not get there, but the rest of the segment (up to a metre of frontier) may well be reachable
    /// from another side, and giving it all up ended runs with whole rooms behind it unentered.
    fn give_up_near_aim(&mut self, grid: &GridSpec, visit: &Visit) {
        self.give_up_around(grid, visit.aim, visit.target.iter().map(|c| grid.index(*c)));
    }

    /// Marks `aim` and the `cells` within [`UNREACHED_GIVE_UP_M`] of it unobservable: a place the
    /// robot failed to get to.
    pub fn give_up_around(
        &mut self,
        grid: &GridSpec,
        aim: usize,
        cells: impl IntoIterator<Item = usize>,
    ) {
        let p = grid.center(grid.cell(aim));
        self.unobservable[aim] = true;
        for i in cells {
            if (grid.center(grid.cell(i)) - p).norm() <= UNREACHED_GIVE_UP_M {
                self.unobservable[i] = true;
            }
        }
    }

    /// Marks every cell of the visit's target unobservable.
    pub fn give_up(&mut self, grid: &GridSpec, visit: &Visit) {
        for c in &visit.target {
            self.unobservable[grid.index(*c)] = true;
        }
    }
}

/// For a frontier at `f` in the camera's blind zone: the least-cost traversable cell `view_m` to
/// `2·view_m` from it, from which the camera sees the floor there.
pub fn blind_zone_viewpoint(
    map: &Map,
    df: &DistanceField,
    f: Point2<f64>,
    view_m: f64,
) -> Option<usize> {
    let grid = map.grid();
    (0..grid.cells())
        .filter(|&i| map.is_traversable(i))
        .filter_map(|i| {
            let d = (grid.center(grid.cell(i)) - f).norm();
            (d >= view_m && d <= 2.0 * view_m)
                .then(|| df.cost_to(i).map(|c| (c, i)))
                .flatten()
        })
        .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
        .map(|(_, i)| i)
}

/// Whether no obstacle cell lies on the straight line between two cell centres (sampled every half
/// cell).
pub fn line_of_sight(map: &Map, grid: &GridSpec, a: usize, b: usize) -> bool {
    let (pa, pb) = (grid.center(grid.cell(a)), grid.center(grid.cell(b)));
    let steps = (((pb - pa).norm() / (0.5 * grid.res)).ceil() as usize).max(1);
    (0..=steps).all(|s| {
        let p = pa + (pb - pa) * (s as f64 / steps as f64);
        grid.cell_of(p)
            .is_some_and(|c| !map.is_obstacle(grid.index(c)))
    })
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
/// `look_on_arrival`, turns once there; with the path's cells after the robot's, which the planner
/// checks for blockage. A path of one cell (the robot is there) is a look around.
pub fn follow_to(
    grid: &GridSpec,
    df: &DistanceField,
    cell: usize,
    look_on_arrival: bool,
) -> (super::Action, Vec<usize>) {
    let path = df.path_to(grid, cell).expect("reachable by construction");
    if path.cells.len() < 2 {
        return (super::Action::LookAround, Vec::new());
    }
    let cells = path.cells.iter().skip(1).map(|c| grid.index(*c)).collect();
    let action = super::Action::Follow {
        path: path.cells.iter().map(|c| grid.center(*c)).collect(),
        look_on_arrival,
    };
    (action, cells)
}
