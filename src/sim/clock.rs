//! Wall-clock timing of the step loop's stages, by name rather than by position in an array of
//! instants.

use super::result::StageTimes;
use std::time::Instant;

/// The stages of one step, in data-flow order (their names are [`super::result::STAGES`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    Sense,
    Map,
    Field,
    Plan,
    Motion,
}

impl Stage {
    /// Every stage, in data-flow order.
    pub const ALL: [Stage; 5] = [
        Stage::Sense,
        Stage::Map,
        Stage::Field,
        Stage::Plan,
        Stage::Motion,
    ];

    /// The stage's name in results and logs.
    pub fn name(self) -> &'static str {
        super::result::STAGES[self as usize]
    }
}

/// Times the stages of each step: [`StageClock::begin`] starts a step, [`StageClock::lap`] closes a
/// named stage (the time since the previous lap), [`StageClock::end`] records the step. A stage the
/// step did not reach (the run ended before it) counts as zero for that step.
pub struct StageClock {
    mark: Instant,
    step_ms: [f64; 5],
    times: StageTimes,
}

impl Default for StageClock {
    fn default() -> Self {
        StageClock {
            mark: Instant::now(),
            step_ms: [0.0; 5],
            times: StageTimes::default(),
        }
    }
}

impl StageClock {
    /// Starts timing a step.
    pub fn begin(&mut self) {
        self.step_ms = [0.0; 5];
        self.mark = Instant::now();
    }

    /// Closes `stage`: the wall time since the step began or the previous lap.
    pub fn lap(&mut self, stage: Stage) {
        let now = Instant::now();
        self.step_ms[stage as usize] = (now - self.mark).as_secs_f64() * 1e3;
        self.mark = now;
    }

    /// Records the step's stage times into the run's statistics.
    pub fn end(&mut self) {
        for stage in Stage::ALL {
            self.times
                .record(stage as usize, self.step_ms[stage as usize]);
        }
    }

    /// This step's stage times so far, milliseconds, in the order of [`Stage::ALL`].
    pub fn step_ms(&self) -> [f64; 5] {
        self.step_ms
    }

    /// Records the TSP solve time of one planning step.
    pub fn record_tsp(&mut self, ms: f64) {
        self.times.record_tsp(ms);
    }

    /// The run's statistics per stage.
    pub fn times(&self) -> &StageTimes {
        &self.times
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stages_are_named_in_data_flow_order() {
        let names: Vec<_> = Stage::ALL.iter().map(|s| s.name()).collect();
        assert_eq!(names, ["sense", "map", "field", "plan", "motion"]);
    }

    /// Each step records one sample per stage, zero for the stages it did not reach.
    #[test]
    fn every_step_records_every_stage() {
        let mut clock = StageClock::default();
        clock.begin();
        clock.lap(Stage::Sense);
        clock.lap(Stage::Map);
        clock.end();
        assert_eq!(clock.step_ms()[Stage::Plan as usize], 0.0);
        clock.begin();
        for s in Stage::ALL {
            clock.lap(s);
        }
        clock.end();
        let summary = clock.times().summary();
        assert_eq!(summary.len(), 5);
        // Two samples of `plan`, one of them zero: the nearest-rank median is that zero.
        assert_eq!(summary["plan"].p50, 0.0);
        assert!(!summary.contains_key("tsp"));
    }
}
