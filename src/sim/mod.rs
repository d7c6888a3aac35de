//! The simulator: robot, motion executor, the step loop and its metrics.

pub(crate) mod clock;
pub(crate) mod metrics;
pub(crate) mod motion;
pub mod observable;
pub(crate) mod robot;
pub(crate) mod run;

pub use clock::{Stage, StageClock};
pub use metrics::{RunResult, Termination};
pub use observable::{CacheOutcome, ObservableCache, ObservableSet};
pub use run::{run, NoObserver, Observer, RunOutput, Simulation, StepOutcome, StepView, World};
