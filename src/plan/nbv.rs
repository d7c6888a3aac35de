//! NBV-TSP (Meng et al., "A two-stage optimized next-view planning framework for 3-D unknown
//! environment exploration, and structural reconstruction", RA-L 2017, Alg. 1): frontier-based coverage sampling of candidate viewpoints (Alg. 2–3)
//! scored by a volumetric heuristic gain (Eq. 4–6), pruned as the map changes (Alg. 4), ordered by a
//! genetic algorithm over a fixed-start open TSP with the cost of Eq. 7 (Alg. 5); the robot drives
//! the first edge, then everything is repeated.
//!
//! Choices where the paper leaves room or does not fit a ground robot with a forward camera:
//! - Samples are 2D floor cells (the robot cannot fly): "Free" = traversable and reachable from the
//!   robot, "Unknown" = an unknown column; visibility between the pair = no obstacle cell on the
//!   straight line. The sampler stops after `misses_per_m2` × (unknown floor area) consecutive
//!   misses (at least `min_misses`), the paper's period proportional to the unmapped volume, or
//!   once `max_viewpoints` candidates exist.
//! - Gain (Eq. 4–6) is cast on a coarse ray fan: every `gain_ray_stride`-th camera ray, at uniform
//!   angles over the full circle; the best yaw is the best window of one field of view. Eq. 4 is
//!   counted on unknown voxels in the height band only (known voxels carry no information worth a
//!   trip; counting them would keep every viewpoint above the cutoff), weighted by each ray's
//!   solid angle and length, so the gain is an expected unknown volume in m³ independent of the ray
//!   count. Eq. 5's unoccupancy product is taken per `visibility_length_m` of free or unknown ray
//!   (the paper's 0.25–0.4 m voxels; per 0.1 m voxel free space would hide anything 2 m away) and
//!   per voxel for occupied voxels (surfaces block whatever their thickness).
//! - MarkCovered marks the floor cells the best-yaw rays reach with visibility of at least
//!   `cover_min_visibility`. Marks are rebuilt each planning step from the surviving viewpoints, so
//!   a pruned viewpoint's area can be sampled again.
//! - Viewpoints with gain below `gain_cutoff_m3` are not kept at all (Alg. 4 would prune them
//!   at the next step anyway). The paper gives no value for Alg. 4's CutoffThreshold; 0.05 m³ is
//!   the largest tried that brings the mean completeness on 33 real plans × 3 random starts to
//!   0.95 (0.1 m³ gave 0.947).
//! - Eq. 7 uses the path cost of the shared search (`costs_to_targets`, metres with the proximity
//!   surcharge) instead of the Euclidean distance, as all planners here do.
//! - The motion executor cannot end at a given heading, so the robot turns once in place on
//!   arrival (it sees at least what the best yaw predicted). While driving, the target's gain is
//!   re-checked once a second and the plan is redone as soon as it falls below the cutoff (the
//!   camera often sees a viewpoint's unknown on the way there); a viewpoint whose gain stays above
//!   the cutoff after a visit is given up, as is one the robot failed to reach twice.
//! - Before answering `Complete`, every frontier segment is tried as a viewpoint, so that a random
//!   sampler's miss cannot end the run early. The robot aims at the segment's least-cost cell not
//!   given up and looks at it from a cell from which the camera sees the floor beside it
//!   ([`super::frontier::FrontierVisits::sighted_viewpoint`]), else from the cell itself:
//!   from on top, the camera's blind zone hides that floor, and the frontier was left for good. A
//!   cell is given up by GREEDY's and THP's rules ([`super::frontier::FrontierVisits`]):
//!   after a look from where the camera could see it, a second look, or two failed approaches;
//!   the next viewpoint for it is chosen away from those looked from. (With every cell
//!   within the sampling radius of a reached anchor given up instead, 29 of 99 runs on real plans
//!   ended `complete` with frontiers left; 15 with these rules.) Then each frontier seen through a gap too narrow to pass is looked at
//!   once from a reachable cell in line of sight ([`super::frontier::distant_view`], shared
//!   with GREEDY and THP).

use super::frontier::{
    distant_view, end_of_run, follow_to, line_of_sight, Ending, FrontierVisits, Visit,
};
use super::tsp::{self, CostMatrix, GaParams};
use super::view_gain::GainModel;
use super::{Action, Count, Plan, PlanContext, Planner};
use crate::config::{Additions, CameraConfig, Config, NbvConfig};
use crate::map::Map;
use crate::Result;
use nalgebra::Point2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;
use std::f64::consts::TAU;
use std::time::Instant;

/// Steps between re-evaluations of the target's gain while driving (1 s at the default `dt`).
const RECHECK_STEPS: u32 = 10;

/// What NBV-TSP reads of the config: its own section, the camera whose views it predicts, the height
/// band of the explored volume, the distance GREEDY stops short of a frontier (shared for the look
/// through a gap before `Complete`), and the run's seed (its random stream).
#[derive(Clone, Debug, PartialEq)]
pub struct NbvParams {
    pub nbv: NbvConfig,
    pub camera: CameraConfig,
    /// `map.band_min_m`, `map.band_max_m`.
    pub band_m: (f64, f64),
    /// `greedy.view_distance_m`.
    pub view_distance_m: f64,
    pub seed: u64,
    /// The rules no paper has (`[additions]`): NBV-TSP's frontier views, distant views and
    /// reopening before `Complete`, and the failed approaches before a viewpoint is given up.
    pub additions: Additions,
}

impl From<&Config> for NbvParams {
    fn from(cfg: &Config) -> NbvParams {
        NbvParams {
            nbv: cfg.nbv.clone(),
            camera: cfg.camera.clone(),
            band_m: (cfg.map.band_min_m, cfg.map.band_max_m),
            view_distance_m: cfg.greedy.view_distance_m.get(),
            seed: cfg.seed,
            additions: cfg.additions.clone(),
        }
    }
}

impl From<&NbvConfig> for GaParams {
    fn from(c: &NbvConfig) -> Self {
        GaParams {
            population: c.ga_population,
            group_size: c.ga_group_size,
            generations: c.ga_generations,
            stall_generations: c.ga_stall_generations,
        }
    }
}

/// A candidate viewpoint.
struct Viewpoint {
    cell: usize,
    pos: Point2<f64>,
    gain: f64,
    yaw: f64,
    /// Floor cells in its predicted observation (MarkCovered).
    covered: Vec<u32>,
    /// For a viewpoint tried before answering `Complete` (see the module doc), the frontier it looks
    /// at: kept whatever its gain until reached or no frontier is left near the aimed cell.
    fallback: Option<Visit>,
}

/// The NBV-TSP planner.
pub struct Nbv {
    /// The rules no paper has (`[additions]`).
    rules: Additions,
    model: GainModel,
    cfg: NbvConfig,
    /// GREEDY's `view_distance_m`, for the look through a gap.
    view_m: f64,
    rng: ChaCha8Rng,
    viewpoints: Vec<Viewpoint>,
    /// The viewpoint being approached (index into `viewpoints`) and its cells on the way.
    target: Option<usize>,
    path_cells: Vec<usize>,
    /// Cells given up as viewpoints (unreachable, or the gain did not drop after a visit).
    given_up: Vec<bool>,
    /// Frontier cells looked at through a gap (or that the robot failed to reach twice for that look):
    /// not looked at that way again.
    distant_done: Vec<bool>,
    /// The looks at frontiers before `Complete`, with GREEDY's and THP's rules for when a frontier is
    /// given up (a look from where the camera could see it, or a second look).
    visits: FrontierVisits,
    attempts: BTreeMap<usize, u32>,
    /// A look through a gap in progress: the aimed frontier cell and its segment's cells.
    distant: Option<(usize, Vec<usize>)>,
    /// Set when the target was abandoned because its gain dropped (not a failure).
    target_seen: bool,
    steps_since_check: u32,
    /// The bounding box of robot positions since the last gain re-evaluation.
    moved: Option<(Point2<f64>, Point2<f64>)>,
    tour: Vec<Point2<f64>>,
    tsp_ms: Option<f64>,
    stats: NbvStats,
}

/// NBV-TSP's run statistics (`planner_stats`, under the field names).
#[derive(Clone, Debug, Default)]
struct NbvStats {
    anchor_tries: Count,
    distant_views: Count,
    anchors_visited: Count,
    gain_evaluations: Count,
    tsp_nodes: Count,
    tsp_solves: Count,
    viewpoints_dropped: Count,
    viewpoints_given_up: Count,
    viewpoints_pruned: Count,
    viewpoints_sampled: Count,
    viewpoints_visited: Count,
}

impl Nbv {
    pub fn new(cfg: &NbvParams) -> Self {
        Nbv {
            model: GainModel::new(&cfg.camera, cfg.band_m, &cfg.nbv),
            cfg: cfg.nbv.clone(),
            rules: cfg.additions.clone(),
            view_m: cfg.view_distance_m,
            // The planner's own stream, derived from the run's seed.
            rng: ChaCha8Rng::seed_from_u64(cfg.seed ^ 0x6e62_7674_7370),
            viewpoints: Vec::new(),
            target: None,
            path_cells: Vec::new(),
            given_up: Vec::new(),
            distant_done: Vec::new(),
            visits: FrontierVisits::new((&cfg.additions).into()),
            attempts: BTreeMap::new(),
            distant: None,
            target_seen: false,
            steps_since_check: 0,
            moved: None,
            tour: Vec::new(),
            tsp_ms: None,
            stats: NbvStats::default(),
        }
    }

    fn note_position(&mut self, p: Point2<f64>) {
        self.moved = Some(match self.moved {
            None => (p, p),
            Some((lo, hi)) => (
                Point2::new(lo.x.min(p.x), lo.y.min(p.y)),
                Point2::new(hi.x.max(p.x), hi.y.max(p.y)),
            ),
        });
    }

    /// Alg. 4: re-evaluates the gain of viewpoints the camera may have changed since the last call
    /// (within two sensor ranges of where the robot went) and drops those below the cutoff, no
    /// longer traversable, or unreachable (`reachable`).
    fn prune(&mut self, map: &Map, reachable: impl Fn(usize) -> bool) {
        let reach = 2.0 * self.model.max_range_m;
        let moved = self.moved.take();
        let mut kept = Vec::with_capacity(self.viewpoints.len());
        for mut vp in std::mem::take(&mut self.viewpoints) {
            let near = moved.is_some_and(|(lo, hi)| {
                let dx = (lo.x - vp.pos.x).max(vp.pos.x - hi.x).max(0.0);
                let dy = (lo.y - vp.pos.y).max(vp.pos.y - hi.y).max(0.0);
                dx * dx + dy * dy <= reach * reach
            });
            if vp.fallback.is_some()
                || !map.is_traversable(vp.cell)
                || !reachable(vp.cell)
                || self.given_up[vp.cell]
            {
                self.stats.viewpoints_dropped.add(1.0);
                continue;
            }
            if near {
                let g = self.model.evaluate(map, vp.pos);
                self.stats.gain_evaluations.add(1.0);
                if g.volume_m3 < self.cfg.gain_cutoff_m3 {
                    self.stats.viewpoints_pruned.add(1.0);
                    continue;
                }
                vp.gain = g.volume_m3;
                vp.yaw = g.yaw;
                vp.covered = self.model.covered(map, vp.pos, vp.yaw);
            }
            kept.push(vp);
        }
        self.viewpoints = kept;
    }

    /// Tries `cell` as a new viewpoint (CalculateGain + MarkCovered); whether it was kept.
    fn try_add(&mut self, map: &Map, cell: usize, covered: &mut [bool]) -> bool {
        let grid = map.grid();
        let pos = grid.center(grid.cell(cell));
        let g = self.model.evaluate(map, pos);
        self.stats.gain_evaluations.add(1.0);
        if g.volume_m3 < self.cfg.gain_cutoff_m3 {
            return false;
        }
        let cov = self.model.covered(map, pos, g.yaw);
        for &c in &cov {
            covered[c as usize] = true;
        }
        // The viewpoint's own cell counts as covered even in the camera's blind zone.
        covered[cell] = true;
        self.viewpoints.push(Viewpoint {
            cell,
            pos,
            gain: g.volume_m3,
            yaw: g.yaw,
            covered: cov,
            fallback: None,
        });
        self.stats.viewpoints_sampled.add(1.0);
        true
    }
}

/// Whether a frontier cell lies within `r` of `p`.
fn frontier_near(map: &Map, p: Point2<f64>, r: f64) -> bool {
    let grid = map.grid();
    let c = grid.cell_at(p.x, p.y);
    let n = (r / grid.res).ceil() as i32;
    (-n..=n).any(|dy| {
        (-n..=n).any(|dx| {
            grid.checked_index(crate::Cell::new(c.x + dx, c.y + dy))
                .is_some_and(|i| map.is_frontier(i))
        })
    })
}

impl Nbv {
    /// The next action (see [`Planner::plan`]).
    fn next_action(&mut self, ctx: &mut PlanContext) -> Result<Action> {
        let grid = *ctx.map.grid();
        let map = ctx.map;
        if self.given_up.len() != grid.cells() {
            self.given_up = vec![false; grid.cells()];
            self.distant_done = vec![false; grid.cells()];
        }
        self.visits.ensure(&grid);
        self.tsp_ms = None;
        self.target = None;
        self.distant = None;
        self.path_cells.clear();
        let robot = ctx.pose.position();
        self.note_position(robot);
        let Some(start) = grid.cell_of(robot).map(|c| grid.index(c)) else {
            return Ok(Action::Complete);
        };
        let search_cfg = &ctx.cfg.search;
        let cost_fn = |i: usize| super::step_cost(map, search_cfg, robot, i);
        let df = ctx
            .search
            .distance_field(&grid, cost_fn, start, f32::INFINITY);
        self.prune(map, |i| df.cost_to(i).is_some());

        // Coverage marks of the surviving viewpoints.
        let mut covered = vec![false; grid.cells()];
        for vp in &self.viewpoints {
            covered[vp.cell] = true;
            for &c in &vp.covered {
                covered[c as usize] = true;
            }
        }
        let free_ok = |i: usize, covered: &[bool], given_up: &[bool]| {
            map.is_traversable(i) && !covered[i] && !given_up[i] && df.cost_to(i).is_some()
        };
        // Alg. 2–3: random neighbouring pairs, one Free (reachable) and one Unknown, in sight.
        let unknown_m2 =
            (0..grid.cells()).filter(|&i| map.is_unknown(i)).count() as f64 * grid.cell_area();
        let max_misses = ((self.cfg.misses_per_m2 * unknown_m2) as usize).max(self.cfg.min_misses);
        let (lo, hi) = grid.bounds();
        let r = self.cfg.sample_radius_m;
        let mut misses = 0;
        while misses < max_misses && self.viewpoints.len() < self.cfg.max_viewpoints {
            misses += 1;
            let p1 = Point2::new(
                self.rng.random_range(lo.x..hi.x),
                self.rng.random_range(lo.y..hi.y),
            );
            let (ang, rad) = (
                self.rng.random_range(0.0..TAU),
                r * self.rng.random::<f64>().sqrt(),
            );
            let p2 = p1 + nalgebra::Vector2::new(rad * ang.cos(), rad * ang.sin());
            let (Some(c1), Some(c2)) = (grid.cell_of(p1), grid.cell_of(p2)) else {
                continue;
            };
            let (i1, i2) = (grid.index(c1), grid.index(c2));
            let free = if map.is_unknown(i2) && free_ok(i1, &covered, &self.given_up) {
                i1
            } else if map.is_unknown(i1) && free_ok(i2, &covered, &self.given_up) {
                i2
            } else {
                continue;
            };
            if !line_of_sight(map, &grid, i1, i2) {
                continue;
            }
            if self.try_add(map, free, &mut covered) {
                misses = 0;
            } else {
                // Low gain: do not evaluate this cell again in this planning step.
                covered[free] = true;
            }
        }
        // Before giving up, every reachable frontier segment with a cell not given up is tried, at
        // any gain: unknown floor in the camera's blind zone can close a narrow passage (it is
        // passable only near the robot), and no viewpoint short of it predicts any gain. The robot
        // looks at that cell from where the camera sees the floor beside it, if anywhere does
        // (shared with GREEDY and THP), else from the cell itself.
        if self.viewpoints.is_empty() && self.rules.nbv_frontier_views {
            for seg in map.frontiers() {
                if self.viewpoints.len() >= self.cfg.max_viewpoints {
                    break;
                }
                // The least-cost cell of the segment not given up, as THP aims.
                let open = seg
                    .cells
                    .iter()
                    .map(|c| grid.index(*c))
                    .filter(|&i| !self.given_up[i]);
                let Some((_, aim)) = self.visits.cheapest_open(open, &df) else {
                    continue;
                };
                let cell = (self.visits)
                    .sighted_viewpoint(map, &df, aim, self.view_m, &ctx.cfg.camera)
                    .unwrap_or(aim);
                let pos = grid.center(grid.cell(cell));
                let g = self.model.evaluate(map, pos);
                self.stats.gain_evaluations.add(1.0);
                self.stats.anchor_tries.add(1.0);
                self.viewpoints.push(Viewpoint {
                    cell,
                    pos,
                    // Eq. 7 needs a positive gain: count it at the cutoff at least.
                    gain: g.volume_m3.max(self.cfg.gain_cutoff_m3).max(1e-6),
                    yaw: g.yaw,
                    covered: Vec::new(),
                    fallback: Some(Visit {
                        target: seg.cells.clone(),
                        aim,
                        near_view: true,
                    }),
                });
            }
        }
        if self.viewpoints.is_empty() {
            self.tour.clear();
            // Nothing reachable is left: look once at each frontier seen through a gap too narrow to
            // pass, from a reachable cell in line of sight, before calling the map done (shared with
            // GREEDY and THP).
            let segments: Vec<Vec<usize>> = map
                .frontiers()
                .iter()
                .map(|s| s.cells.iter().map(|c| grid.index(*c)).collect())
                .collect();
            let (rules, view_m, params) = (self.rules.clone(), self.view_m, ctx.cfg);
            let camera = &params.camera;
            let ending = end_of_run(
                &rules,
                self,
                |nbv| {
                    let done = |i: usize| nbv.distant_done[i] || nbv.given_up[i];
                    distant_view(map, &df, &segments, done, view_m)
                },
                // NBV-TSP's own viewpoints already cover the volume: it takes no volume views.
                |_| None::<()>,
                |nbv| {
                    // A frontier cell given up as a viewpoint counts as given up too; reopened, it
                    // is open to the looks above again.
                    let given_up = &nbv.given_up;
                    let reopened =
                        (nbv.visits).reopen_seeable(map, &df, &segments, camera, |i| given_up[i]);
                    for &i in &reopened {
                        nbv.given_up[i] = false;
                    }
                    !reopened.is_empty()
                },
            );
            let view = match ending {
                Ending::DistantView(view) => view,
                Ending::VolumeView(()) | Ending::Reopened => return Ok(Action::LookAround),
                Ending::Complete => return Ok(Action::Complete),
            };
            self.stats.distant_views.add(1.0);
            self.distant = Some((view.aim, segments[view.segment].clone()));
            let action;
            (action, self.path_cells) = follow_to(&grid, &df, view.viewpoint, true, true);
            return Ok(action);
        }

        // Alg. 5: Eq. 7 costs over path costs, the robot as the fixed start (node 0).
        let robot_gain = self.model.evaluate(map, robot).volume_m3;
        self.stats.gain_evaluations.add(1.0);
        let nodes: Vec<usize> = std::iter::once(start)
            .chain(self.viewpoints.iter().map(|v| v.cell))
            .collect();
        let gains: Vec<f64> = std::iter::once(robot_gain)
            .chain(self.viewpoints.iter().map(|v| v.gain))
            .collect();
        let n = nodes.len();
        let mut dist = vec![vec![None; n]; n];
        dist[0] = nodes.iter().map(|&t| df.cost_to(t)).collect();
        for i in 1..n {
            dist[i] = ctx
                .search
                .costs_to_targets(&grid, cost_fn, nodes[i], &nodes, f32::INFINITY);
        }
        let eta = self.cfg.eta;
        let m = CostMatrix::from_fn(n, |i, j| {
            if i == j {
                return 0.0;
            }
            match dist[i][j] {
                Some(d) => {
                    let d = d as f64;
                    d / (gains[i] + gains[j] * (-eta * d).exp()).max(1e-12)
                }
                None => f64::INFINITY,
            }
        });
        let t0 = Instant::now();
        let tour = tsp::genetic(&m, 0, &GaParams::from(&self.cfg), &mut self.rng);
        self.tsp_ms = Some(t0.elapsed().as_secs_f64() * 1e3);
        self.stats.tsp_solves.add(1.0);
        self.stats.tsp_nodes.add(n as f64);
        self.tour = tour.order[1..]
            .iter()
            .map(|&k| self.viewpoints[k - 1].pos)
            .collect();

        // Drive the first edge.
        let k = tour.order[1] - 1;
        let goal = self.viewpoints[k].cell;
        self.target = Some(k);
        self.target_seen = false;
        self.steps_since_check = 0;
        let path = ctx.search.astar(&grid, cost_fn, start, goal);
        let Some(path) = path else {
            // The distance field reached it, so this cannot happen; treat it as a failed approach.
            self.given_up[goal] = true;
            return Ok(Action::LookAround);
        };
        if path.cells.len() < 2 {
            return Ok(Action::LookAround);
        }
        self.path_cells = path.cells.iter().skip(1).map(|c| grid.index(*c)).collect();
        Ok(Action::Follow {
            path: path.cells.iter().map(|c| grid.center(*c)).collect(),
            look_on_arrival: true,
            // A look at a frontier cell aims at one voxel (see `sighted_viewpoint`).
            exact_arrival: self.viewpoints[k].fallback.is_some(),
        })
    }
}

impl Planner for Nbv {
    fn name(&self) -> &'static str {
        "nbv"
    }

    fn plan(&mut self, ctx: &mut PlanContext) -> Result<Plan> {
        let action = self.next_action(ctx)?;
        Ok(Plan::new(action, self.tour.clone(), self.tsp_ms.take()))
    }

    fn is_outdated(&mut self, ctx: &PlanContext, action: &Action) -> bool {
        self.note_position(ctx.pose.position());
        if !matches!(action, Action::Follow { .. }) {
            return false;
        }
        if self.path_cells.iter().any(|&i| !ctx.passable(i)) {
            return true;
        }
        self.steps_since_check += 1;
        if self.steps_since_check >= RECHECK_STEPS {
            self.steps_since_check = 0;
            if let Some(vp) = self.target.and_then(|k| self.viewpoints.get(k)) {
                if let Some(visit) = &vp.fallback {
                    // Outdated once no frontier is left within the sampling radius of its aim.
                    let grid = ctx.map.grid();
                    let at = grid.center(grid.cell(visit.aim));
                    let seen = !frontier_near(ctx.map, at, self.cfg.sample_radius_m);
                    self.target_seen = seen;
                    return seen;
                }
                let g = self.model.evaluate(ctx.map, vp.pos);
                self.stats.gain_evaluations.add(1.0);
                if g.volume_m3 < self.cfg.gain_cutoff_m3 {
                    self.target_seen = true;
                    return true;
                }
            }
        }
        false
    }

    fn action_finished(&mut self, ctx: &PlanContext, reached: bool) {
        self.note_position(ctx.pose.position());
        if let Some((aim, cells)) = self.distant.take() {
            // A look through a gap: done once looked, or after failing to get there twice.
            let a = self.attempts.entry(aim).or_insert(0);
            *a += u32::from(!reached);
            if reached || *a >= self.rules.approach_attempts {
                for i in cells {
                    self.distant_done[i] = true;
                }
            }
            return;
        }
        let Some(k) = self.target.take() else {
            return;
        };
        if k >= self.viewpoints.len() {
            return;
        }
        let cell = self.viewpoints[k].cell;
        if let Some(visit) = self.viewpoints[k].fallback.clone() {
            // Given up: the cells this look could see, any cell on its second look, and the cells
            // near an aim the robot failed to reach twice (shared with GREEDY and THP). Marking
            // everything within the sampling radius of a reached anchor done ended runs `complete`
            // with frontiers whose floor the look had not shown.
            if reached {
                self.stats.anchors_visited.add(1.0);
            }
            if reached || !self.target_seen {
                self.visits.finished_in(ctx, &visit, reached);
            }
            self.viewpoints.remove(k);
        } else if reached {
            self.stats.viewpoints_visited.add(1.0);
            // Visited: if the looked-around view did not bring the gain below the cutoff, the
            // prediction cannot be met from here; give the cell up so it is not sampled again.
            let g = self.model.evaluate(ctx.map, self.viewpoints[k].pos);
            self.stats.gain_evaluations.add(1.0);
            if g.volume_m3 >= self.cfg.gain_cutoff_m3 {
                self.given_up[cell] = true;
                self.stats.viewpoints_given_up.add(1.0);
            }
            self.viewpoints.remove(k);
        } else if self.target_seen {
            self.viewpoints.remove(k);
            self.stats.viewpoints_pruned.add(1.0);
        } else {
            let a = self.attempts.entry(cell).or_insert(0);
            *a += 1;
            if *a >= self.rules.approach_attempts {
                self.given_up[cell] = true;
                self.viewpoints.remove(k);
                self.stats.viewpoints_given_up.add(1.0);
            }
        }
        self.target_seen = false;
    }

    fn stats(&self) -> BTreeMap<String, f64> {
        let s = &self.stats;
        super::counted(
            [
                ("anchor_tries", s.anchor_tries),
                ("distant_views", s.distant_views),
                ("anchors_visited", s.anchors_visited),
                ("gain_evaluations", s.gain_evaluations),
                ("tsp_nodes", s.tsp_nodes),
                ("tsp_solves", s.tsp_solves),
                ("viewpoints_dropped", s.viewpoints_dropped),
                ("viewpoints_given_up", s.viewpoints_given_up),
                ("viewpoints_pruned", s.viewpoints_pruned),
                ("viewpoints_sampled", s.viewpoints_sampled),
                ("viewpoints_visited", s.viewpoints_visited),
            ]
            .into_iter()
            .chain(self.visits.stats()),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::GridSpec;
    use crate::map::testing::seen_from;
    use crate::scene::TriMesh;
    use crate::sensor::raycast::testing::push_box;
    use crate::sensor::raycast::MeshBvh;
    use crate::Pose2;

    #[test]
    fn line_of_sight_is_blocked_by_obstacle_cells() {
        let cfg = Config::default();
        let grid = GridSpec::covering(Point2::new(0.0, -2.0), Point2::new(6.0, 2.0), 1.8, 0.1);
        let mut mesh = TriMesh::default();
        push_box(&mut mesh, [-1.0, -3.0, -0.1], [7.0, 3.0, 0.0]);
        push_box(&mut mesh, [3.0, -3.0, 0.0], [3.1, 0.0, 2.0]);
        let bvh = MeshBvh::new(&mesh).unwrap();
        let map = seen_from(grid, &cfg, &bvh, [Pose2::new(0.5, 0.0, 0.0); 3]);
        let idx = |x: f64, y: f64| grid.index(grid.cell_at(x, y));
        assert!(map.is_obstacle(idx(3.05, -0.5)));
        assert!(!line_of_sight(&map, &grid, idx(2.5, -0.5), idx(3.5, -0.5)));
        assert!(line_of_sight(&map, &grid, idx(2.5, 0.5), idx(3.5, 0.5)));
        assert!(line_of_sight(&map, &grid, idx(2.5, 0.5), idx(2.5, 0.5)));
    }

    #[test]
    fn config_errors_name_the_key() {
        let bad = [
            ("nbv.ga_group_size=200", "nbv.ga_group_size"),
            ("nbv.ga_population=0", "nbv.ga_population"),
            ("nbv.sample_radius_m=0", "nbv.sample_radius_m"),
            ("nbv.cover_min_visibility=1.5", "nbv.cover_min_visibility"),
            ("nbv.gain_cutoff_m3=-1", "nbv.gain_cutoff_m3"),
            ("nbv.eta=-0.1", "nbv.eta"),
        ];
        for (set, key) in bad {
            let e = Config::load(None, &[set.to_string()]).unwrap_err();
            assert!(e.to_string().contains(key), "{set}: {e}");
            assert!(matches!(e, crate::Error::Usage(_)), "{set}: {e:?}");
        }
        let p = GaParams::from(&Config::default().nbv);
        assert_eq!((p.population, p.group_size), (100, 4));
    }
}
