//! What a frontier planner remembers about frontier cells: how each was looked at, and when it is
//! given up (the module doc of [`super`] tells the rules).

use super::state::{CellEvent, CellState};
use super::viewpoints::{
    away_from, first_sighted, lowest_unknown_beside, unknown_beside, viewpoint_ring,
};
use crate::config::{Additions, CameraConfig};
use crate::grid::{Cell, GridSpec};
use crate::map::sight::{camera_sees, Sight};
use crate::map::Map;
use crate::plan::search::DistanceField;
use crate::plan::{Count, PlanContext};
use nalgebra::Point2;
use std::cell::OnceCell;

/// The rules of `[additions]` that decide when a frontier cell is looked at again and when it is
/// given up (see `configs/default.toml`). With `look_from_on_top` off and `viewpoint_looks` 0, a
/// look that leaves a frontier open drops it, as Yamauchi's method does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VisitRules {
    /// A second approach, all the way onto the frontier, after the first look.
    pub look_from_on_top: bool,
    /// Looks from viewpoints chosen to see a cell before it is given up (0: none).
    pub viewpoint_looks: u32,
    /// A new viewpoint for a cell keeps this far from the earlier ones where it can, metres.
    pub viewpoint_away_m: f64,
    /// Failed approaches before a frontier is given up.
    pub approach_attempts: u32,
    /// Radius around an aim the robot failed to reach within which the frontier is given up,
    /// metres: about the robot's diameter, so that the next aim is a place the robot might fit.
    pub unreached_give_up_m: f64,
    /// Times a given-up cell may be reopened before `Complete` (0: never).
    pub reopen_max: u32,
}

impl From<&Additions> for VisitRules {
    fn from(a: &Additions) -> VisitRules {
        VisitRules {
            look_from_on_top: a.look_from_on_top,
            viewpoint_looks: a.viewpoint_looks,
            viewpoint_away_m: a.viewpoint_away_m.get(),
            approach_attempts: a.approach_attempts,
            unreached_give_up_m: a.unreached_give_up_m.get(),
            reopen_max: a.reopen_max,
        }
    }
}

/// Whether a frontier in the camera's blind zone around the robot (never approached) is looked at
/// before the goal chosen beyond the blind zone, whose path cost from the robot is `goal_cost`:
/// when `additions.blind_zone_step_back` is on and that cost exceeds
/// `additions.blind_zone_look_first_m` (0 by default: always).
///
/// Left until no other frontier was left, such a frontier was seen only if the robot's way passed
/// it. A goal across the plan left it behind, and the robot drove back for it at the end, in round
/// trips of 6–17 m. On 66 real plans × 3 random starts this rule makes THP drive 4.0 m less a run and
/// GREEDY 1.2 m; thresholds from 0 to 9 m were compared (docs/experiments.md).
pub fn blind_zone_first(rules: &Additions, goal_cost: f32) -> bool {
    rules.blind_zone_step_back && f64::from(goal_cost) > rules.blind_zone_look_first_m.get()
}

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
#[derive(Clone)]
pub struct FrontierVisits {
    rules: VisitRules,
    /// Per grid cell, where it stands in its visits as a frontier cell.
    state: Vec<CellState>,
    /// Looks from a viewpoint chosen to see the cell.
    near_looks: Vec<u8>,
    /// Times given up and then reopened before `Complete` ([`FrontierVisits::reopen_seeable`]), at
    /// most `reopen_max`.
    reopened: Vec<u8>,
    /// Where looks from chosen viewpoints were taken: (looked-at cell, the robot's cell).
    looked_from: Vec<(usize, usize)>,
    /// Failed attempts per aimed-at cell.
    attempts: Vec<(usize, u32)>,
    /// Looks taken from viewpoints chosen to see a frontier (`planner_stats.viewpoint_looks`:
    /// sighted viewpoints, blind-zone step backs and distant views).
    viewpoint_looks: Count,
    /// Cells reopened before `Complete` (`planner_stats.reopened`).
    reopened_cells: Count,
}

/// The default rules (tests).
#[cfg(test)]
impl Default for FrontierVisits {
    fn default() -> FrontierVisits {
        FrontierVisits::new(VisitRules::from(
            &crate::config::Config::default().additions,
        ))
    }
}

impl FrontierVisits {
    /// No cell visited yet, under `rules`.
    pub fn new(rules: VisitRules) -> FrontierVisits {
        FrontierVisits {
            rules,
            state: Vec::new(),
            near_looks: Vec::new(),
            reopened: Vec::new(),
            looked_from: Vec::new(),
            attempts: Vec::new(),
            viewpoint_looks: Count::default(),
            reopened_cells: Count::default(),
        }
    }

    /// The counters of the rules (`viewpoint_looks`, `reopened`), for `planner_stats`.
    pub fn stats(&self) -> [(&'static str, Count); 2] {
        [
            ("viewpoint_looks", self.viewpoint_looks),
            ("reopened", self.reopened_cells),
        ]
    }

    /// Sizes the memory for `grid` (a no-op once sized).
    pub fn ensure(&mut self, grid: &GridSpec) {
        if self.state.len() != grid.cells() {
            self.state = vec![CellState::Unvisited; grid.cells()];
            self.near_looks = vec![0; grid.cells()];
            self.reopened = vec![0; grid.cells()];
            self.looked_from.clear();
            self.attempts.clear();
        }
    }

    /// The state of `cell` (`Unvisited` before the memory is sized).
    fn state_of(&self, cell: usize) -> CellState {
        self.state.get(cell).copied().unwrap_or_default()
    }

    /// Changes the state of `cell` by `event` ([`CellState::next`]).
    fn apply(&mut self, cell: usize, event: CellEvent) {
        self.state[cell] = self.state[cell].next(event);
    }

    /// Whether the frontier cell was given up on.
    pub fn is_unobservable(&self, cell: usize) -> bool {
        self.state_of(cell).is_given_up()
    }

    /// The least-cost cell of `cells` (flat indices) that `df` reaches and that was not given up,
    /// with its cost; ties go to the lower index. Where THP and NBV-TSP aim in a frontier segment.
    pub fn cheapest_open(
        &self,
        cells: impl IntoIterator<Item = usize>,
        df: &DistanceField,
    ) -> Option<(f32, usize)> {
        cells
            .into_iter()
            .filter(|&i| !self.is_unobservable(i))
            .filter_map(|i| df.cost_to(i).map(|d| (d, i)))
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
    }

    /// Whether the frontier cell is next looked at from a viewpoint chosen to see it
    /// ([`FrontierVisits::sighted_viewpoint`]): it survived a look from a distance and one from on
    /// top of it, or it lay in the blind zone during its first look.
    pub fn needs_viewpoint(&self, cell: usize) -> bool {
        self.state_of(cell).needs_viewpoint()
    }

    /// For the cells of `visit` that need a viewpoint where none sees them: a cell that only lay in
    /// the blind zone gets the ordinary two approaches instead (it counts as looked at from a
    /// distance), so that no cell waits for a viewpoint that does not exist.
    pub fn no_viewpoint(&mut self, grid: &GridSpec, visit: &Visit) {
        for c in &visit.target {
            let i = grid.index(*c);
            // Without looks from on top there is no second approach to wait for.
            let approach = self.rules.look_from_on_top;
            self.apply(i, CellEvent::NoViewpoint { approach });
        }
    }

    /// Before calling the map done: reopens the given-up frontier cells of `segments` that `df`
    /// reaches and whose lowest unknown voxel beside them the camera may see ([`Sight::Possible`])
    /// from a reachable cell within its depth range, at most `reopen_max` times a cell. A
    /// reopened cell next gets one look from a viewpoint chosen to see it
    /// ([`FrontierVisits::sighted_viewpoint`]: away from the earlier ones where any other sees it),
    /// and that look gives it up again. Returns the cells reopened.
    /// Every reopening takes a `Possible` sight, and the next look comes from a new place: a look
    /// that missed a voxel at the edge of the view from one place says little about another.
    ///
    /// The map at the end of a run is not the map of the look that gave a cell up: on real plans
    /// the ground truth's camera saw the voxels beside frontiers left at `complete` from cells the
    /// final map held standable, and the map's own sight test agreed from most of them. A look
    /// can also change the map it was chosen by: traced on a real plan, the look from a viewpoint
    /// that surely saw the voxel left it unknown and no longer surely in sight from there, while
    /// another reachable cell surely saw it.
    ///
    /// A cell counts as given up here, or where `given_up_elsewhere` says so (a planner's own
    /// marks: NBV-TSP gives up frontier cells as viewpoints); the caller clears its own marks of
    /// the cells returned.
    pub fn reopen_seeable(
        &mut self,
        map: &Map,
        df: &DistanceField,
        segments: &[Vec<usize>],
        camera: &CameraConfig,
        given_up_elsewhere: impl Fn(usize) -> bool,
    ) -> Vec<usize> {
        let (near, far) = (camera.min_range_m.get(), camera.max_range_m.get());
        let mut reopened = Vec::new();
        for &i in segments.iter().flatten() {
            let given_up = self.state[i].is_given_up() || given_up_elsewhere(i);
            // The bound is checked here too: the sight tests cost a scan of the ring.
            if !given_up
                || u32::from(self.reopened[i]) >= self.rules.reopen_max
                || df.cost_to(i).is_none()
            {
                continue;
            }
            let lowest = lowest_unknown_beside(map, i);
            if lowest.is_empty() {
                continue;
            }
            let wide = viewpoint_ring(map, df, i, near, far);
            if first_sighted(map, &wide, &lowest, camera, Sight::Possible).is_some() {
                self.reopened[i] += 1;
                self.apply(i, CellEvent::Reopen);
                self.near_looks[i] = self.near_looks[i].max(1);
                reopened.push(i);
            }
        }
        if !reopened.is_empty() {
            self.reopened_cells.add(reopened.len() as f64);
        }
        reopened
    }

    /// Where the looks at `cell` from chosen viewpoints were taken.
    fn looked_from_at(&self, grid: &GridSpec, cell: usize) -> Vec<Point2<f64>> {
        (self.looked_from.iter())
            .filter(|&&(c, _)| c == cell)
            .map(|&(_, v)| grid.center(grid.cell(v)))
            .collect()
    }

    /// The least-cost traversable cell `view_m` to `2·view_m` from the frontier cell `aim` from
    /// which the camera surely sees the lowest unknown voxel of an Unknown column beside it
    /// ([`Sight::Sure`]). Where no cell of that ring does, the least-cost cell within the camera's
    /// depth range of `aim` that surely sees such a voxel; then the same two rings for a cell that
    /// may see it ([`Sight::Possible`]); and failing those, a cell within the depth range that
    /// surely, then possibly, sees any unknown voxel of those columns (a look at the upper voxels
    /// alone leaves the column Unknown, and its second look gave the frontier up).
    ///
    /// The lowest voxel is what keeps the column Unknown (a column is known only with its lowest
    /// voxel, `map.column_known_fraction`), and beside a wall or furniture only steep rays from
    /// 1–2.5 m reach it: a viewpoint picked by cost alone often looked over it, and the frontier
    /// was given up. In a nook no cell of the ring may see it, while the rest of the column is
    /// still in view from nearer or farther; giving the cell up without that look ended runs
    /// `complete` with observable space unseen beside a frontier.
    ///
    /// Cells within `viewpoint_away_m` of a viewpoint a look at `aim` was taken from are chosen only
    /// where no other cell is: a second look from the same place mostly shows what the first did,
    /// but the map may have changed since, or the robot stand a little apart.
    pub fn sighted_viewpoint(
        &self,
        map: &Map,
        df: &DistanceField,
        aim: usize,
        view_m: f64,
        camera: &CameraConfig,
    ) -> Option<usize> {
        let grid = map.grid();
        let ring = viewpoint_ring(map, df, aim, view_m, 2.0 * view_m);
        let (near, far) = (camera.min_range_m.get(), camera.max_range_m.get());
        // The wide ring scans the whole grid: once, and only if a tier needs it.
        let wide_ring = OnceCell::new();
        let wide_ring = || wide_ring.get_or_init(|| viewpoint_ring(map, df, aim, near, far));
        let wide = || wide_ring().clone();
        let lowest = lowest_unknown_beside(map, aim);
        let tiers = |ring: &[(f32, usize)], wide: &dyn Fn() -> Vec<(f32, usize)>| {
            first_sighted(map, ring, &lowest, camera, Sight::Sure).or_else(|| {
                let wide = wide();
                first_sighted(map, &wide, &lowest, camera, Sight::Sure)
                    .or_else(|| first_sighted(map, ring, &lowest, camera, Sight::Possible))
                    .or_else(|| first_sighted(map, &wide, &lowest, camera, Sight::Possible))
                    .or_else(|| {
                        let any = unknown_beside(map, aim);
                        first_sighted(map, &wide, &any, camera, Sight::Sure)
                            .or_else(|| first_sighted(map, &wide, &any, camera, Sight::Possible))
                    })
            })
        };
        let from = self.looked_from_at(grid, aim);
        if from.is_empty() {
            return tiers(&ring, &wide);
        }
        let away_m = self.rules.viewpoint_away_m;
        let away = |ring: &[(f32, usize)]| away_from(grid, &from, ring, away_m);
        tiers(&away(&ring), &|| away(wide_ring())).or_else(|| tiers(&ring, &wide))
    }

    /// Whether the robot stopped short of the frontier cell and looked at it (its next approach goes
    /// all the way).
    pub fn was_approached(&self, cell: usize) -> bool {
        self.state_of(cell).was_approached()
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
        let view_m = if self.was_approached(aim) {
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

    /// [`FrontierVisits::finished`] with the robot's position, blind zone and camera from `ctx`.
    pub fn finished_in(&mut self, ctx: &PlanContext, visit: &Visit, reached: bool) {
        self.finished(
            ctx.map,
            visit,
            reached,
            ctx.pose.position(),
            ctx.cfg.search.near_unknown_radius_m,
            &ctx.cfg.camera,
        );
    }

    /// Records how an attempt at `visit` ended: `reached` its (cut-short) goal and looked from
    /// `robot`, or not. The camera does not see the floor within `blind_zone_m` of the robot, so a
    /// look counts only for the target cells beyond it:
    /// - a first look marks those cells approached, and the cells inside the blind zone `blinded`;
    /// - a look from the frontier itself marks the approached cells within `blind_zone_m` of the
    ///   robot `topped`, and gives up those topped before (cells farther along the segment were
    ///   not looked at from on top);
    /// - a look from a viewpoint chosen to see the frontier (`near_view`) gives up the cells it
    ///   surely could see (the [`Sight::Sure`] test to the unknown voxel beside each), and any cell
    ///   on its second such look; a cell it does not give up counts as looked at from a distance
    ///   (approached), so its next visit goes all the way onto it rather than to another step back
    ///   from the same place.
    ///
    /// Giving up every target cell after a look from on top of it ended runs `complete` with
    /// frontiers whose floor no look had shown (the segment grew, or the first look stood too close).
    pub fn finished(
        &mut self,
        map: &Map,
        visit: &Visit,
        reached: bool,
        robot: Point2<f64>,
        blind_zone_m: f64,
        camera: &CameraConfig,
    ) {
        if !visit.is_open(map) {
            return;
        }
        let grid = map.grid();
        let in_blind_zone =
            |c: Cell| (grid.center(c) - robot).norm_squared() <= blind_zone_m * blind_zone_m;
        // A second approach goes all the way onto the frontier, to look from on top. The motion
        // guard keeps the robot's disc off never-seen cells, so beside unseen floor it stops short,
        // blocked; stopped within the blind zone, it stands where a look from on top would, and the
        // attempt counts as that look (the cell next needs a sighted viewpoint, not another try).
        let reached = reached
            || (!visit.near_view
                && self.state[visit.aim].was_approached()
                && in_blind_zone(grid.cell(visit.aim)));
        if reached {
            if visit.near_view {
                // Given up: the cells this look could see (the missing voxel beside them was in
                // view and stayed unknown), and any cell on its second such look. Cells that had
                // only a look from a distance still get their approach; the aimed cell always
                // counts (a distant view aims at a cell the robot cannot reach, which would otherwise
                // be looked at from the same viewpoint again and again).
                let from = grid.cell_of(robot).map(|c| grid.index(c));
                self.viewpoint_looks.add(1.0);
                let max_looks = self.rules.viewpoint_looks.max(1);
                for c in &visit.target {
                    let i = grid.index(*c);
                    let s = self.state[i];
                    let waits_for_approach =
                        s.was_approached() && !s.was_topped() && !s.is_blinded();
                    if waits_for_approach && i != visit.aim {
                        continue;
                    }
                    let seeable = from.is_some_and(|v| {
                        lowest_unknown_beside(map, i)
                            .iter()
                            .any(|&t| camera_sees(map, v, t, camera, Sight::Sure))
                    });
                    self.near_looks[i] += 1;
                    if let Some(v) = from {
                        self.looked_from.push((i, v));
                    }
                    let give_up = seeable || u32::from(self.near_looks[i]) >= max_looks;
                    self.apply(i, CellEvent::ViewpointLook { give_up });
                }
            } else if self.state[visit.aim].was_approached() {
                for c in &visit.target {
                    let i = grid.index(*c);
                    if self.state[i].was_approached() && in_blind_zone(*c) {
                        self.apply(i, CellEvent::LookFromOnTop);
                    }
                }
            } else {
                // The first look. Without looks from on top, a cell beyond the blind zone that it
                // left open next gets a viewpoint look if those are on, and is dropped if not; a
                // cell inside the blind zone, which the look could not show, likewise.
                let (on_top, viewpoints) =
                    (self.rules.look_from_on_top, self.rules.viewpoint_looks > 0);
                for c in &visit.target {
                    let i = grid.index(*c);
                    let event = if !in_blind_zone(*c) {
                        match (on_top, viewpoints) {
                            (true, _) => CellEvent::SeenFromAfar,
                            (false, true) => CellEvent::LeftOpenFromAfar,
                            (false, false) => {
                                self.apply(i, CellEvent::SeenFromAfar);
                                CellEvent::GiveUp
                            }
                        }
                    } else if viewpoints || self.state[i].was_approached() {
                        CellEvent::MissedInBlindZone
                    } else {
                        CellEvent::GiveUp
                    };
                    self.apply(i, event);
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
        if entry.1 >= self.rules.approach_attempts {
            self.give_up_near_aim(grid, visit);
        }
    }

    /// Marks the target cells within `unreached_give_up_m` of the aim unobservable: the robot could
    /// not get there, but the rest of the segment (up to a metre of frontier) may well be reachable
    /// from another side, and giving it all up ended runs with whole rooms behind it unentered.
    fn give_up_near_aim(&mut self, grid: &GridSpec, visit: &Visit) {
        self.give_up_around(grid, visit.aim, visit.target.iter().map(|c| grid.index(*c)));
    }

    /// Marks `aim` and the `cells` within `unreached_give_up_m` of it unobservable: a place the
    /// robot failed to get to.
    pub fn give_up_around(
        &mut self,
        grid: &GridSpec,
        aim: usize,
        cells: impl IntoIterator<Item = usize>,
    ) {
        let p = grid.center(grid.cell(aim));
        self.apply(aim, CellEvent::GiveUp);
        for i in cells {
            if (grid.center(grid.cell(i)) - p).norm() <= self.rules.unreached_give_up_m {
                self.apply(i, CellEvent::GiveUp);
            }
        }
    }
}

#[cfg(test)]
mod tests;
