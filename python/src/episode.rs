//! An owned simulation: `sim::Simulation` borrows its scene and config for the run; a Python object
//! must own them, so the episode keeps both behind `Arc`s beside the simulation that borrows them.

use std::sync::Arc;
use tensorscout::plan::Planner;
use tensorscout::scene::Scene;
use tensorscout::sim::{Observer, RunOutput, Simulation, StepOutcome, World};
use tensorscout::Config;

/// A scene, a config and the simulation of a run in them.
pub struct Episode {
    /// Declared first, so dropped first: it borrows `cfg` and `scene`.
    sim: Option<Simulation<'static>>,
    cfg: Arc<Config>,
    scene: Arc<Scene>,
}

// SAFETY: the simulation holds the scene and config by reference, plain data that is `Sync`, the
// world (`World: Send`, asserted below), buffers, and the planner. The planner is either a built-in
// one (`PlannerKind::build` returns `Box<dyn Planner + Send>`) or a Python planner, which holds only
// `Py` handles (`Send`) and takes the GIL for every call; `Episode::new` takes `Send` planners only.
// The episode is therefore safe to move to another thread; it is never shared between threads.
unsafe impl Send for Episode {}

// SAFETY: through a shared reference an episode only gives read access to plain data (the map,
// the last frame, the pose, counters: `Simulation`'s `&self` methods); the planner, the one part
// that might hold interior mutability, is only reached through `&mut` (stepping and finishing).
unsafe impl Sync for Episode {}

const _: () = {
    const fn send<T: Send>() {}
    const fn sync<T: Sync>() {}
    send::<World>();
    send::<tensorscout::map::Map>();
    send::<tensorscout::plan::search::Search>();
    sync::<Scene>();
    sync::<Config>();
};

impl Episode {
    /// A run of `scene` in `world` under `cfg` with `planner`.
    pub fn new(
        scene: Arc<Scene>,
        cfg: Arc<Config>,
        world: World,
        planner: Box<dyn Planner + Send>,
    ) -> Episode {
        // SAFETY: the references point into the `Arc`s this episode keeps alive for as long as the
        // simulation exists (the simulation is dropped first, see the field order, and is only ever
        // taken out by `finish`, which consumes it before returning an owned output). The `Arc`s'
        // contents never move and are never mutated.
        let scene_ref: &'static Scene = unsafe { &*Arc::as_ptr(&scene) };
        let cfg_ref: &'static Config = unsafe { &*Arc::as_ptr(&cfg) };
        let sim = Simulation::with_planner(scene_ref, world, cfg_ref, planner);
        Episode {
            sim: Some(sim),
            cfg,
            scene,
        }
    }

    /// The simulation (until [`Episode::finish`]).
    pub fn sim(&self) -> &Simulation<'static> {
        self.sim.as_ref().expect("episode not finished")
    }

    pub fn sim_mut(&mut self) -> &mut Simulation<'static> {
        self.sim.as_mut().expect("episode not finished")
    }

    pub fn step(&mut self, observer: &mut dyn Observer) -> StepOutcome {
        self.sim_mut().step(observer)
    }

    pub fn cfg(&self) -> &Config {
        &self.cfg
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The run's output; the simulation is gone afterwards.
    pub fn finish(&mut self) -> RunOutput {
        self.sim.take().expect("episode not finished").finish()
    }

    pub fn is_finished(&self) -> bool {
        self.sim.is_none()
    }
}
