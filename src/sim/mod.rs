//! The simulator: robot, motion executor, the step loop and its metrics.

pub mod metrics;
pub mod motion;
pub mod observable;
pub mod robot;
pub mod run;

pub use metrics::{RunResult, Termination};
pub use observable::{CacheOutcome, ObservableCache, ObservableSet};
pub use run::{run, run_planner, NoObserver, Observer, RunOutput, StepView, World};
