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
//! in [`record`]); [`record`] turns simulator state into messages; [`writer`] writes them with zstd
//! chunks and metadata; [`reader`] reads a possibly damaged file; [`replay`] summarises, verifies
//! and renders.

pub mod reader;
pub mod record;
pub mod replay;
pub mod topics;
pub mod tum;
pub mod writer;

pub use reader::{read_log, LogContents, LoggedMessage};
pub use record::{Recorder, Sink};
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

const B64: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// Standard base64 with padding (how Foxglove's JSON encoding carries `bytes` fields).
pub fn base64_encode(bytes: &[u8]) -> String {
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(B64[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// Inverse of [`base64_encode`]; `None` on a character outside the alphabet.
pub fn base64_decode(text: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    let mut acc = 0u32;
    let mut bits = 0;
    for c in text.bytes().filter(|&c| c != b'=') {
        let v = B64.iter().position(|&a| a == c)? as u32;
        acc = (acc << 6) | v;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_known_answers_and_round_trip() {
        assert_eq!(base64_encode(b""), "");
        assert_eq!(base64_encode(b"f"), "Zg==");
        assert_eq!(base64_encode(b"fo"), "Zm8=");
        assert_eq!(base64_encode(b"foobar"), "Zm9vYmFy");
        let bytes: Vec<u8> = (0..=255).collect();
        assert_eq!(base64_decode(&base64_encode(&bytes)).unwrap(), bytes);
        assert_eq!(base64_decode("Zm8="), Some(b"fo".to_vec()));
        assert_eq!(base64_decode("Z!"), None);
    }

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
