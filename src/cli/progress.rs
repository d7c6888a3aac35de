//! Progress bars of the commands that make or measure a scene (a run's and a batch's bars live
//! with their commands), shown only on a terminal.

use indicatif::{ProgressBar, ProgressStyle};
use std::sync::Arc;
use tensorscout::eval::SampleProgress;
use tensorscout::sim::ObservableCache;

/// A bar of `what` (`"rooms furnished"`), hidden unless `shown`.
pub fn bar(shown: bool, what: &str) -> ProgressBar {
    let bar = if shown {
        ProgressBar::new(0)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "[{{elapsed_precise}}] {{bar:30}} {{pos}}/{{len}} {what}, ETA {{eta}}"
        ))
        .expect("valid template"),
    );
    bar
}

/// The user's observable-set cache; when `interactive`, it says that it computes a set and shows
/// the camera positions sampled.
pub fn user_cache(interactive: bool) -> ObservableCache {
    let cache = ObservableCache::user().announcing(interactive);
    if interactive {
        cache.with_progress(Arc::new(Positions(bar(true, "camera positions"))))
    } else {
        cache
    }
}

/// The camera positions of an observable set's sampling, on a bar.
struct Positions(ProgressBar);

impl SampleProgress for Positions {
    fn add(&self, positions: usize) {
        self.0.inc_length(positions as u64);
    }

    fn sampled(&self) {
        self.0.inc(1);
    }

    fn finished(&self) {
        self.0.finish_and_clear();
    }
}
