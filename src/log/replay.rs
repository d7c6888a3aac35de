//! `replay`: a log's summary, its exact re-run check, and pictures.

use super::reader::LogContents;
use super::record::{Recorder, Sink};
use super::topics::{self, Topic};
use super::RunIdentity;
use crate::plan::PlannerKind;
use crate::sim::{self, RunResult, World};
use crate::{Config, Error, Pose2, Result};
use serde::Serialize;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;

/// Metrics at one fraction of the run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Milestone {
    pub fraction: f64,
    pub time_s: f64,
    pub completeness: f64,
    pub path_length_m: f64,
}

/// What `replay` prints.
#[derive(Debug, Serialize)]
pub struct ReplaySummary {
    pub identity: Option<RunIdentity>,
    /// The recorded final result (absent when the run did not finish its file).
    pub result: Option<RunResult>,
    pub milestones: Vec<Milestone>,
    pub messages: BTreeMap<String, u64>,
    pub chunks_read: u64,
    pub chunks_lost: u64,
    pub messages_lost: u64,
    pub complete: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub problem: Option<String>,
}

/// The `/metrics` messages decoded, in time order (undecodable ones skipped).
fn metrics(log: &LogContents) -> Vec<Value> {
    log.topic(topics::METRICS.name)
        .filter_map(|m| serde_json::from_slice(&m.data).ok())
        .collect()
}

/// Completeness and path length at 25, 50, 75 and 100 % of the recorded simulated time (the last
/// `/metrics` sample at or before each fraction).
pub fn milestones(log: &LogContents) -> Vec<Milestone> {
    let samples = metrics(log);
    let Some(end) = samples.last().and_then(|m| m["time_s"].as_f64()) else {
        return Vec::new();
    };
    [0.25, 0.5, 0.75, 1.0]
        .iter()
        .filter_map(|&f| {
            let t = end * f;
            let m = samples
                .iter()
                .take_while(|m| m["time_s"].as_f64().unwrap_or(f64::MAX) <= t + 1e-9)
                .last()?;
            Some(Milestone {
                fraction: f,
                time_s: m["time_s"].as_f64()?,
                completeness: m["completeness"].as_f64()?,
                path_length_m: m["path_length_m"].as_f64()?,
            })
        })
        .collect()
}

pub fn summarise(log: &LogContents) -> ReplaySummary {
    ReplaySummary {
        identity: log.identity.clone(),
        result: log.result.clone(),
        milestones: milestones(log),
        messages: log.counts(),
        chunks_read: log.chunks_read,
        chunks_lost: log.chunks_lost,
        messages_lost: log.messages_lost,
        complete: log.complete,
        problem: log.problem.clone(),
    }
}

/// The first place a re-run differs from the log.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Divergence {
    pub time_s: f64,
    pub topic: String,
    /// JSON pointer of the first differing field, or what is missing.
    pub field: String,
}

/// Compares a re-run's messages with the recorded ones, in order; keeps the first divergence.
struct Comparer<'a> {
    recorded: Vec<&'a super::LoggedMessage>,
    next: usize,
    divergence: Option<Divergence>,
}

/// JSON pointer of the first difference between `a` and `b` (ignoring wall-clock `stage_ms`).
fn first_difference(a: &Value, b: &Value, at: &str) -> Option<String> {
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            for (k, va) in x {
                if k == "stage_ms" {
                    continue;
                }
                match y.get(k) {
                    Some(vb) => {
                        if let Some(d) = first_difference(va, vb, &format!("{at}/{k}")) {
                            return Some(d);
                        }
                    }
                    None => return Some(format!("{at}/{k}")),
                }
            }
            y.keys()
                .find(|k| !x.contains_key(*k))
                .map(|k| format!("{at}/{k}"))
        }
        (Value::Array(x), Value::Array(y)) => {
            if x.len() != y.len() {
                return Some(format!("{at} (length {} vs {})", x.len(), y.len()));
            }
            x.iter()
                .zip(y)
                .enumerate()
                .find_map(|(i, (p, q))| first_difference(p, q, &format!("{at}/{i}")))
        }
        _ => (a != b).then(|| if at.is_empty() { "/".into() } else { at.into() }),
    }
}

impl Sink for Comparer<'_> {
    fn put(&mut self, topic: &'static Topic, time_ns: u64, message: Vec<u8>) {
        if self.divergence.is_some() {
            return;
        }
        let time_s = time_ns as f64 * 1e-9;
        let Some(rec) = self.recorded.get(self.next) else {
            self.divergence = Some(Divergence {
                time_s,
                topic: topic.name.into(),
                field: "message missing from the log (re-run is longer)".into(),
            });
            return;
        };
        self.next += 1;
        let field = if rec.topic != topic.name {
            Some(format!("topic (log has {} here)", rec.topic))
        } else if rec.log_time_ns != time_ns {
            Some(format!("log time (log has {} ns)", rec.log_time_ns))
        } else if rec.data == message {
            None
        } else {
            let a: Value = serde_json::from_slice(&rec.data).unwrap_or(Value::Null);
            let b: Value = serde_json::from_slice(&message).unwrap_or(Value::Null);
            first_difference(&a, &b, "")
        };
        if let Some(field) = field {
            self.divergence = Some(Divergence {
                time_s,
                topic: topic.name.into(),
                field,
            });
        }
    }
}

/// Re-runs the logged run from its recorded scene, config and seed and compares every message
/// (poses, depth, grids, plans, metrics apart from wall-clock `stage_ms`). `Ok(None)` = identical.
pub fn verify(log: &LogContents) -> Result<Option<Divergence>> {
    let id = log
        .identity
        .as_ref()
        .ok_or_else(|| Error::Runtime("the log has no run identity metadata".into()))?;
    let cfg: Config = toml::from_str(&id.config_toml)
        .map_err(|e| Error::Runtime(format!("the log's config does not parse: {e}")))?;
    cfg.validate()?;
    let planner = <PlannerKind as clap::ValueEnum>::from_str(&id.planner, true)
        .map_err(|_| Error::Runtime(format!("log names an unknown planner `{}`", id.planner)))?;
    let scene_path = Path::new(&id.scene_path);
    let scene = crate::scene::load(scene_path, &cfg.scene)?;
    if scene.content_hash != id.scene_hash {
        return Err(Error::Runtime(format!(
            "scene {} changed: content hash {} differs from the logged {}",
            scene_path.display(),
            scene.content_hash,
            id.scene_hash
        )));
    }
    let spawn = parse_spawn(&id.spawn);
    let world = World::new(&scene, &cfg, spawn)?;
    let comparer = Comparer {
        recorded: log.messages.iter().collect(),
        next: 0,
        divergence: None,
    };
    let mut rec = Recorder::new(comparer, &cfg.log, None);
    sim::run(&scene, world, &cfg, planner, &mut rec)?;
    let c = rec.sink;
    if c.divergence.is_some() {
        return Ok(c.divergence);
    }
    if let Some(extra) = c.recorded.get(c.next) {
        return Ok(Some(Divergence {
            time_s: extra.log_time_ns as f64 * 1e-9,
            topic: extra.topic.clone(),
            field: "message in the log but not in the re-run (re-run is shorter)".into(),
        }));
    }
    Ok(None)
}

/// `X,Y,YAW` as stored in [`RunIdentity::spawn`].
fn parse_spawn(s: &str) -> Option<Pose2> {
    let v: Vec<f64> = s.split(',').filter_map(|p| p.parse().ok()).collect();
    (v.len() == 3).then(|| Pose2::new(v[0], v[1], v[2]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn first_difference_names_the_field_and_ignores_stage_ms() {
        let a = json!({"x": 1, "p": {"y": [1, 2]}, "stage_ms": {"sense": 1.0}});
        let b = json!({"x": 1, "p": {"y": [1, 3]}, "stage_ms": {"sense": 2.0}});
        assert_eq!(first_difference(&a, &b, ""), Some("/p/y/1".into()));
        let c = json!({"x": 1, "p": {"y": [1, 2]}, "stage_ms": {"sense": 9.0}});
        assert_eq!(first_difference(&a, &c, ""), None);
    }
}
