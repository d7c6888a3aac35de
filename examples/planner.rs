//! A minimal planner, to show what adding one takes: implement the four methods of
//! [`tensorscout::plan::Planner`] and hand the planner to a [`Simulation`]. Nothing here depends on
//! another planner's internals; the map, the shared cost rule and the search workspace come in the
//! [`PlanContext`].
//!
//! `NearestCell` drives to the nearest frontier cell it has not tried yet (by path cost under the
//! shared cost rule) and looks around there. It is a teaching example, simpler than GREEDY: it
//! neither groups frontier cells into segments nor stops short of them.
//!
//! ```text
//! cargo run --release --example planner -- scenes/apartment_small.obj
//! ```

use std::collections::BTreeSet;
use tensorscout::plan::{search_source, step_cost, Action, Plan, PlanContext, Planner};
use tensorscout::sim::{NoObserver, RunOutput, Simulation, World};
use tensorscout::{scene, Config, Result};

/// Drives to the nearest untried frontier cell; complete when none is reachable.
#[derive(Default)]
pub struct NearestCell {
    /// The frontier cell being driven to.
    target: Option<usize>,
    /// Cells already driven to (reached or not): never chosen again, so an unobservable frontier
    /// cannot hold the robot.
    tried: BTreeSet<usize>,
}

impl Planner for NearestCell {
    fn name(&self) -> &'static str {
        "nearest-cell"
    }

    fn plan(&mut self, ctx: &mut PlanContext) -> Result<Plan> {
        let grid = *ctx.map.grid();
        let (map, search_cfg, robot) = (ctx.map, &ctx.cfg.search, ctx.pose.position());
        let Some(start) = search_source(map, search_cfg, robot, ctx.cfg.robot.radius_m) else {
            // Nowhere to go from here: a look around may show a way out.
            return Ok(Action::LookAround.into());
        };
        // One Dijkstra field from the robot under the cost rule every planner shares.
        let df = ctx.search.distance_field(
            &grid,
            |i| step_cost(map, search_cfg, robot, i),
            start,
            f32::INFINITY,
        );
        // The nearest untried frontier cell beyond the camera's blind zone around the robot (cells
        // there are seen once it moves on); ties go to the lower index (deterministic).
        let blind_m = search_cfg.near_unknown_radius_m;
        let best = (0..grid.cells())
            .filter(|&i| map.is_frontier(i) && !self.tried.contains(&i))
            .filter(|&i| (grid.center(grid.cell(i)) - robot).norm() > blind_m)
            .filter_map(|i| df.cost_to(i).map(|c| (c, i)))
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let Some((_, cell)) = best else {
            return Ok(Action::Complete.into());
        };
        let path = df
            .path_to(&grid, cell)
            .expect("a reachable cell has a path");
        self.target = Some(cell);
        Ok(Action::Follow {
            path: path.cells.iter().map(|c| grid.center(*c)).collect(),
            look_on_arrival: true,
            exact_arrival: false,
        }
        .into())
    }

    fn is_outdated(&mut self, ctx: &PlanContext, action: &Action) -> bool {
        // Re-plan once the target has been seen on the way.
        matches!(action, Action::Follow { .. })
            && self.target.is_some_and(|i| !ctx.map.is_frontier(i))
    }

    fn action_finished(&mut self, _ctx: &PlanContext, _reached: bool) {
        if let Some(cell) = self.target.take() {
            self.tried.insert(cell);
        }
    }
}

/// Explores the scene at `path` with [`NearestCell`] for at most `budget_s` simulated seconds.
pub fn explore(path: &std::path::Path, budget_s: f64) -> Result<RunOutput> {
    let cfg = Config::load(None, &[format!("sim.budget_s={budget_s}")])?;
    let scene = scene::load(path, &cfg.scene)?;
    let world = World::new(&scene, &cfg, None)?;
    let sim = Simulation::with_planner(&scene, world, &cfg, Box::new(NearestCell::default()));
    Ok(sim.run_to_end(&mut NoObserver))
}

fn main() -> Result<()> {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "scenes/apartment_small.obj".into());
    let out = explore(path.as_ref(), 300.0)?;
    let r = &out.result;
    println!(
        "{}: {} after {:.1} s, completeness {:.3}, path {:.1} m, {} collisions",
        r.planner,
        r.termination.as_str(),
        r.sim_time_s,
        r.completeness,
        r.path_length_m,
        r.collisions
    );
    Ok(())
}
