//! What `explore --live` and `replay --live` share: the `--rate` flag, pacing to it, and the lines
//! on stderr that say where the server listens and what it delivered.

use super::{note, signals};
use std::time::{Duration, Instant};
pub use tensorscout::log::live::DEFAULT_ADDR;
use tensorscout::log::{LiveReport, LiveServer};
use tensorscout::sim::{Observer, StepView};

/// `--rate`: how fast simulated time runs against wall time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Rate {
    /// R seconds of simulated time per wall second.
    Times(f64),
    /// As fast as the simulation goes.
    Max,
}

/// `R` (a number from 0.001 to 1e6) or `max`.
pub fn parse_rate(s: &str) -> Result<Rate, String> {
    if s.eq_ignore_ascii_case("max") {
        return Ok(Rate::Max);
    }
    match s.parse::<f64>() {
        Ok(r) if r.is_finite() && (0.001..=1e6).contains(&r) => Ok(Rate::Times(r)),
        _ => Err(format!(
            "`{s}`: give a multiple of real time from 0.001 to 1e6 (1 = real time) or `max`"
        )),
    }
}

/// Holds a run (or a replay) back to `rate` × real time.
pub struct Pacer {
    start: Instant,
    rate: Rate,
}

impl Pacer {
    pub fn new(rate: Rate) -> Pacer {
        Pacer {
            start: Instant::now(),
            rate,
        }
    }

    /// Waits until simulated time `sim_s` is due (at once with `max`, or when a stop is asked).
    pub fn wait_until(&self, sim_s: f64) {
        let Rate::Times(r) = self.rate else {
            return;
        };
        let Some(due) = Duration::try_from_secs_f64(sim_s / r)
            .ok()
            .and_then(|d| self.start.checked_add(d))
        else {
            return;
        };
        loop {
            let now = Instant::now();
            if now >= due || signals::stop_requested() {
                return;
            }
            std::thread::sleep((due - now).min(Duration::from_millis(50)));
        }
    }
}

impl Observer for Pacer {
    fn on_step(&mut self, view: &StepView) {
        self.wait_until(view.time_s);
    }
}

/// Binds the server and says where it listens.
pub fn serve(addr: &str) -> tensorscout::Result<LiveServer> {
    let server = LiveServer::bind(addr)?;
    note!(
        "live: serving on ws://{} (Foxglove: Open connection → Foxglove WebSocket)",
        server.local_addr()
    );
    Ok(server)
}

/// The line at the end: clients served, messages sent and dropped.
pub fn report(r: &LiveReport) {
    note!(
        "live: {} client{} served, {} messages sent, {} dropped (slow or disconnected clients)",
        r.clients,
        if r.clients == 1 { "" } else { "s" },
        r.sent,
        r.dropped
    );
}
