//! Run logs in MCAP: one file per run that any MCAP reader reads and Foxglove opens directly.
//!
//! Why the `mcap` crate with Foxglove's JSON schemas and not the `foxglove` SDK crate: (1) `replay`
//! must decode what it wrote, and the SDK only encodes (decoding its protobuf types would add
//! `prost` decoding code of our own); (2) even with `default-features = false` the SDK pulls in its
//! logging context machinery (arc-swap, bimap, flume, parking_lot, tracing, prost, ...) on a 2-core
//! build machine; (3) we need byte-exact control of message content and timestamps (simulated
//! time) so that `replay --verify` can compare a re-run message by message. Foxglove opens
//! `jsonschema`-encoded channels whose schema name is a well-known `foxglove.*` name; byte fields
//! (`data`) are base64 strings, as Foxglove's JSON encoding expects.
//!
//! Layout: [`topics`] is the registry (adding a topic is one line there plus one builder function
//! in [`record`]); [`record`] turns simulator state into messages, once, for two sinks
//! ([`Sinks`]): [`writer`] writes them with zstd chunks and metadata, [`live`] serves them to
//! Foxglove over a WebSocket as the run goes; [`reader`] reads a possibly damaged file; [`replay`] summarises, verifies
//! and renders.

pub mod live;
pub mod reader;
pub(crate) mod record;
pub mod replay;
pub(crate) mod topics;
pub mod tum;
pub(crate) mod writer;

pub use live::{LiveReport, LiveServer};
pub use reader::{read_log, LogContents, LoggedMessage};
pub use record::{Recorder, Sink, Sinks};
pub use topics::{Topic, TOPICS};
pub use writer::RunLog;

use serde::{Deserialize, Serialize};

/// Name of the MCAP metadata record that identifies the run.
pub const RUN_METADATA: &str = "tensorscout.run";
/// Name of the MCAP metadata record holding the final `RunResult` JSON.
pub const RESULT_METADATA: &str = "tensorscout.result";

/// What identifies a run well enough to repeat it (stored as MCAP metadata).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunIdentity {
    /// The scene path as given on the command line.
    pub scene_path: String,
    /// The same path made absolute when the run started (empty in logs written before it was
    /// stored), so that `replay --verify` works from any folder.
    pub scene_abs_path: String,
    pub scene_hash: String,
    pub planner: String,
    pub seed: u64,
    pub version: String,
    pub config_hash: String,
    pub config_toml: String,
    /// `X,Y,YAW` of an explicit `--spawn`, empty when the scene's own was used.
    pub spawn: String,
}

impl RunIdentity {
    /// The identity of a run of `planner` on `scene` (loaded from `scene_path`) under `cfg`.
    pub fn new(
        scene_path: &std::path::Path,
        scene: &crate::scene::Scene,
        planner: crate::plan::PlannerKind,
        cfg: &crate::Config,
        spawn: Option<crate::Pose2>,
    ) -> Self {
        RunIdentity {
            scene_path: scene_path.display().to_string(),
            scene_abs_path: std::path::absolute(scene_path)
                .map(|p| p.display().to_string())
                .unwrap_or_default(),
            scene_hash: scene.content_hash.clone(),
            planner: planner.name().to_string(),
            seed: cfg.seed,
            version: crate::VERSION.to_string(),
            config_hash: cfg.hash(),
            config_toml: cfg.to_toml(),
            spawn: spawn
                .map(|p| format!("{},{},{}", p.x, p.y, p.yaw))
                .unwrap_or_default(),
        }
    }

    fn to_map(&self) -> std::collections::BTreeMap<String, String> {
        [
            ("scene_path", &self.scene_path),
            ("scene_abs_path", &self.scene_abs_path),
            ("scene_hash", &self.scene_hash),
            ("planner", &self.planner),
            ("seed", &self.seed.to_string()),
            ("version", &self.version),
            ("config_hash", &self.config_hash),
            ("config_toml", &self.config_toml),
            ("spawn", &self.spawn),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v.clone()))
        .collect()
    }

    fn from_map(m: &std::collections::BTreeMap<String, String>) -> Option<RunIdentity> {
        let get = |k: &str| m.get(k).cloned();
        Some(RunIdentity {
            scene_path: get("scene_path")?,
            scene_abs_path: get("scene_abs_path").unwrap_or_default(),
            scene_hash: get("scene_hash")?,
            planner: get("planner")?,
            seed: get("seed")?.parse().ok()?,
            version: get("version")?,
            config_hash: get("config_hash")?,
            config_toml: get("config_toml")?,
            spawn: get("spawn").unwrap_or_default(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identity_round_trips_through_metadata() {
        let id = RunIdentity {
            scene_path: "s.obj".into(),
            scene_abs_path: "/data/s.obj".into(),
            scene_hash: "00ff".into(),
            planner: "greedy".into(),
            seed: 7,
            version: "0.1.0".into(),
            config_hash: "abc".into(),
            config_toml: "seed = 7\n".into(),
            spawn: String::new(),
        };
        assert_eq!(RunIdentity::from_map(&id.to_map()), Some(id));
    }
}
