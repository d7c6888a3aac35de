//! The simulator: robot, its pose and motion error, motion executor, the step loop and the run's
//! result.

pub(crate) mod clock;
pub(crate) mod motion;
pub(crate) mod odometry;
pub(crate) mod result;
pub(crate) mod robot;
pub(crate) mod run;

pub use crate::eval::{CacheOutcome, ObservableCache, ObservableSet};
pub use clock::{Stage, StageClock};
pub use odometry::{ate, Delta, Odometry};
pub use result::{CurveSample, RunResult, StageStats, Termination, STAGES};
pub use robot::Command;
pub use run::{run, NoObserver, Observer, RunOutput, Simulation, StepOutcome, StepView, World};
