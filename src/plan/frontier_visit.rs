//! Frontier visits, shared by the frontier-driven planners (GREEDY and THP, and NBV-TSP's looks at
//! frontiers before `Complete`).
//!
//! A forward camera cannot see the floor right in front of it, so a frontier is approached in two
//! tries: first the robot stops `view_m` short of it (along the path) and turns once in place to
//! look into the unknown; if the frontier survives, the next approach goes all the way. A frontier
//! cell that is still a frontier after a look from a distance and then a look from on top of it, or
//! after a look from a viewpoint chosen to see it, or that the robot failed to reach twice, is
//! marked unobservable and skipped from then on (THP §3.4: "done after the robot has looked at
//! it"). A look counts only for the cells beyond the blind zone (`search.near_unknown_radius_m`)
//! around the robot. A second approach that the motion guard stops short within the blind zone
//! (beside never-seen floor it cannot get any nearer) counts as the look from on top, not as a
//! failed attempt. With that and the wider sighted viewpoint
//! ([`FrontierVisits::sighted_viewpoint`]), runs on 33 real plans × 3 starts that ended `complete`
//! with an observable frontier left went from 20 to 14 (GREEDY) and from 24 to 11 (THP)
//! (BENCHMARKS.md, "Frontiers given up too early"). A look from a chosen viewpoint is driven to
//! exactly (`exact_arrival`, [`super::Action::Follow`]): 0.2 m off it the aimed voxel was often out
//! of view. A viewpoint is first sought where the camera surely sees the aimed voxel (its centre,
//! through no occupied voxel), then where it may see it (a point of the voxel, past the ray hits of
//! the occupied voxels on the way: [`Sight`]); a look gives a cell up at once only if the camera
//! surely saw it. Before calling the map done, a planner reopens each given-up frontier cell it can
//! reach whose unknown floor the camera would see from a reachable cell of the final map
//! ([`FrontierVisits::reopen_seeable`]: if the camera may see it, at most `additions.reopen_max` times): a
//! look from a chosen viewpoint, away from the earlier ones where another sees it, then decides it.

use super::search::DistanceField;
use super::Count;
use crate::config::{Additions, CameraConfig};
use crate::grid::{Cell, GridSpec};
use crate::map::occupancy::{traverse_while, ObstacleBox, VoxelState};
use crate::map::Map;
use nalgebra::{Point2, Point3, Vector3};
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
/// it. A goal across the plan left it behind, and the robot drove back for it at the end: THP on
/// `plan_ade2a47d0b`, random start 1, made four such round trips of 6–17 m (99.0 m in all; 64.1 m
/// with this rule). On 66 real plans × 3 random starts THP drove 4.0 m less a run and GREEDY 1.2 m
/// (BENCHMARKS.md, where thresholds from 0 to 9 m are compared).
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
    unobservable: Vec<bool>,
    approached: Vec<bool>,
    /// Looked at from a distance and then from on top, and still a frontier.
    topped: Vec<bool>,
    /// Lay in the camera's blind zone during a first look, which therefore showed nothing of it.
    blinded: Vec<bool>,
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
            unobservable: Vec::new(),
            approached: Vec::new(),
            topped: Vec::new(),
            blinded: Vec::new(),
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
        if self.unobservable.len() != grid.cells() {
            self.unobservable = vec![false; grid.cells()];
            self.approached = vec![false; grid.cells()];
            self.topped = vec![false; grid.cells()];
            self.blinded = vec![false; grid.cells()];
            self.near_looks = vec![0; grid.cells()];
            self.reopened = vec![0; grid.cells()];
            self.looked_from.clear();
            self.attempts.clear();
        }
    }

    /// Whether the frontier cell was given up on.
    pub fn is_unobservable(&self, cell: usize) -> bool {
        self.unobservable.get(cell).copied().unwrap_or(false)
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
        self.topped.get(cell).copied().unwrap_or(false)
            || self.blinded.get(cell).copied().unwrap_or(false)
    }

    /// For the cells of `visit` that need a viewpoint where none sees them: a cell that only lay in
    /// the blind zone gets the ordinary two approaches instead (it counts as looked at from a
    /// distance), so that no cell waits for a viewpoint that does not exist.
    pub fn no_viewpoint(&mut self, grid: &GridSpec, visit: &Visit) {
        for c in &visit.target {
            let i = grid.index(*c);
            if self.blinded[i] && !self.topped[i] {
                self.blinded[i] = false;
                // Without looks from on top there is no second approach to wait for.
                if self.rules.look_from_on_top {
                    self.approached[i] = true;
                } else {
                    self.unobservable[i] = true;
                }
            }
        }
    }

    /// Before calling the map done: reopens the given-up frontier cells of `segments` that `df`
    /// reaches and whose lowest unknown voxel beside them the camera may see ([`Sight::Possible`])
    /// from a reachable cell within its depth range, at most `reopen_max` times a cell. A
    /// reopened cell next gets one look from a viewpoint chosen to see it
    /// ([`FrontierVisits::sighted_viewpoint`]: away from the earlier ones where any other sees it),
    /// and that look gives it up again. Returns the cells reopened.
    ///
    /// Before, only the first reopening took a `Possible` sight and later ones needed `Sure`, and
    /// the next look came from the same viewpoint as the last whenever the map had not changed; a
    /// look that missed a voxel at the edge of the view from one place says little about another
    /// (BENCHMARKS.md, "Looks from a new place").
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
            let given_up = self.unobservable[i] || given_up_elsewhere(i);
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
                self.unobservable[i] = false;
                self.topped[i] = true;
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

    /// [`FrontierVisits::finished`] with the robot's position, blind zone and camera from `ctx`.
    pub fn finished_in(&mut self, ctx: &super::PlanContext, visit: &Visit, reached: bool) {
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
                && self.approached[visit.aim]
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
                    let waits_for_approach =
                        self.approached[i] && !self.topped[i] && !self.blinded[i];
                    if waits_for_approach && i != visit.aim {
                        continue;
                    }
                    self.blinded[i] = false;
                    let seeable = from.is_some_and(|v| {
                        lowest_unknown_beside(map, i)
                            .iter()
                            .any(|&t| camera_sees(map, v, t, camera, Sight::Sure))
                    });
                    self.near_looks[i] += 1;
                    if let Some(v) = from {
                        self.looked_from.push((i, v));
                    }
                    if seeable || u32::from(self.near_looks[i]) >= max_looks {
                        self.unobservable[i] = true;
                    } else {
                        self.approached[i] = true;
                    }
                }
            } else if self.approached[visit.aim] {
                for c in &visit.target {
                    let i = grid.index(*c);
                    if self.approached[i] && in_blind_zone(*c) {
                        if self.topped[i] {
                            self.unobservable[i] = true;
                        }
                        self.topped[i] = true;
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
                    if !in_blind_zone(*c) {
                        self.approached[i] = true;
                        if !on_top {
                            if viewpoints {
                                self.topped[i] = true;
                            } else {
                                self.unobservable[i] = true;
                            }
                        }
                    } else if !self.approached[i] {
                        if viewpoints {
                            self.blinded[i] = true;
                        } else {
                            self.unobservable[i] = true;
                        }
                    }
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
        self.unobservable[aim] = true;
        for i in cells {
            if (grid.center(grid.cell(i)) - p).norm() <= self.rules.unreached_give_up_m {
                self.unobservable[i] = true;
            }
        }
    }
}

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

/// For the frontier cell `aim` in the camera's blind zone: the least-cost traversable cell `view_m`
/// to `2·view_m` from it from which the camera surely, then possibly, sees the floor beside it
/// ([`FrontierVisits::sighted_viewpoint`]'s first and third tiers); if none of that ring does, the
/// least-cost cell of the ring.
pub fn blind_zone_viewpoint(
    map: &Map,
    df: &DistanceField,
    aim: usize,
    view_m: f64,
    camera: &CameraConfig,
) -> Option<usize> {
    let ring = viewpoint_ring(map, df, aim, view_m, 2.0 * view_m);
    let lowest = lowest_unknown_beside(map, aim);
    first_sighted(map, &ring, &lowest, camera, Sight::Sure)
        .or_else(|| first_sighted(map, &ring, &lowest, camera, Sight::Possible))
        .or(ring.first().map(|&(_, v)| v))
}

/// The cells of `ring` farther than `away_m` from every point of `from`.
fn away_from(
    grid: &GridSpec,
    from: &[Point2<f64>],
    ring: &[(f32, usize)],
    away_m: f64,
) -> Vec<(f32, usize)> {
    (ring.iter().copied())
        .filter(|&(_, v)| {
            let p = grid.center(grid.cell(v));
            from.iter().all(|f| (p - f).norm() > away_m)
        })
        .collect()
}

/// The reachable traversable cells `from_m` to `to_m` from `aim`, by cost (then index).
fn viewpoint_ring(
    map: &Map,
    df: &DistanceField,
    aim: usize,
    from_m: f64,
    to_m: f64,
) -> Vec<(f32, usize)> {
    let grid = map.grid();
    let f = grid.center(grid.cell(aim));
    let mut ring: Vec<(f32, usize)> = (0..grid.cells())
        .filter(|&i| map.is_traversable(i))
        .filter_map(|i| {
            let d = (grid.center(grid.cell(i)) - f).norm();
            (d >= from_m && d <= to_m)
                .then(|| df.cost_to(i).map(|c| (c, i)))
                .flatten()
        })
        .collect();
    ring.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    ring
}

/// The first cell of `ring` from which the camera sees one of the voxels `targets` (as sure as
/// `sight`).
fn first_sighted(
    map: &Map,
    ring: &[(f32, usize)],
    targets: &[usize],
    camera: &CameraConfig,
    sight: Sight,
) -> Option<usize> {
    ring.iter().map(|&(_, v)| v).find(|&v| {
        targets
            .iter()
            .any(|&t| camera_sees(map, v, t, camera, sight))
    })
}

/// The Unknown 4-neighbour columns of `cell`.
fn unknown_columns_beside(map: &Map, cell: usize) -> impl Iterator<Item = usize> + '_ {
    let grid = map.grid();
    let c = grid.cell(cell);
    crate::grid::NEIGHBOURS_8[..4]
        .iter()
        .filter_map(move |&(dx, dy)| grid.checked_index(Cell::new(c.x + dx, c.y + dy)))
        .filter(|&j| map.is_unknown(j))
}

/// The unknown voxels of column `j` above the floor layer, lowest first.
fn unknown_voxels_of(map: &Map, j: usize) -> impl Iterator<Item = usize> + '_ {
    let occ = map.occupancy();
    let grid = occ.grid();
    (1..grid.nz)
        .map(move |iz| grid.voxel_index(grid.cell(j), iz))
        .filter(|&v| occ.state(v) == VoxelState::Unknown)
}

/// The lowest unknown voxel above the floor layer of each Unknown 4-neighbour column of `cell`.
fn lowest_unknown_beside(map: &Map, cell: usize) -> Vec<usize> {
    unknown_columns_beside(map, cell)
        .filter_map(|j| unknown_voxels_of(map, j).next())
        .collect()
}

/// Every unknown voxel above the floor layer of each Unknown 4-neighbour column of `cell`.
fn unknown_beside(map: &Map, cell: usize) -> Vec<usize> {
    unknown_columns_beside(map, cell)
        .flat_map(|j| unknown_voxels_of(map, j))
        .collect()
}

/// Offsets of the points [`Sight::Possible`] tries in a voxel, in voxels from its centre (centre
/// first): a 3 × 3 × 3 lattice a little inside the faces.
const SIGHT_POINTS: [f64; 3] = [0.0, -0.4, 0.4];

/// How sure a sight test must be.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Sight {
    /// The camera may see the voxel: some point of a 3 × 3 × 3 lattice inside it
    /// ([`SIGHT_POINTS`]) is in view, and the segment to it crosses no known obstacle surface: an
    /// occupied voxel blocks only where the segment meets its column's obstacle box (the extent of
    /// the ray hits there, [`ObstacleBox`]), as a wall fills a tenth of the voxels it lies in and
    /// the camera's rays pass the rest. For choosing where to look from.
    Possible,
    /// The camera surely sees it: its centre is in view, through no occupied voxel at all. For
    /// giving a frontier up after one look: a look from where the camera only may see the voxel
    /// (a corner at the edge of the view, past a wall's end) is often missed by the discrete rays.
    Sure,
}

/// Whether the camera, standing at cell `from` and turning in place, sees voxel `target` (`sight`
/// says how sure): a point of the voxel within the vertical field of view and the depth range, with
/// the segment to it clear.
///
/// Testing the centre alone, through whole occupied voxels, found no viewpoint for most unseen
/// voxels left beside frontiers at `complete` on the dev plans, while the ground truth's camera saw
/// them from cells the robot's map held standable (BENCHMARKS.md, "Sight test as the camera sees").
fn camera_sees(map: &Map, from: usize, target: usize, camera: &CameraConfig, sight: Sight) -> bool {
    let occ = map.occupancy();
    let grid = occ.grid();
    let p = grid.center(grid.cell(from));
    let origin = Point3::new(p.x, p.y, camera.mount_height_m.get());
    let (cell, iz) = grid.voxel_parts(target);
    let q = grid.center(grid.cell(cell));
    let half_vfov = 0.5 * camera.vfov_deg.to_radians();
    let (near, far) = (camera.min_range_m.get(), camera.max_range_m.get());
    let sees_point = |dx: f64, dy: f64, dz: f64| {
        let to = Vector3::new(
            q.x + dx * grid.res - p.x,
            q.y + dy * grid.res - p.y,
            grid.layer_center(iz) + dz * grid.res - origin.z,
        );
        let range = to.norm();
        if range < near || range > far || to.z.abs().atan2(to.xy().norm()) > half_vfov {
            return false;
        }
        let dir = to / range;
        let mut seen = false;
        traverse_while(grid, origin, dir, range, |v, t_in, t_out| {
            if v == target {
                seen = true;
                return false;
            }
            occ.state(v) != VoxelState::Occupied
                || (sight == Sight::Possible
                    && !segment_meets_box(occ, grid, v, origin, dir, t_in, t_out))
        });
        seen
    };
    match sight {
        Sight::Sure => sees_point(0.0, 0.0, 0.0),
        Sight::Possible => SIGHT_POINTS.iter().any(|&dx| {
            SIGHT_POINTS
                .iter()
                .any(|&dy| SIGHT_POINTS.iter().any(|&dz| sees_point(dx, dy, dz)))
        }),
    }
}

/// Whether the part `[t_in, t_out]` of the ray `origin + t·dir` inside occupied voxel `v` meets the
/// obstacle box of `v`'s column in plan view (the whole cell when the column has no recorded hit).
fn segment_meets_box(
    occ: &crate::map::Occupancy,
    grid: &GridSpec,
    v: usize,
    origin: Point3<f64>,
    dir: Vector3<f64>,
    t_in: f64,
    t_out: f64,
) -> bool {
    let (c, _) = grid.voxel_parts(v);
    let b = occ.obstacle_box(c);
    let b = if b.is_empty() {
        ObstacleBox::cell(grid, grid.cell(c))
    } else {
        b
    };
    // Tested as the segment's bounding box in plan view against the box: exact for a segment along
    // an axis, and for a diagonal one it may call a pass by the box's corner a hit (conservative:
    // it never sees through the hits). The exact test (the segment clipped to the box) was tried
    // and not kept: it let viewpoints whose lines graze a wall's end pass, and looks from them
    // missed more (BENCHMARKS.md, 2026-11-27 evening).
    let (x0, x1) = (origin.x + dir.x * t_in, origin.x + dir.x * t_out);
    let (y0, y1) = (origin.y + dir.y * t_in, origin.y + dir.y * t_out);
    x0.max(x1) >= f64::from(b.min[0])
        && x0.min(x1) <= f64::from(b.max[0])
        && y0.max(y1) >= f64::from(b.min[1])
        && y0.min(y1) <= f64::from(b.max[1])
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
/// `look_on_arrival`, turns once there (`exact_arrival`: see [`super::Action::Follow`]); with the
/// path's cells after the robot's, which the planner checks for blockage. A path of one cell (the
/// robot is there) is a look around.
pub fn follow_to(
    grid: &GridSpec,
    df: &DistanceField,
    cell: usize,
    look_on_arrival: bool,
    exact_arrival: bool,
) -> (super::Action, Vec<usize>) {
    let path = df.path_to(grid, cell).expect("reachable by construction");
    if path.cells.len() < 2 {
        return (super::Action::LookAround, Vec::new());
    }
    let cells = path.cells.iter().skip(1).map(|c| grid.index(*c)).collect();
    let action = super::Action::Follow {
        path: path.cells.iter().map(|c| grid.center(*c)).collect(),
        look_on_arrival,
        exact_arrival,
    };
    (action, cells)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use crate::map::testing::{furnished_room_setup, seen_from};
    use crate::Pose2;
    use std::f64::consts::FRAC_PI_2;

    /// One look into a furnished room leaves frontier segments; a visit to the longest one.
    fn open_visit() -> (Map, Visit) {
        let cfg = Config::default();
        let (grid, bvh) = furnished_room_setup(&cfg);
        let map = seen_from(grid, &cfg, &bvh, [Pose2::new(1.0, 4.0, 0.0)]);
        let target = map
            .frontiers()
            .into_iter()
            .max_by_key(|s| s.cells.len())
            .expect("a frontier")
            .cells;
        assert!(target.len() >= 4, "{}", target.len());
        let aim = grid.index(target[0]);
        let visit = Visit {
            target,
            aim,
            near_view: false,
        };
        assert!(visit.is_open(&map));
        (map, visit)
    }

    /// [`open_visit`] after a first look from 5 m away, which marks every cell approached (blind
    /// zone 1 m), with the planners' memory of it.
    fn looked_at_from_afar() -> (Map, Visit, FrontierVisits) {
        let (map, visit) = open_visit();
        let grid = map.grid();
        let mut visits = FrontierVisits::default();
        visits.ensure(grid);
        let aim_p = grid.center(grid.cell(visit.aim));
        let afar = Point2::new(aim_p.x - 5.0, aim_p.y);
        visits.finished(&map, &visit, true, afar, 1.0, &Config::default().camera);
        assert!(visit.target.iter().all(|c| {
            let i = grid.index(*c);
            visits.was_approached(i) && !visits.needs_viewpoint(i)
        }));
        (map, visit, visits)
    }

    /// [`open_visit`] after a first look from on its aim with the whole segment in the blind zone,
    /// which leaves every cell wanting a viewpoint, with the planners' memory of it.
    fn looked_at_from_on_it() -> (Map, Visit, FrontierVisits) {
        let (map, visit) = open_visit();
        let grid = map.grid();
        let mut visits = FrontierVisits::default();
        visits.ensure(grid);
        let robot = grid.center(grid.cell(visit.aim));
        let cam = Config::default().camera;
        visits.finished(&map, &visit, true, robot, f64::INFINITY, &cam);
        assert!(visit.target.iter().all(|c| {
            let i = grid.index(*c);
            visits.needs_viewpoint(i) && !visits.was_approached(i)
        }));
        (map, visit, visits)
    }

    #[test]
    fn looks_give_up_a_frontier_cell_only_after_a_look_that_could_show_it() {
        let (map, visit) = open_visit();
        let grid = map.grid();
        let cam = Config::default().camera;
        // Stand on the aim, with a blind zone reaching half way along the segment: the cells within
        // it get no look, and are next looked at from a viewpoint.
        let robot = grid.center(grid.cell(visit.aim));
        let blind = 0.5
            * visit
                .target
                .iter()
                .map(|c| (grid.center(*c) - robot).norm())
                .fold(0.0, f64::max);
        let far = |c: &Cell| (grid.center(*c) - robot).norm() > blind;
        assert!(visit.target.iter().any(far) && !visit.target.iter().all(far));
        let mut visits = FrontierVisits::default();
        visits.ensure(grid);
        visits.finished(&map, &visit, true, robot, blind, &cam);
        for c in &visit.target {
            let i = grid.index(*c);
            assert_eq!(visits.was_approached(i), far(c), "{c:?}");
            assert_eq!(visits.needs_viewpoint(i), !far(c), "{c:?}");
            assert!(!visits.is_unobservable(i));
        }
        // The next look, from on top of a cell that had its look from afar, gives up nothing: the
        // approached cells now want a viewpoint too. (A look from on top counts for the cells in
        // the blind zone around the robot; here that zone spans the whole segment.)
        let aim = grid.index(*visit.target.iter().find(|c| far(c)).unwrap());
        let on_top = Visit {
            aim,
            ..visit.clone()
        };
        let top = grid.center(grid.cell(aim));
        let whole = visit
            .target
            .iter()
            .map(|c| (grid.center(*c) - top).norm())
            .fold(0.0, f64::max);
        visits.finished(&map, &on_top, true, top, whole, &cam);
        for c in &visit.target {
            let i = grid.index(*c);
            assert!(
                visits.needs_viewpoint(i) && !visits.is_unobservable(i),
                "{c:?}"
            );
        }
        // Looks from a viewpoint off the map see none of it: the first gives up nothing, the
        // second gives up the cells looked at from afar and from on top. The cells the first look
        // had in its blind zone count the first viewpoint look as their look from afar and wait
        // for their approach all the way (the aim always counts).
        let view = Visit {
            near_view: true,
            ..visit.clone()
        };
        let nowhere = Point2::new(-100.0, -100.0);
        visits.finished(&map, &view, true, nowhere, blind, &cam);
        assert!(visit
            .target
            .iter()
            .all(|c| !visits.is_unobservable(grid.index(*c))));
        visits.finished(&map, &view, true, nowhere, blind, &cam);
        for c in &visit.target {
            let i = grid.index(*c);
            assert_eq!(visits.is_unobservable(i), far(c) || i == visit.aim, "{c:?}");
        }
    }

    /// A look from on top of one frontier cell is a look from on top only for the cells in the
    /// blind zone around the robot. Counted for the whole segment, a look from on top of a cell
    /// gave up cells 3.3–3.6 m from the robot (THP, `plan_28182f788a` start 1).
    #[test]
    fn a_look_from_on_top_counts_only_for_the_cells_around_the_robot() {
        let (map, visit, mut visits) = looked_at_from_afar();
        let grid = map.grid();
        let cam = Config::default().camera;
        let p0 = grid.center(grid.cell(visit.aim));
        // Twice from on top of one end of the segment.
        let end = *visit
            .target
            .iter()
            .max_by(|a, b| {
                let d = |c: &Cell| (grid.center(*c) - p0).norm();
                d(a).total_cmp(&d(b)).then(a.cmp(b))
            })
            .unwrap();
        let top = grid.center(end);
        // A blind zone around the robot reaching half way along the segment.
        let blind = 0.5
            * visit
                .target
                .iter()
                .map(|c| (grid.center(*c) - top).norm())
                .fold(0.0, f64::max);
        let near = |c: &Cell| (grid.center(*c) - top).norm() <= blind;
        assert!(visit.target.iter().any(|c| !near(c)) && near(&end));
        let on_top = Visit {
            aim: grid.index(end),
            ..visit.clone()
        };
        visits.finished(&map, &on_top, true, top, blind, &cam);
        for c in &visit.target {
            let i = grid.index(*c);
            assert_eq!(visits.needs_viewpoint(i), near(c), "{c:?}");
            assert!(visits.was_approached(i) && !visits.is_unobservable(i));
        }
        visits.finished(&map, &on_top, true, top, blind, &cam);
        for c in &visit.target {
            assert_eq!(visits.is_unobservable(grid.index(*c)), near(c), "{c:?}");
        }
    }

    /// A look from a viewpoint chosen to see a cell that lay in the blind zone, which showed
    /// nothing, counts as its look from afar: the cell's next visit goes all the way onto it. Left
    /// unapproached, it stayed a blind-zone cell, the next step back looked from the same spot, and
    /// that second look gave it up, never approached (THP, `plan_28182f788a` start 1).
    #[test]
    fn a_look_from_a_viewpoint_that_shows_nothing_counts_as_the_look_from_afar() {
        // A first look with the whole segment in the blind zone: every cell wants a viewpoint.
        let (map, visit, mut visits) = looked_at_from_on_it();
        let grid = map.grid();
        let cam = Config::default().camera;
        // A look from a viewpoint that sees none of it.
        let view = Visit {
            near_view: true,
            ..visit.clone()
        };
        visits.finished(&map, &view, true, Point2::new(-100.0, -100.0), 1.0, &cam);
        for c in &visit.target {
            let i = grid.index(*c);
            assert!(visits.was_approached(i), "{c:?}");
            assert!(
                !visits.needs_viewpoint(i) && !visits.is_unobservable(i),
                "{c:?}"
            );
        }
    }

    #[test]
    fn a_second_approach_blocked_in_the_blind_zone_counts_as_the_look_from_on_top() {
        let (map, visit) = open_visit();
        let grid = map.grid();
        let cam = Config::default().camera;
        let aim_p = grid.center(grid.cell(visit.aim));
        let blind = 1.0;
        // The first look, from afar, marks the cells approached.
        let afar = Point2::new(aim_p.x - 5.0, aim_p.y);
        let approached = || {
            let mut visits = FrontierVisits::default();
            visits.ensure(grid);
            visits.finished(&map, &visit, true, afar, blind, &cam);
            assert!(visits.was_approached(visit.aim));
            visits
        };
        // Blocked 0.4 m short of the aim (inside the blind zone), twice: the cells want a
        // viewpoint after the first, and only the second gives them up, as two looks from on top.
        let mut visits = approached();
        let short = Point2::new(aim_p.x - 0.4, aim_p.y);
        visits.finished(&map, &visit, false, short, blind, &cam);
        assert!(visits.needs_viewpoint(visit.aim) && !visits.is_unobservable(visit.aim));
        visits.finished(&map, &visit, false, short, blind, &cam);
        assert!(visits.is_unobservable(visit.aim));
        // Blocked beyond the blind zone: failed attempts, the aim given up on the second.
        let mut visits = approached();
        let far = Point2::new(aim_p.x - 1.5, aim_p.y);
        visits.finished(&map, &visit, false, far, blind, &cam);
        assert!(!visits.needs_viewpoint(visit.aim) && !visits.is_unobservable(visit.aim));
        visits.finished(&map, &visit, false, far, blind, &cam);
        assert!(visits.is_unobservable(visit.aim));
    }

    /// Before `Complete`, a frontier cell given up after two failed attempts is reopened when the
    /// camera would surely see the unknown floor beside it from a reachable cell: it next wants a
    /// viewpoint, a second call before its look does not count again, and the look from the
    /// viewpoint gives it up. While the voxel stays unknown and in sight that repeats, each look
    /// from a viewpoint away from the earlier ones, at most `additions.reopen_max` times; then the cell
    /// stays given up. Where every cell was looked from, the viewpoint is the one chosen first.
    #[test]
    fn a_given_up_cell_the_camera_would_see_is_reopened_a_bounded_number_of_times() {
        let cfg = Config::default();
        let cam = cfg.camera.clone();
        let (grid, bvh) = furnished_room_setup(&cfg);
        let turn = |x: f64| (0..24).map(move |k| Pose2::new(x, 4.0, k as f64 * FRAC_PI_2 / 6.0));
        let map = seen_from(grid, &cfg, &bvh, turn(1.0).chain(turn(2.5)));
        let start = grid.index(grid.cell_of(Point2::new(1.0, 4.0)).unwrap());
        let df = crate::plan::search::Search::new(&grid).distance_field(
            &grid,
            |i| map.is_traversable(i).then_some(0.1),
            start,
            f32::INFINITY,
        );
        let segments: Vec<Vec<usize>> = map
            .frontiers()
            .iter()
            .map(|s| s.cells.iter().map(|c| grid.index(*c)).collect())
            .collect();
        let (near, far) = (cam.min_range_m.get(), cam.max_range_m.get());
        let seeable = |i: usize| {
            let ring = viewpoint_ring(&map, &df, i, near, far);
            first_sighted(
                &map,
                &ring,
                &lowest_unknown_beside(&map, i),
                &cam,
                Sight::Sure,
            )
            .is_some()
        };
        let (k, aim) = segments
            .iter()
            .enumerate()
            .flat_map(|(k, s)| s.iter().map(move |&i| (k, i)))
            .find(|&(_, i)| df.cost_to(i).is_some() && seeable(i))
            .expect("a reachable frontier cell the camera would see");
        let visit = Visit {
            target: segments[k].iter().map(|&i| grid.cell(i)).collect(),
            aim,
            near_view: false,
        };
        let mut visits = FrontierVisits::default();
        visits.ensure(&grid);
        let robot = grid.center(grid.cell(start));
        for _ in 0..2 {
            visits.finished(&map, &visit, false, robot, 1.0, &cam);
        }
        assert!(visits.is_unobservable(aim));
        let look = Visit {
            near_view: true,
            ..visit.clone()
        };
        let mut looked_from: Vec<Point2<f64>> = Vec::new();
        // The map does not change here, so the voxel stays unknown and in sight after every look.
        for _ in 0..Config::default().additions.reopen_max {
            assert!(visits
                .reopen_seeable(&map, &df, &segments, &cam, |_| false)
                .contains(&aim));
            assert!(!visits.is_unobservable(aim) && visits.needs_viewpoint(aim));
            assert!(!visits
                .reopen_seeable(&map, &df, &segments, &cam, |_| false)
                .contains(&aim));
            let viewpoint = visits
                .sighted_viewpoint(&map, &df, aim, 1.2, &cam)
                .expect("a viewpoint");
            let at = grid.center(grid.cell(viewpoint));
            let away_m = Config::default().additions.viewpoint_away_m.get();
            assert!(looked_from.iter().all(|p| (p - at).norm() > away_m));
            looked_from.push(at);
            visits.finished(&map, &look, true, at, 1.0, &cam);
            assert!(visits.is_unobservable(aim));
        }
        // (Cells of the segment first given up by a look may still be reopened; the aim is not.)
        visits.reopen_seeable(&map, &df, &segments, &cam, |_| false);
        assert!(visits.is_unobservable(aim));
        // With a look recorded from every cell, the viewpoint is the one chosen with none.
        let first = FrontierVisits::default().sighted_viewpoint(&map, &df, aim, 1.2, &cam);
        assert!(first.is_some());
        visits
            .looked_from
            .extend((0..grid.cells()).map(|k| (aim, k)));
        assert_eq!(visits.sighted_viewpoint(&map, &df, aim, 1.2, &cam), first);
    }

    /// A look at a cell from a viewpoint rules out the viewpoints within `additions.viewpoint_away_m` of it for
    /// that cell only.
    #[test]
    fn viewpoints_near_where_a_cell_was_looked_at_from_are_not_chosen_for_it_again() {
        let grid = GridSpec::covering(Point2::new(0.0, 0.0), Point2::new(3.0, 1.0), 1.8, 0.1);
        let at = |x: f64| grid.index(grid.cell_at(x, 0.55));
        let mut visits = FrontierVisits::default();
        visits.ensure(&grid);
        visits.looked_from.push((at(0.05), at(1.05)));
        let ring: Vec<(f32, usize)> = [0.65, 0.85, 1.05, 1.25, 1.45]
            .iter()
            .map(|&x| (x as f32, at(x)))
            .collect();
        let away = |cell: usize| away_from(&grid, &visits.looked_from_at(&grid, cell), &ring, 0.3);
        let kept: Vec<usize> = away(at(0.05)).iter().map(|r| r.1).collect();
        assert_eq!(kept, vec![at(0.65), at(1.45)]);
        assert_eq!(away(at(0.15)), ring);
    }

    #[test]
    fn looks_from_a_viewpoint_give_up_the_aimed_cell_even_if_it_waits_for_its_approach() {
        // A look from afar: every cell is approached and waits for its look from on top.
        let (map, visit, mut visits) = looked_at_from_afar();
        let grid = map.grid();
        let cam = Config::default().camera;
        // Then two looks from a viewpoint that sees none of it (a distant view of a cell the robot
        // cannot reach): the aim is given up on the second, the other cells still wait.
        let view = Visit {
            near_view: true,
            ..visit.clone()
        };
        let nowhere = Point2::new(-100.0, -100.0);
        visits.finished(&map, &view, true, nowhere, 1.0, &cam);
        assert!(!visits.is_unobservable(visit.aim));
        visits.finished(&map, &view, true, nowhere, 1.0, &cam);
        assert!(visits.is_unobservable(visit.aim));
        assert!(visit
            .target
            .iter()
            .filter(|c| grid.index(**c) != visit.aim)
            .all(|c| !visits.is_unobservable(grid.index(*c))));
    }

    /// The voxel of layer `iz` above the centre of the cell holding `(x, y)`.
    fn voxel_at(grid: &GridSpec, x: f64, y: f64, iz: usize) -> usize {
        grid.voxel_index(grid.cell_at(x, y), iz)
    }

    #[test]
    fn the_sight_test_sees_past_a_thin_post_in_an_occupied_voxel_as_the_camera_does() {
        let cfg = Config::default();
        let (grid, _) = furnished_room_setup(&cfg);
        let mut mesh = crate::sensor::raycast::testing::furnished_room(8.0);
        // A 2 cm post in the south part of the cell [3.0, 3.1] × [4.0, 4.1].
        crate::sensor::raycast::testing::push_box(
            &mut mesh,
            [3.04, 4.005, 0.0],
            [3.06, 4.025, 1.8],
        );
        let bvh = crate::sensor::MeshBvh::new(&mesh).unwrap();
        // Seen from the south: the post's column is occupied, the space east of it unknown.
        let mut map = seen_from(grid, &cfg, &bvh, [Pose2::new(3.05, 2.6, FRAC_PI_2)]);
        let layer = 6; // 0.6–0.7 m, the camera's height
        let post = voxel_at(&grid, 3.05, 4.05, layer);
        let target = voxel_at(&grid, 5.05, 4.05, layer);
        assert_eq!(map.voxel_state(post), VoxelState::Occupied);
        assert_eq!(map.voxel_state(target), VoxelState::Unknown);
        // From the west, the line between cell centres runs through the post's voxel but 1.5 cm
        // north of the post's box.
        let from = grid.index(grid.cell_at(1.05, 4.05));
        let mut crosses_post = false;
        let origin = Point3::new(1.05, 4.05, cfg.camera.mount_height_m.get());
        let to = Vector3::new(4.0, 0.0, grid.layer_center(layer) - origin.z);
        traverse_while(&grid, origin, to.normalize(), to.norm(), |v, _, _| {
            crosses_post |= v == post;
            true
        });
        assert!(crosses_post);
        assert!(camera_sees(
            &map,
            from,
            target,
            &cfg.camera,
            Sight::Possible
        ));
        assert!(!camera_sees(&map, from, target, &cfg.camera, Sight::Sure));
        // And the camera there does see it.
        let cam = crate::sensor::DepthCamera::new(&cfg.camera);
        map.integrate(&cam.capture(&bvh, Pose2::new(1.05, 4.05, 0.0)));
        assert_ne!(map.voxel_state(target), VoxelState::Unknown);
    }

    #[test]
    fn the_sight_test_does_not_see_through_a_seen_pillar() {
        let cfg = Config::default();
        let (grid, bvh) = furnished_room_setup(&cfg);
        // The pillar [4.0, 4.3] × [3.0, 3.3] seen from the west, nothing behind it.
        let map = seen_from(grid, &cfg, &bvh, [Pose2::new(2.55, 3.15, 0.0)]);
        let target = voxel_at(&grid, 5.05, 3.15, 6);
        assert_eq!(map.voxel_state(target), VoxelState::Unknown);
        let from = grid.index(grid.cell_at(2.55, 3.15));
        for sight in [Sight::Possible, Sight::Sure] {
            assert!(!camera_sees(&map, from, target, &cfg.camera, sight));
        }
        // Beside the pillar, in plain view, it sees.
        let beside = voxel_at(&grid, 3.35, 4.05, 3);
        for sight in [Sight::Possible, Sight::Sure] {
            assert!(camera_sees(&map, from, beside, &cfg.camera, sight));
        }
    }

    #[test]
    fn a_cell_no_viewpoint_sees_gets_the_two_approaches_instead() {
        // A blind zone that holds the whole segment: every cell wants a viewpoint.
        let (map, visit, mut visits) = looked_at_from_on_it();
        let grid = map.grid();
        visits.no_viewpoint(grid, &visit);
        for c in &visit.target {
            let i = grid.index(*c);
            assert!(
                !visits.needs_viewpoint(i) && visits.was_approached(i),
                "{c:?}"
            );
        }
    }
}
