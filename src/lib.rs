//! tensorscout: a headless simulator and benchmark for autonomous exploration of indoor scenes by a
//! ground robot with one forward-facing depth camera.
//!
//! Data flows one way through the stages, one module each:
//! `scene` (mesh, ground truth) → `sensor` (depth frames) → `map` (occupancy voxels, 2D layers,
//! frontiers) → `eval` (reachable region, observable set, metrics) → `field` (tensor field and its
//! topology) → `plan` (goals and paths) → `sim` (robot, motion, the step loop, the run's result) →
//! `log`, `bench`, `render` (run logs, batch runs, pictures) → the
//! binary's `cli`. A module uses only its own layer, earlier ones and the foundations (`config`,
//! `error`, `grid`, `util`); `tests/layers.rs` checks it, and ARCHITECTURE.md draws the graph.
//! Implementation modules are private to the crate; each layer re-exports what callers need.
//!
//! One exploration from code:
//!
//! ```no_run
//! use tensorscout::{plan::PlannerKind, scene, sim, Config};
//! # fn main() -> tensorscout::Result<()> {
//! let cfg = Config::default();
//! let scene = scene::load("scenes/apartment_small.obj".as_ref(), &cfg.scene)?;
//! let world = sim::World::new(&scene, &cfg, None)?;
//! let out = sim::run(&scene, world, &cfg, PlannerKind::Thp, &mut sim::NoObserver)?;
//! println!("completeness {:.3}", out.result.completeness);
//! # Ok(()) }
//! ```

pub mod bench;
pub mod config;
pub mod error;
pub mod eval;
pub mod field;
pub mod grid;
pub mod log;
pub mod map;
pub mod plan;
pub mod render;
pub mod scene;
pub mod sensor;
pub mod sim;
pub mod util;

pub use config::Config;
pub use error::{Error, Result};
pub use grid::{Cell, GridSpec};

use serde::{Deserialize, Serialize};

/// A planar pose on the floor: position in metres and heading (yaw about +z) in radians.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pose2 {
    pub x: f64,
    pub y: f64,
    pub yaw: f64,
}

impl Pose2 {
    pub const fn new(x: f64, y: f64, yaw: f64) -> Self {
        Pose2 { x, y, yaw }
    }

    /// The position as a point.
    pub fn position(&self) -> nalgebra::Point2<f64> {
        nalgebra::Point2::new(self.x, self.y)
    }
}

/// The program version, stored in every result and log.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
