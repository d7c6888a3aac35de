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
    /// The log was cut off: running past its last message is not a divergence.
    prefix_only: bool,
    exhausted: &'a std::cell::Cell<bool>,
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
            if self.prefix_only {
                self.exhausted.set(true);
                return;
            }
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

/// What `replay --verify` found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Verification {
    /// The first place the re-run differs from the log; `None` = identical.
    pub divergence: Option<Divergence>,
    /// When the log stops before the run's end (interrupted, or cut off): the simulated time up to
    /// which the comparison went and why it stopped there.
    pub partial: Option<(f64, String)>,
    /// The scene file the re-run used (found by path, absolute path, or hash next to the log).
    pub scene: std::path::PathBuf,
}

/// Stops a re-run after as many steps as the interrupted original ran, so that both end alike.
struct StopAfter<'a, S: Sink> {
    inner: &'a mut Recorder<S>,
    steps: Option<u64>,
    seen: u64,
    /// Set when the log has nothing more to compare (a cut-off log): stop at once.
    exhausted: &'a std::cell::Cell<bool>,
}

impl<S: Sink> sim::Observer for StopAfter<'_, S> {
    fn on_step(&mut self, view: &sim::StepView) {
        self.seen += 1;
        self.inner.on_step(view);
    }
    fn on_plan(
        &mut self,
        time_s: f64,
        action: &crate::plan::Action,
        map: &crate::map::Map,
        tour: &[nalgebra::Point2<f64>],
    ) {
        self.inner.on_plan(time_s, action, map, tour);
    }
    fn on_finish(&mut self, result: &RunResult) {
        self.inner.on_finish(result);
    }
    fn stop_requested(&self) -> bool {
        self.steps.is_some_and(|n| self.seen >= n)
            || self.exhausted.get()
            || self.inner.stop_requested()
    }
}

/// The scene file of a logged run: the path as recorded (relative to the working folder), the
/// absolute path recorded with it, the same file name next to the log, or any file next to the
/// log with the same extension and the recorded content hash (the log was moved with its scene).
fn find_scene(
    id: &RunIdentity,
    cfg: &Config,
    log_path: Option<&Path>,
) -> Result<crate::scene::Scene> {
    let recorded = Path::new(&id.scene_path);
    let mut candidates = vec![recorded.to_path_buf()];
    if !id.scene_abs_path.is_empty() {
        candidates.push(id.scene_abs_path.clone().into());
    }
    let log_dir = log_path.map(|p| {
        p.parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."))
            .to_path_buf()
    });
    if let (Some(dir), Some(name)) = (&log_dir, recorded.file_name()) {
        candidates.push(dir.join(name));
    }
    let mut changed = None;
    let mut tried = std::collections::BTreeSet::new();
    let mut try_path = |p: &Path| -> Option<crate::scene::Scene> {
        if !p.is_file() || !tried.insert(std::path::absolute(p).unwrap_or(p.to_path_buf())) {
            return None;
        }
        match crate::scene::load(p, &cfg.scene) {
            Ok(s) if s.content_hash == id.scene_hash => Some(s),
            Ok(s) => {
                changed.get_or_insert((p.to_path_buf(), s.content_hash));
                None
            }
            Err(_) => None,
        }
    };
    for c in &candidates {
        if let Some(s) = try_path(c) {
            return Ok(s);
        }
    }
    if let Some(dir) = &log_dir {
        let ext = recorded.extension();
        let mut entries: Vec<_> = std::fs::read_dir(dir)
            .map(|rd| rd.filter_map(|e| e.ok().map(|e| e.path())).collect())
            .unwrap_or_default();
        entries.sort();
        for p in entries.iter().filter(|p| p.extension() == ext) {
            if let Some(s) = try_path(p) {
                return Ok(s);
            }
        }
    }
    Err(match changed {
        Some((p, hash)) => Error::Runtime(format!(
            "scene {} changed: content hash {hash} differs from the logged {}",
            p.display(),
            id.scene_hash
        )),
        None => Error::Runtime(format!(
            "scene {} not found (tried the recorded path{}, and files next to the log with hash {})",
            id.scene_path,
            if id.scene_abs_path.is_empty() {
                String::new()
            } else {
                format!(", {}", id.scene_abs_path)
            },
            id.scene_hash
        )),
    })
}

/// Re-runs the logged run from its recorded scene, config and seed and compares every message
/// (poses, depth, grids, plans, metrics apart from wall-clock `stage_ms`). A log that ends early
/// (an interrupted run, or a cut-off file) is compared up to where it ends, and says so.
/// `log_path` locates a scene that moved with the log.
pub fn verify(log: &LogContents, log_path: Option<&Path>) -> Result<Verification> {
    let id = log
        .identity
        .as_ref()
        .ok_or_else(|| Error::Runtime("the log has no run identity metadata".into()))?;
    let cfg: Config = toml::from_str(&id.config_toml)
        .map_err(|e| Error::Runtime(format!("the log's config does not parse: {e}")))?;
    cfg.validate()?;
    // The run is repeated from the config's seed; the seed the log reports must be that one, or a
    // verdict of `identical` would vouch for a seed that was never run.
    if id.seed != cfg.seed {
        return Err(Error::Runtime(format!(
            "the log's seed metadata ({}) differs from the seed its recorded config holds ({}): the log was edited",
            id.seed, cfg.seed
        )));
    }
    let planner = <PlannerKind as clap::ValueEnum>::from_str(&id.planner, true)
        .map_err(|_| Error::Runtime(format!("log names an unknown planner `{}`", id.planner)))?;
    let scene = find_scene(id, &cfg, log_path)?;
    let spawn = parse_spawn(&id.spawn);
    let world = World::with_cache(&scene, &cfg, spawn, &crate::sim::ObservableCache::user())?;
    let interrupted = log
        .result
        .as_ref()
        .filter(|r| r.termination == sim::Termination::Interrupted);
    // Without a recorded result the file was cut off: compare the messages it holds.
    let cut_off = log.result.is_none();
    let exhausted = std::cell::Cell::new(false);
    let comparer = Comparer {
        recorded: log.messages.iter().collect(),
        next: 0,
        divergence: None,
        prefix_only: cut_off,
        exhausted: &exhausted,
    };
    let mut rec = Recorder::new(comparer, &cfg, &scene.mesh, None);
    let mut observer = StopAfter {
        inner: &mut rec,
        steps: interrupted.map(|r| r.steps),
        seen: 0,
        exhausted: &exhausted,
    };
    sim::run(&scene, world, &cfg, planner, &mut observer)?;
    let c = rec.sink;
    let end_s = log
        .messages
        .last()
        .map_or(0.0, |m| m.log_time_ns as f64 * 1e-9);
    let partial = if let Some(r) = interrupted {
        Some((r.sim_time_s, "the run was interrupted there".to_string()))
    } else if cut_off {
        Some((end_s, "the log ends there".to_string()))
    } else {
        None
    };
    let mut divergence = c.divergence;
    if divergence.is_none() && !cut_off {
        if let Some(extra) = c.recorded.get(c.next) {
            divergence = Some(Divergence {
                time_s: extra.log_time_ns as f64 * 1e-9,
                topic: extra.topic.clone(),
                field: "message in the log but not in the re-run (re-run is shorter)".into(),
            });
        }
    }
    Ok(Verification {
        divergence,
        partial,
        scene: scene.path,
    })
}

/// `X,Y,YAW` as stored in [`RunIdentity::spawn`].
fn parse_spawn(s: &str) -> Option<Pose2> {
    let v: Vec<f64> = s.split(',').filter_map(|p| p.parse().ok()).collect();
    (v.len() == 3).then(|| Pose2::new(v[0], v[1], v[2]))
}

/// A `/map/grid` message decoded: its grid and the `state` code of every cell.
struct LoggedGrid {
    grid: crate::GridSpec,
    state: Vec<f32>,
}

fn decode_grid(v: &Value) -> Option<LoggedGrid> {
    decode_grid_at(v, 0)
}

/// A `foxglove.Grid`'s float32 field at byte `offset` within each cell.
fn decode_grid_at(v: &Value, offset: usize) -> Option<LoggedGrid> {
    let nx = v["column_count"].as_u64()? as usize;
    let row_stride = v["row_stride"].as_u64()? as usize;
    let cell_stride = v["cell_stride"].as_u64()? as usize;
    let data = crate::util::base64_decode(v["data"].as_str()?)?;
    if nx == 0
        || row_stride < nx * cell_stride
        || cell_stride < offset + 4
        || data.len() % row_stride != 0
    {
        return None;
    }
    let ny = data.len() / row_stride;
    let grid = crate::GridSpec {
        origin_x: v["pose"]["position"]["x"].as_f64()?,
        origin_y: v["pose"]["position"]["y"].as_f64()?,
        res: v["cell_size"]["x"].as_f64()?,
        nx,
        ny,
        nz: 1,
    };
    let state = (0..nx * ny)
        .map(|i| {
            let at = (i / nx) * row_stride + (i % nx) * cell_stride + offset;
            f32::from_le_bytes(data[at..at + 4].try_into().expect("4 bytes"))
        })
        .collect();
    Some(LoggedGrid { grid, state })
}

/// Coloured sphere centres of a `SceneUpdate` message (`/plan/frontiers`, `/field/degenerate`).
fn decode_spheres(v: &Value) -> Vec<(nalgebra::Point2<f64>, image::Rgb<u8>)> {
    let spheres = v["entities"][0]["spheres"]
        .as_array()
        .cloned()
        .unwrap_or_default();
    spheres
        .iter()
        .filter_map(|s| {
            let p = &s["pose"]["position"];
            let c = &s["color"];
            let ch = |k: &str| (c[k].as_f64().unwrap_or(0.0) * 255.0).round() as u8;
            Some((
                nalgebra::Point2::new(p["x"].as_f64()?, p["y"].as_f64()?),
                image::Rgb([ch("r"), ch("g"), ch("b")]),
            ))
        })
        .collect()
}

/// Points of the line strip in a `/plan/path` message.
fn decode_path(v: &Value) -> Vec<nalgebra::Point2<f64>> {
    decode_lines(v).into_iter().next().unwrap_or_default()
}

/// Every line strip of a `SceneUpdate` message (`/plan/path`, `/field/topology`).
fn decode_lines(v: &Value) -> Vec<Vec<nalgebra::Point2<f64>>> {
    let lines = v["entities"][0]["lines"]
        .as_array()
        .cloned()
        .unwrap_or_default();
    lines
        .iter()
        .map(|l| {
            l["points"]
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(|p| Some(nalgebra::Point2::new(p["x"].as_f64()?, p["y"].as_f64()?)))
                .collect()
        })
        .collect()
}

fn decode_pose(v: &Value) -> Option<Pose2> {
    let p = &v["pose"]["position"];
    let q = &v["pose"]["orientation"];
    let yaw = 2.0 * q["z"].as_f64()?.atan2(q["w"].as_f64()?);
    Some(Pose2::new(p["x"].as_f64()?, p["y"].as_f64()?, yaw))
}

/// The decoded messages of `topic` with their times, in time order.
fn decoded<T>(log: &LogContents, topic: &Topic, f: impl Fn(&Value) -> Option<T>) -> Vec<(u64, T)> {
    log.topic(topic.name)
        .filter_map(|m| {
            let v: Value = serde_json::from_slice(&m.data).ok()?;
            Some((m.log_time_ns, f(&v)?))
        })
        .collect()
}

/// The last item at or before `t_ns`.
fn latest<T>(items: &[(u64, T)], t_ns: u64) -> Option<&T> {
    let n = items.partition_point(|(t, _)| *t <= t_ns);
    n.checked_sub(1).map(|i| &items[i].1)
}

/// Writes `frame_NNNN.png` every `every_s` simulated seconds and `overview.png`: the latest map
/// key frame (unknown grey, free white, obstacles black, frontier cells orange), frontiers coloured
/// by group, the planner's tour (orange, first stop larger), the path being followed (an A* path or
/// an advected pathline), the driven path, and the robot with its camera frustum. Returns the
/// number of frames written. Field glyphs, separatrices and degenerate points are drawn when
/// `log.field` was on.
pub fn render(log: &LogContents, dir: &Path, every_s: f64) -> Result<usize> {
    use super::record::{GRID_FREE, GRID_FRONTIER, GRID_OBSTACLE};
    use crate::render::palette::{
        fade, FOV, GLYPH, PLAN_PATH, ROBOT, SEPARATRIX, TOPOLOGY_EDGE, TOUR,
    };
    use crate::render::{Canvas, FREE, FRONTIER, OCCUPIED, PATH, START, UNKNOWN};
    let grids = decoded(log, &topics::MAP_GRID, decode_grid);
    let poses = decoded(log, &topics::POSE, decode_pose);
    let frontiers = decoded(log, &topics::PLAN_FRONTIERS, |v| Some(decode_spheres(v)));
    let degenerate = decoded(log, &topics::FIELD_DEGENERATE, |v| Some(decode_spheres(v)));
    let paths = decoded(log, &topics::PLAN_PATH, |v| Some(decode_path(v)));
    let tours = decoded(log, &topics::PLAN_TOUR, |v| {
        Some((decode_path(v), decode_spheres(v)))
    });
    let tensors = decoded(log, &topics::FIELD_TENSOR, |v| {
        Some((decode_grid_at(v, 0)?, decode_grid_at(v, 4)?))
    });
    let topology = decoded(log, &topics::FIELD_TOPOLOGY, |v| {
        let colours = v["entities"][0]["lines"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|l| {
                let ch = |k: &str| (l["color"][k].as_f64().unwrap_or(0.0) * 255.0).round() as u8;
                let c = image::Rgb([ch("r"), ch("g"), ch("b")]);
                if c == TOPOLOGY_EDGE {
                    TOPOLOGY_EDGE
                } else {
                    SEPARATRIX
                }
            });
        Some(decode_lines(v).into_iter().zip(colours).collect::<Vec<_>>())
    });
    let Some(end_ns) = poses.last().map(|p| p.0) else {
        return Err(Error::Runtime("the log has no poses to draw".into()));
    };
    let cfg: Option<Config> = log
        .identity
        .as_ref()
        .and_then(|id| toml::from_str(&id.config_toml).ok());
    let (hfov, range) = cfg.as_ref().map_or((58f64, 5.0), |c| {
        (c.camera.hfov_deg, c.camera.max_range_m.get())
    });
    let draw = |t_ns: u64, with_plan: bool| -> Option<Canvas> {
        let g = latest(&grids, t_ns)?;
        let mut canvas = Canvas::new(g.grid, UNKNOWN);
        canvas.paint_cells(|i| match g.state[i] {
            s if s == GRID_OBSTACLE => Some(OCCUPIED),
            s if s == GRID_FRONTIER => Some(FRONTIER),
            s if s == GRID_FREE => Some(FREE),
            _ => None,
        });
        let cell_px = canvas.scale as f64;
        if with_plan {
            // The field as glyphs along its major eigenvector, every 4th cell where it is defined,
            // and the separatrices and graph edges, when the field was logged.
            if let Some((a, b)) = latest(&tensors, t_ns) {
                let every = 4;
                let half = 0.4 * every as f64 * a.grid.res;
                for iy in (every / 2..a.grid.ny).step_by(every) {
                    for ix in (every / 2..a.grid.nx).step_by(every) {
                        let c = crate::Cell::new(ix as i32, iy as i32);
                        let i = a.grid.index(c);
                        let (ai, bi) = (f64::from(a.state[i]), f64::from(b.state[i]));
                        let p = a.grid.center(c);
                        // Glyphs only over known free space of the map at that time.
                        let known = g.grid.cell_of(p).is_some_and(|mc| {
                            let s = g.state[g.grid.index(mc)];
                            s == GRID_FREE || s == GRID_FRONTIER
                        });
                        if ai.hypot(bi) <= 0.0 || !known {
                            continue;
                        }
                        let theta = 0.5 * bi.atan2(ai);
                        let d = nalgebra::Vector2::new(theta.cos(), theta.sin()) * half;
                        canvas.line(p - d, p + d, 1.0, fade(GLYPH, 0.35));
                        canvas.note(GLYPH);
                    }
                }
            }
            for (line, c) in latest(&topology, t_ns).into_iter().flatten() {
                let width = if *c == TOPOLOGY_EDGE { 1.5 } else { 1.0 };
                canvas.polyline(line, width, *c);
            }
            for (p, c) in latest(&frontiers, t_ns).into_iter().flatten() {
                canvas.disc(*p, (cell_px * 0.6).max(1.5), *c);
            }
            // Degenerate points by type (the palette's wedge and trisector colours, as logged).
            for (p, c) in latest(&degenerate, t_ns).into_iter().flatten() {
                canvas.disc(*p, (cell_px * 1.5).max(3.0), *c);
            }
            if let Some((line, stops)) = latest(&tours, t_ns) {
                canvas.polyline(line, 1.5, TOUR);
                for (k, (p, c)) in stops.iter().enumerate() {
                    let r = if k == 0 { 2.0 } else { 1.2 } * cell_px;
                    canvas.disc(*p, r.max(2.0), *c);
                }
            }
            if let Some(path) = latest(&paths, t_ns) {
                canvas.polyline(path, 2.0, PLAN_PATH);
            }
        }
        let n = poses.partition_point(|(t, _)| *t <= t_ns);
        let driven: Vec<_> = poses[..n].iter().map(|(_, p)| p.position()).collect();
        canvas.polyline(&driven, 2.0, PATH);
        if let (Some(first), Some((_, pose))) =
            (driven.first(), n.checked_sub(1).map(|i| &poses[i]))
        {
            let r = (0.25 / g.grid.res * cell_px).max(3.0);
            canvas.disc(*first, r, START);
            // The field of view: rays across the FOV, each stopped at the first obstacle cell of
            // the map (marched in steps of half a cell); the outline joins the two edge rays and
            // the rays' ends.
            let half = hfov.to_radians() / 2.0;
            let o = pose.position();
            let step = g.grid.res / 2.0;
            let ray = |a: f64| {
                let d = nalgebra::Vector2::new(a.cos(), a.sin());
                let mut t = 0.0;
                while t < range {
                    let next = (t + step).min(range);
                    let hit = g
                        .grid
                        .cell_of(o + d * next)
                        .is_some_and(|c| g.state[g.grid.index(c)] == GRID_OBSTACLE);
                    if hit {
                        break;
                    }
                    t = next;
                }
                o + d * t
            };
            const RAYS: usize = 24;
            let ends: Vec<_> = (0..=RAYS)
                .map(|k| ray(pose.yaw + half - 2.0 * half * k as f64 / RAYS as f64))
                .collect();
            canvas.line(o, ends[0], 1.0, FOV);
            canvas.line(o, ends[RAYS], 1.0, FOV);
            canvas.polyline(&ends, 1.0, FOV);
            canvas.disc(o, r, ROBOT);
        }
        Some(canvas)
    };
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let step_ns = super::record::time_ns(every_s).max(1);
    let mut frames = 0;
    let mut t = 0;
    while t <= end_ns {
        if let Some(c) = draw(t, true) {
            c.save(&dir.join(format!("frame_{frames:04}.png")))?;
            frames += 1;
        }
        t += step_ns;
    }
    draw(end_ns, false)
        .ok_or_else(|| Error::Runtime("the log has no map key frame to draw".into()))?
        .save(&dir.join("overview.png"))?;
    Ok(frames)
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
