//! Turns simulator state into log messages (JSON bytes), one builder function per topic; the same
//! code feeds the file writer and `replay --verify`, so a re-run is compared byte for byte.

use super::topics::{self, Topic};
use crate::config::{CameraConfig, Config, FieldConfig, LogConfig};
use crate::field::{DegenerateKind, TensorField};
use crate::map::{CellState, Map};
use crate::plan::Action;
use crate::render::palette;
use crate::scene::TriMesh;
use crate::sim::STAGES;
use crate::sim::{Observer, RunResult, StepView};
use crate::Pose2;
use nalgebra::Point2;
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// Where recorded messages go.
pub trait Sink {
    fn put(&mut self, topic: &'static Topic, time_ns: u64, message: Vec<u8>);
    fn finish(&mut self, _result: &RunResult) {}
}

/// The run log, the live server, or both: every message is built once and goes to each.
#[derive(Default)]
pub struct Sinks {
    pub log: Option<super::RunLog>,
    pub live: Option<super::LiveServer>,
}

impl Sink for Sinks {
    fn put(&mut self, topic: &'static Topic, time_ns: u64, message: Vec<u8>) {
        if let Some(live) = &self.live {
            live.publish(topic, time_ns, &message);
        }
        if let Some(log) = &mut self.log {
            log.put(topic, time_ns, message);
        }
    }

    fn finish(&mut self, result: &RunResult) {
        if let Some(log) = &mut self.log {
            log.finish(result);
        }
        if let Some(live) = &mut self.live {
            live.finish(result);
        }
    }
}

/// An [`Observer`] that builds every topic's messages at the configured rates.
pub struct Recorder<S: Sink> {
    pub sink: S,
    cfg: LogConfig,
    field_cfg: FieldConfig,
    /// `additions.field_range_m`, for the field built here.
    field_range_m: f64,
    /// Built at the first key frame when `log.field` is on (GREEDY has no field of its own).
    field: Option<TensorField>,
    frames_seen: u64,
    next_key_frame_s: f64,
    stop: Option<Arc<AtomicBool>>,
    camera: CameraConfig,
    robot_radius_m: f64,
    robot_height_m: f64,
    /// `/scene`, built once from the mesh and written at the first step (then `None`).
    scene: Option<Value>,
    /// The travelled trajectory, simplified (see [`Trajectory`]).
    trajectory: Trajectory,
    /// Whether `/tf` carries the true pose beside the estimate (`[noise.pose]` or
    /// `[noise.motion]` on).
    true_frame: bool,
}

impl<S: Sink> Recorder<S> {
    /// A recorder of a run on `mesh` (the scene, logged once on `/scene`) under `cfg`; `stop`, when
    /// set, ends the run cleanly (Ctrl-C).
    pub fn new(sink: S, cfg: &Config, mesh: &TriMesh, stop: Option<Arc<AtomicBool>>) -> Self {
        Recorder {
            sink,
            cfg: cfg.log.clone(),
            field_cfg: cfg.field.clone(),
            field_range_m: cfg.additions.field_range_m.get(),
            field: None,
            frames_seen: 0,
            next_key_frame_s: 0.0,
            stop,
            camera: cfg.camera.clone(),
            robot_radius_m: cfg.robot.radius_m,
            robot_height_m: cfg.robot.height_m,
            scene: Some(scene_message(0.0, mesh)),
            trajectory: Trajectory::default(),
            true_frame: cfg.noise.pose_is_noisy(),
        }
    }

    fn put(&mut self, topic: &'static Topic, time_s: f64, message: &Value) {
        let bytes = serde_json::to_vec(message).expect("JSON values serialise");
        self.sink.put(topic, time_ns(time_s), bytes);
    }

    /// `/robot/pose` and `/tf` at `time_s` (with the true pose when the run has pose or motion
    /// noise), and the pose appended to the trajectory.
    fn put_pose(&mut self, time_s: f64, pose: Pose2, true_pose: Pose2) {
        self.put(&topics::POSE, time_s, &pose_message(time_s, pose));
        let true_pose = self.true_frame.then_some(true_pose);
        let tf = tf_message(time_s, pose, true_pose, &self.camera);
        self.put(&topics::TF, time_s, &tf);
        self.trajectory.push([pose.x, pose.y]);
    }
}

/// Simulated time in whole nanoseconds (the MCAP log time of every message).
pub fn time_ns(time_s: f64) -> u64 {
    (time_s * 1e9).round() as u64
}

fn stamp(time_s: f64) -> Value {
    let ns = time_ns(time_s);
    json!({"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000})
}

fn pose_json(x: f64, y: f64, z: f64, yaw: f64) -> Value {
    json!({
        "position": {"x": x, "y": y, "z": z},
        "orientation": {"x": 0.0, "y": 0.0, "z": (yaw / 2.0).sin(), "w": (yaw / 2.0).cos()}
    })
}

/// `/robot/pose`: the robot on the floor, heading as a quaternion about +z.
pub fn pose_message(time_s: f64, pose: Pose2) -> Value {
    json!({"timestamp": stamp(time_s), "frame_id": "world", "pose": pose_json(pose.x, pose.y, 0.0, pose.yaw)})
}

/// Rotation from `base_link` (x forward, y left, z up) to the camera's optical frame (z forward,
/// x right, y down), as ROS and Foxglove expect for images: quaternion `(x, y, z, w)`.
pub const OPTICAL_ROTATION: [f64; 4] = [-0.5, 0.5, -0.5, 0.5];

fn transform(time_s: f64, parent: &str, child: &str, t: [f64; 3], q: [f64; 4]) -> Value {
    json!({
        "timestamp": stamp(time_s), "parent_frame_id": parent, "child_frame_id": child,
        "translation": {"x": t[0], "y": t[1], "z": t[2]},
        "rotation": {"x": q[0], "y": q[1], "z": q[2], "w": q[3]}
    })
}

/// `/tf`: `world → base_link` (the robot on the floor, where it believes it is) and the fixed
/// `base_link → camera` (the optical frame at the mount height); with pose or motion noise also
/// `world → base_link_true`, the true pose, so that a viewer shows the drift. The fixed transform
/// is repeated in every message so that a viewer that seeks (and reads back only the latest `/tf`)
/// still has the whole tree.
pub fn tf_message(
    time_s: f64,
    pose: Pose2,
    true_pose: Option<Pose2>,
    camera: &CameraConfig,
) -> Value {
    let on_floor = |parent: &str, child: &str, p: Pose2| {
        let (s, c) = (p.yaw / 2.0).sin_cos();
        transform(time_s, parent, child, [p.x, p.y, 0.0], [0.0, 0.0, s, c])
    };
    let mut transforms = vec![
        on_floor("world", "base_link", pose),
        transform(
            time_s,
            "base_link",
            "camera",
            [0.0, 0.0, camera.mount_height_m.get()],
            OPTICAL_ROTATION,
        ),
    ];
    if let Some(t) = true_pose {
        transforms.push(on_floor("world", "base_link_true", t));
    }
    json!({ "transforms": transforms })
}

/// The pinhole intrinsics `(fx, fy, cx, cy)` of the depth camera, pixels, with pixel centres at
/// integer coordinates (ROS convention): ray `(col, row)` leaves through `((col + 0.5)/w·2 − 1)·tan(hfov/2)`
/// (see `DepthCamera::new`), so `fx = w / (2 tan(hfov/2))` and `cx = w/2 − 0.5`.
pub fn intrinsics(camera: &CameraConfig) -> [f64; 4] {
    let (w, h) = (camera.width as f64, camera.height as f64);
    let fx = w / (2.0 * (camera.hfov_deg.to_radians() / 2.0).tan());
    let fy = h / (2.0 * (camera.vfov_deg.to_radians() / 2.0).tan());
    [fx, fy, w / 2.0 - 0.5, h / 2.0 - 0.5]
}

/// `/camera/calibration`: the depth camera's pinhole model (no distortion), in the `camera` frame.
pub fn calibration_message(time_s: f64, camera: &CameraConfig) -> Value {
    let [fx, fy, cx, cy] = intrinsics(camera);
    json!({
        "timestamp": stamp(time_s), "frame_id": "camera",
        "width": camera.width, "height": camera.height,
        "distortion_model": "plumb_bob", "D": [0.0, 0.0, 0.0, 0.0, 0.0],
        "K": [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
        "R": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        "P": [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    })
}

/// Rounds a coordinate to a tenth of a millimetre for display topics (halves their size; far
/// below any resolution in the simulation).
fn r4(v: f64) -> f64 {
    (v * 1e4).round() / 1e4
}

/// `/scene`: the scene mesh as one faint grey `TriangleListPrimitive` in `world` (shared vertices
/// through `indices`), an entity of its own that the viewer can hide.
pub fn scene_message(time_s: f64, mesh: &TriMesh) -> Value {
    let points: Vec<Value> = mesh
        .vertices
        .iter()
        .map(|v| json!({"x": r4(f64::from(v.x)), "y": r4(f64::from(v.y)), "z": r4(f64::from(v.z))}))
        .collect();
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let mut e = entity_value(time_s, "world", "scene_mesh", false);
    e["triangles"] = json!([{
        "pose": pose_json(0.0, 0.0, 0.0, 0.0), "points": points,
        "color": colour_alpha(palette::SCENE_MESH, 0.25), "colors": [], "indices": indices
    }]);
    update(e)
}

/// `/robot/footprint`: the robot's disc (a cylinder of its radius and height) and a heading arrow,
/// in `base_link` and frame-locked, so the viewer moves it with `/tf`.
pub fn footprint_message(time_s: f64, radius_m: f64, height_m: f64) -> Value {
    let mut e = entity_value(time_s, "base_link", "robot", true);
    e["cylinders"] = json!([{
        "pose": pose_json(0.0, 0.0, height_m / 2.0, 0.0),
        "size": {"x": 2.0 * radius_m, "y": 2.0 * radius_m, "z": height_m},
        "bottom_scale": 1.0, "top_scale": 1.0, "color": colour_alpha(palette::ROBOT, 0.6)
    }]);
    e["arrows"] = json!([{
        "pose": pose_json(0.0, 0.0, height_m + 0.05, 0.0),
        "shaft_length": 1.5 * radius_m, "shaft_diameter": 0.05,
        "head_length": 0.15, "head_diameter": 0.12, "color": colour(palette::ROBOT)
    }]);
    update(e)
}

/// The travelled path with collinear runs dropped: a pose is kept when a skipped point would lie
/// more than [`Trajectory::TOLERANCE_M`] from the straight segment that replaces it, so the line
/// drawn differs from the driven path by at most that much.
#[derive(Debug, Default)]
pub struct Trajectory {
    /// Kept points.
    pub kept: Vec<[f64; 2]>,
    /// Points since the last kept one (the candidate segment's interior and its end).
    tail: Vec<[f64; 2]>,
}

impl Trajectory {
    pub const TOLERANCE_M: f64 = 0.01;

    pub fn push(&mut self, p: [f64; 2]) {
        let Some(&a) = self.kept.last() else {
            self.kept.push(p);
            return;
        };
        let off = |q: &[f64; 2]| {
            let (dx, dy) = (p[0] - a[0], p[1] - a[1]);
            let len = dx.hypot(dy);
            if len < 1e-12 {
                (q[0] - a[0]).hypot(q[1] - a[1])
            } else {
                ((q[0] - a[0]) * dy - (q[1] - a[1]) * dx).abs() / len
            }
        };
        if self.tail.iter().any(|q| off(q) > Self::TOLERANCE_M) {
            let last = *self.tail.last().expect("non-empty when a point deviates");
            self.kept.push(last);
            self.tail.clear();
        }
        self.tail.push(p);
    }

    /// The line to draw: the kept points and the current position.
    pub fn points(&self) -> impl Iterator<Item = &[f64; 2]> {
        self.kept.iter().chain(self.tail.last())
    }
}

/// `/robot/trajectory`: the path travelled so far as a line strip in `world`.
pub fn trajectory_message(time_s: f64, trajectory: &Trajectory) -> Value {
    let points: Vec<Value> = trajectory
        .points()
        .map(|p| json!({"x": r4(p[0]), "y": r4(p[1]), "z": 0.02}))
        .collect();
    let mut e = entity_value(time_s, "world", "trajectory", false);
    e["lines"] = json!([line_strip(&points, palette::PATH, 0.04)]);
    update(e)
}

/// `/camera/depth`: 16UC1 depth along the optical axis in millimetres (0 = no return), the depth
/// convention of ROS REP 118. `foxglove.RawImage` defines `32FC1` as brightness from 0 (black) to
/// 1 (white), so depth in metres there shows as a white image, whereas a 16-bit image is drawn
/// with the image panel's colour map and value range (the shipped layout's 0–5 m).
pub fn depth_message(time_s: f64, frame: &crate::sensor::DepthFrame) -> Value {
    let bytes: Vec<u8> = frame
        .depth_image()
        .iter()
        .flat_map(|&d| depth_mm(d).to_le_bytes())
        .collect();
    json!({
        "timestamp": stamp(time_s), "frame_id": "camera",
        "width": frame.width, "height": frame.height, "encoding": "16UC1",
        "step": frame.width * 2, "data": crate::util::base64_encode(&bytes)
    })
}

/// A depth in metres as a 16UC1 pixel: the nearest millimetre (0 stays 0, no return). Depth beyond
/// 65.535 m, possible only with `camera.max_range_m` above it, saturates at 65535: a 16-bit pixel
/// has no room for it, and an indoor camera sees no farther.
pub fn depth_mm(depth_m: f32) -> u16 {
    (depth_m * 1000.0).round().clamp(0.0, f32::from(u16::MAX)) as u16
}

/// Cell codes of the `state` layer of `/map/grid`.
pub const GRID_UNKNOWN: f32 = 0.0;
pub const GRID_FREE: f32 = 1.0;
pub const GRID_OBSTACLE: f32 = 2.0;
pub const GRID_FRONTIER: f32 = 3.0;

/// `/map/grid`: two float32 layers per cell, `state` (codes above) and `known` (fraction of the
/// column's voxels that are known, a height/knowledge layer).
pub fn grid_message(time_s: f64, map: &Map) -> Value {
    let g = *map.grid();
    let mut data = Vec::with_capacity(g.cells() * 8);
    for idx in 0..g.cells() {
        let state = if map.is_frontier(idx) {
            GRID_FRONTIER
        } else {
            match map.cell_state(idx) {
                CellState::Unknown => GRID_UNKNOWN,
                CellState::Free => GRID_FREE,
                CellState::Obstacle => GRID_OBSTACLE,
            }
        };
        let known = (0..g.nz)
            .filter(|&iz| map.is_voxel_known(g.voxel_index(g.cell(idx), iz)))
            .count() as f32
            / g.nz.max(1) as f32;
        data.extend_from_slice(&state.to_le_bytes());
        data.extend_from_slice(&known.to_le_bytes());
    }
    json!({
        "timestamp": stamp(time_s), "frame_id": "world",
        "pose": pose_json(g.origin_x, g.origin_y, 0.0, 0.0),
        "column_count": g.nx, "cell_size": {"x": g.res, "y": g.res},
        "row_stride": g.nx * 8, "cell_stride": 8,
        "fields": [{"name": "state", "offset": 0, "type": 7}, {"name": "known", "offset": 4, "type": 7}],
        "data": crate::util::base64_encode(&data)
    })
}

/// `v` as float32 rounded to 10 mantissa bits (relative error at most 2⁻¹¹ ≈ 0.05 %): full float32
/// noise in the low bits does not compress, and the field dominated the log's size (office_large:
/// 55 MB → 39 MB with this rounding; see README, run logs).
pub fn round_f32(v: f64) -> f32 {
    const DROP: u32 = 13;
    let bits = (v as f32).to_bits();
    f32::from_bits(bits.wrapping_add(1 << (DROP - 1)) & !((1 << DROP) - 1))
}

/// `/field/tensor`: the field's `a`, `b` (tensor components) and constraint weight as float32,
/// rounded by [`round_f32`].
pub fn field_tensor_message(time_s: f64, field: &TensorField) -> Value {
    let f = field.field();
    let g = f.spec;
    let mut data = Vec::with_capacity(g.cells() * 12);
    for i in 0..g.cells() {
        for v in [f.ab[i][0], f.ab[i][1], f.weight[i]] {
            data.extend_from_slice(&round_f32(v).to_le_bytes());
        }
    }
    json!({
        "timestamp": stamp(time_s), "frame_id": "world",
        "pose": pose_json(g.origin_x, g.origin_y, 0.0, 0.0),
        "column_count": g.nx, "cell_size": {"x": g.res, "y": g.res},
        "row_stride": g.nx * 12, "cell_stride": 12,
        "fields": [{"name": "a", "offset": 0, "type": 7}, {"name": "b", "offset": 4, "type": 7},
                   {"name": "weight", "offset": 8, "type": 7}],
        "data": crate::util::base64_encode(&data)
    })
}

/// `/field/degenerate`: one sphere per degenerate point, coloured by type (the palette's wedge,
/// trisector and other colours).
pub fn degenerate_message(time_s: f64, field: &TensorField) -> Value {
    let spheres: Vec<Value> = field
        .points()
        .iter()
        .map(|p| {
            let c = match p.kind {
                DegenerateKind::Wedge => palette::WEDGE,
                DegenerateKind::Trisector => palette::TRISECTOR,
                _ => palette::OTHER_DEGENERATE,
            };
            json!({"pose": pose_json(p.x, p.y, 0.3, 0.0), "size": {"x": 0.3, "y": 0.3, "z": 0.3}, "color": colour(c)})
        })
        .collect();
    let mut e = entity_value(time_s, "world", "degenerate_points", false);
    e["spheres"] = Value::Array(spheres);
    update(e)
}

fn line_strip(points: &[Value], c: image::Rgb<u8>, thickness: f64) -> Value {
    json!({
        "type": 0, "pose": pose_json(0.0, 0.0, 0.0, 0.0), "thickness": thickness,
        "scale_invariant": false, "points": points, "color": colour(c),
        "colors": [], "indices": []
    })
}

/// `/field/topology`: separatrices as thin line strips and topology-graph edges as thicker ones
/// (each edge is a traced separatrix or a shortest-path pairing between two points).
pub fn topology_message(time_s: f64, field: &TensorField) -> Value {
    let strip = |polyline: &[[f64; 2]], c, thickness: f64| {
        let points: Vec<Value> = polyline
            .iter()
            .map(|p| json!({"x": p[0], "y": p[1], "z": 0.2}))
            .collect();
        line_strip(&points, c, thickness)
    };
    let graph = field.graph();
    let lines: Vec<Value> = graph
        .separatrices
        .iter()
        .map(|s| strip(&s.polyline, palette::SEPARATRIX, 0.03))
        .chain(
            graph
                .edges
                .iter()
                .map(|e| strip(&e.polyline, palette::TOPOLOGY_EDGE, 0.06)),
        )
        .collect();
    let mut e = entity_value(time_s, "world", "topology", false);
    e["lines"] = Value::Array(lines);
    update(e)
}

fn colour(c: image::Rgb<u8>) -> Value {
    colour_alpha(c, 1.0)
}

fn colour_alpha(c: image::Rgb<u8>, a: f64) -> Value {
    let [r, g, b] = c.0;
    json!({"r": f64::from(r) / 255.0, "g": f64::from(g) / 255.0, "b": f64::from(b) / 255.0, "a": a})
}

/// A `SceneEntity` with every primitive list empty (the official schema requires them all).
fn entity_value(time_s: f64, frame_id: &str, id: &str, frame_locked: bool) -> Value {
    json!({
        "timestamp": stamp(time_s), "frame_id": frame_id, "id": id,
        "lifetime": {"sec": 0, "nsec": 0}, "frame_locked": frame_locked, "metadata": [],
        "arrows": [], "cubes": [], "spheres": [], "cylinders": [], "lines": [],
        "triangles": [], "texts": [], "models": []
    })
}

/// A `SceneUpdate` that adds or replaces `entity`.
fn update(entity: Value) -> Value {
    json!({"deletions": [], "entities": [entity]})
}

fn entity(time_s: f64, id: &str, spheres: Vec<Value>, lines: Vec<Value>) -> Value {
    let mut e = entity_value(time_s, "world", id, false);
    e["spheres"] = Value::Array(spheres);
    e["lines"] = Value::Array(lines);
    update(e)
}

/// `/plan/frontiers`: one sphere per frontier cell, coloured by its group (segment).
pub fn frontiers_message(time_s: f64, map: &Map) -> Value {
    let g = map.grid();
    let mut spheres = Vec::new();
    for (group, seg) in map.frontiers().iter().enumerate() {
        let c = colour(palette::GROUP_COLOURS[group % palette::GROUP_COLOURS.len()]);
        for &cell in &seg.cells {
            let p = g.center(cell);
            spheres.push(json!({
                "pose": pose_json(p.x, p.y, 0.05, 0.0),
                "size": {"x": g.res, "y": g.res, "z": g.res}, "color": c
            }));
        }
    }
    entity(time_s, "frontiers", spheres, Vec::new())
}

/// `/plan/path`: the A* path of a `Follow` action as a line strip (empty for other actions).
pub fn path_message(time_s: f64, action: &Action) -> Value {
    let points: Vec<Value> = match action {
        Action::Follow { path, .. } => path
            .iter()
            .map(|p| json!({"x": p.x, "y": p.y, "z": 0.05}))
            .collect(),
        _ => Vec::new(),
    };
    let line = line_strip(&points, palette::PLAN_PATH, 0.05);
    entity(time_s, "astar_path", Vec::new(), vec![line])
}

/// `/plan/tour`: the planner's tour (THP: anchors and groups in TSP order; NBV-TSP: viewpoints in GA
/// order) as a line strip in the palette's tour colour with a sphere per stop, the first one larger. Empty without a tour.
pub fn tour_message(time_s: f64, tour: &[Point2<f64>]) -> Value {
    let orange = colour(palette::TOUR);
    let spheres = tour
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let size = if k == 0 { 0.35 } else { 0.2 };
            json!({
                "pose": pose_json(p.x, p.y, 0.1, 0.0),
                "size": {"x": size, "y": size, "z": size}, "color": orange
            })
        })
        .collect();
    let points: Vec<Value> = tour
        .iter()
        .map(|p| json!({"x": p.x, "y": p.y, "z": 0.1}))
        .collect();
    let line = line_strip(&points, palette::TOUR, 0.04);
    entity(time_s, "tour", spheres, vec![line])
}

/// `/metrics`: the step's metrics; `stage_ms` is wall-clock and not compared by `--verify`.
pub fn metrics_message(view: &StepView) -> Value {
    let stage_ms: BTreeMap<&str, f64> = STAGES.iter().copied().zip(view.stage_ms).collect();
    json!({
        "step": view.step, "time_s": view.time_s, "completeness": view.completeness,
        "explored_volume_m3": view.explored_volume_m3, "path_length_m": view.path_length_m,
        "collisions": view.collisions, "replans": view.replans, "stage_ms": stage_ms
    })
}

impl<S: Sink> Observer for Recorder<S> {
    /// Every message carries the simulated time of the state it shows. A step senses at its start
    /// (`sensed_time_s`, pose `sensed_pose`) and moves the robot by its end (`time_s`): the depth
    /// frame, the map key frame and the field it was built from are stamped with the former; pose,
    /// `/tf`, trajectory and metrics (path length, collisions, completeness as known then) with
    /// the latter. Messages are put in time order, so a live viewer sees stamps that never go back.
    fn on_step(&mut self, view: &StepView) {
        let sensed = view.sensed_time_s;
        if let Some(scene) = self.scene.take() {
            // Once, at the first step: the scene mesh, the robot's footprint (frame-locked to
            // `base_link`, so it follows `/tf`) and the start pose, where the first frame was taken.
            self.put(&topics::SCENE, sensed, &scene);
            let footprint = footprint_message(sensed, self.robot_radius_m, self.robot_height_m);
            self.put(&topics::ROBOT, sensed, &footprint);
            self.put_pose(sensed, view.sensed_pose, view.sensed_true_pose);
        }
        if let Some(frame) = view.frame {
            let n = self.cfg.depth_every_n;
            if n > 0 && self.frames_seen.is_multiple_of(n) {
                self.put(&topics::DEPTH, sensed, &depth_message(sensed, frame));
                let calibration = calibration_message(sensed, &self.camera);
                self.put(&topics::CAMERA_INFO, sensed, &calibration);
            }
            self.frames_seen += 1;
        }
        let key_frame = sensed + 1e-9 >= self.next_key_frame_s;
        if key_frame {
            self.put(&topics::MAP_GRID, sensed, &grid_message(sensed, view.map));
            if self.cfg.field {
                // The planner's own field when it has one (what THP and TENSOR steer by, path
                // constraints included); else one built here from the map.
                let field = match view.field {
                    Some(f) => Some(f),
                    None => {
                        let (cfg, map, range_m) = (&self.field_cfg, view.map, self.field_range_m);
                        let own = self.field.get_or_insert_with(|| {
                            TensorField::new(*map.grid(), cfg).with_range(range_m)
                        });
                        // The field's grid is the map's, so update cannot fail on a grid mismatch.
                        own.update(map).is_ok().then_some(&*own)
                    }
                };
                if let Some(field) = field {
                    let tensor = field_tensor_message(sensed, field);
                    let degenerate = degenerate_message(sensed, field);
                    let topology = topology_message(sensed, field);
                    self.put(&topics::FIELD_TENSOR, sensed, &tensor);
                    self.put(&topics::FIELD_DEGENERATE, sensed, &degenerate);
                    self.put(&topics::FIELD_TOPOLOGY, sensed, &topology);
                }
            }
            while self.next_key_frame_s <= sensed + 1e-9 {
                self.next_key_frame_s += self.cfg.map_every_s;
            }
        }
        self.put_pose(view.time_s, view.pose, view.true_pose);
        if key_frame {
            let trajectory = trajectory_message(view.time_s, &self.trajectory);
            self.put(&topics::TRAJECTORY, view.time_s, &trajectory);
        }
        self.put(&topics::METRICS, view.time_s, &metrics_message(view));
    }

    fn on_plan(&mut self, time_s: f64, action: &Action, map: &Map, tour: &[Point2<f64>]) {
        self.put(
            &topics::PLAN_FRONTIERS,
            time_s,
            &frontiers_message(time_s, map),
        );
        self.put(&topics::PLAN_PATH, time_s, &path_message(time_s, action));
        self.put(&topics::PLAN_TOUR, time_s, &tour_message(time_s, tour));
    }

    fn on_finish(&mut self, result: &RunResult) {
        self.sink.finish(result);
    }

    fn stop_requested(&self) -> bool {
        self.stop
            .as_ref()
            .is_some_and(|s| s.load(Ordering::Relaxed))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_quaternion_and_stamp() {
        let v = pose_message(1.5, Pose2::new(1.0, 2.0, std::f64::consts::PI));
        assert_eq!(v["timestamp"]["sec"], 1);
        assert_eq!(v["timestamp"]["nsec"], 500_000_000);
        assert!((v["pose"]["orientation"]["z"].as_f64().unwrap() - 1.0).abs() < 1e-12);
        assert!(v["pose"]["orientation"]["w"].as_f64().unwrap().abs() < 1e-12);
        assert_eq!(time_ns(270.4), 270_400_000_000);
    }

    #[test]
    fn rounded_floats_keep_three_digits_and_exact_zeros() {
        for v in [0.0, 1.0, -1.0, 0.123456, -3.5e-7, 12345.678] {
            let r = f64::from(round_f32(v));
            assert!((r - v).abs() <= v.abs() * 2f64.powi(-11), "{v} -> {r}");
        }
        assert_eq!(round_f32(0.0), 0.0);
        assert_eq!(round_f32(0.75), 0.75);
        assert_eq!(round_f32(1.0 + 2f64.powi(-20)), 1.0);
    }

    #[test]
    fn trajectory_keeps_corners_and_drops_collinear_points() {
        let mut t = Trajectory::default();
        for k in 0..=10 {
            t.push([k as f64 * 0.1, 0.0]);
        }
        for k in 1..=10 {
            t.push([1.0, k as f64 * 0.1]);
        }
        let pts: Vec<[f64; 2]> = t.points().copied().collect();
        assert_eq!(pts.len(), 3, "{pts:?}");
        assert!((pts[1][0] - 1.0).abs() < 1e-12 && pts[1][1].abs() < 1e-12);
        assert!((pts[2][1] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn optical_frame_looks_along_base_link_x() {
        // Rotate the optical z axis (0, 0, 1) by OPTICAL_ROTATION: it must become base_link's +x,
        // and the optical y axis (image down) must become −z.
        let [x, y, z, w] = OPTICAL_ROTATION;
        let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
        let fwd = q * nalgebra::Vector3::z();
        let down = q * nalgebra::Vector3::y();
        assert!((fwd - nalgebra::Vector3::x()).norm() < 1e-12);
        assert!((down + nalgebra::Vector3::z()).norm() < 1e-12);
    }

    #[test]
    fn depth_is_16uc1_millimetres() {
        assert_eq!(depth_mm(0.0), 0);
        assert_eq!(depth_mm(1.2344), 1234);
        assert_eq!(depth_mm(1.2346), 1235);
        assert_eq!(depth_mm(5.0), 5000);
        assert_eq!(depth_mm(99.0), u16::MAX);
        // A real frame: a camera 2 m in front of a wall that fills its view sees it at 2000 mm.
        let cfg = crate::Config::default().camera;
        let mut wall = crate::scene::TriMesh::default();
        crate::sensor::raycast::testing::push_box(
            &mut wall,
            [2.0, -50.0, -50.0],
            [2.1, 50.0, 50.0],
        );
        let bvh = crate::sensor::MeshBvh::new(&wall).unwrap();
        let frame = crate::sensor::DepthCamera::new(&cfg).capture(&bvh, Pose2::new(0.0, 0.0, 0.0));
        let v = depth_message(0.0, &frame);
        assert_eq!(v["encoding"], "16UC1");
        assert_eq!(v["step"], cfg.width * 2);
        let data = crate::util::base64_decode(v["data"].as_str().unwrap()).unwrap();
        assert_eq!(data.len(), cfg.width * cfg.height * 2);
        let px: Vec<u16> = data
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect();
        let depth = frame.depth_image();
        assert!(px.iter().zip(&depth).all(|(&p, &d)| p == depth_mm(d)));
        assert!(px.iter().all(|&p| p.abs_diff(2000) <= 1), "{:?}", &px[..8]);
    }

    #[test]
    fn intrinsics_match_the_ray_directions() {
        let cam = crate::Config::default().camera;
        let [fx, fy, cx, cy] = intrinsics(&cam);
        let c = crate::sensor::DepthCamera::new(&cam);
        // Ray (col, row) in the optical frame is ((col − cx)/fx, (row − cy)/fy, 1), normalised; the
        // camera's own directions are (forward, left, up) = (1, −right, −down).
        for (col, row) in [(0, 0), (cam.width - 1, 7), (13, cam.height - 1)] {
            let d = c.camera_dirs()[row * cam.width + col].cast::<f64>();
            let right = (col as f64 - cx) / fx;
            let down = (row as f64 - cy) / fy;
            let expect = nalgebra::Vector3::new(1.0, -right, -down).normalize();
            assert!(
                (d - expect).norm() < 1e-6,
                "{col},{row}: {d:?} vs {expect:?}"
            );
        }
    }
}
