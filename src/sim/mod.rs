//! The simulator: robot, motion executor, the step loop and its metrics.

pub mod clock;
pub mod metrics;
pub mod motion;
pub mod observable;
pub mod robot;
pub mod run;

pub use clock::{Stage, StageClock};
pub use metrics::{RunResult, Termination};
pub use observable::{CacheOutcome, ObservableCache, ObservableSet};
pub use run::{run, NoObserver, Observer, RunOutput, Simulation, StepOutcome, StepView, World};
