//! Turns simulator state into log messages (JSON bytes), one builder function per topic; the same
//! code feeds the file writer and `replay --verify`, so a re-run is compared byte for byte.

use super::topics::{self, Topic};
use crate::config::{Config, FieldConfig, LogConfig};
use crate::field::{DegenerateKind, TensorField};
use crate::map::{CellState, Map};
use crate::plan::Action;
use crate::sim::metrics::STAGES;
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

/// An [`Observer`] that builds every topic's messages at the configured rates.
pub struct Recorder<S: Sink> {
    pub sink: S,
    cfg: LogConfig,
    field_cfg: FieldConfig,
    /// Built at the first key frame when `log.field` is on (GREEDY has no field of its own).
    field: Option<TensorField>,
    frames_seen: u64,
    next_key_frame_s: f64,
    stop: Option<Arc<AtomicBool>>,
}

impl<S: Sink> Recorder<S> {
    pub fn new(sink: S, cfg: &Config, stop: Option<Arc<AtomicBool>>) -> Self {
        Recorder {
            sink,
            cfg: cfg.log.clone(),
            field_cfg: cfg.field.clone(),
            field: None,
            frames_seen: 0,
            next_key_frame_s: 0.0,
            stop,
        }
    }

    fn put(&mut self, topic: &'static Topic, time_s: f64, message: &Value) {
        let bytes = serde_json::to_vec(message).expect("JSON values serialise");
        self.sink.put(topic, time_ns(time_s), bytes);
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

/// `/camera/depth`: 32FC1 depth along the optical axis, metres (0 = no return).
pub fn depth_message(time_s: f64, frame: &crate::sensor::DepthFrame) -> Value {
    let bytes: Vec<u8> = frame
        .depth_image()
        .iter()
        .flat_map(|d| d.to_le_bytes())
        .collect();
    json!({
        "timestamp": stamp(time_s), "frame_id": "camera",
        "width": frame.width, "height": frame.height, "encoding": "32FC1",
        "step": frame.width * 4, "data": super::base64_encode(&bytes)
    })
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
        "data": super::base64_encode(&data)
    })
}

/// `/field/tensor`: the field's `a`, `b` (tensor components) and constraint weight as float32.
pub fn field_tensor_message(time_s: f64, field: &TensorField) -> Value {
    let f = field.field();
    let g = f.spec;
    let mut data = Vec::with_capacity(g.cells() * 12);
    for i in 0..g.cells() {
        for v in [f.ab[i][0], f.ab[i][1], f.weight[i]] {
            data.extend_from_slice(&(v as f32).to_le_bytes());
        }
    }
    json!({
        "timestamp": stamp(time_s), "frame_id": "world",
        "pose": pose_json(g.origin_x, g.origin_y, 0.0, 0.0),
        "column_count": g.nx, "cell_size": {"x": g.res, "y": g.res},
        "row_stride": g.nx * 12, "cell_stride": 12,
        "fields": [{"name": "a", "offset": 0, "type": 7}, {"name": "b", "offset": 4, "type": 7},
                   {"name": "weight", "offset": 8, "type": 7}],
        "data": super::base64_encode(&data)
    })
}

/// `/field/degenerate`: one sphere per degenerate point, wedges green, trisectors red, others grey.
pub fn degenerate_message(time_s: f64, field: &TensorField) -> Value {
    let spheres = field
        .points()
        .iter()
        .map(|p| {
            let c = match p.kind {
                DegenerateKind::Wedge => [40, 180, 60],
                DegenerateKind::Trisector => [220, 40, 40],
                _ => [120, 120, 120],
            };
            json!({"pose": pose_json(p.x, p.y, 0.3, 0.0), "size": {"x": 0.3, "y": 0.3, "z": 0.3}, "color": colour(c)})
        })
        .collect();
    entity(time_s, "degenerate_points", spheres, Vec::new())
}

/// `/field/topology`: separatrices as grey line strips and topology-graph edges as blue ones (each
/// edge is a traced separatrix or a shortest-path pairing between two points).
pub fn topology_message(time_s: f64, field: &TensorField) -> Value {
    let strip = |polyline: &[[f64; 2]], c: [u8; 3], thickness: f64| {
        let points: Vec<Value> = polyline
            .iter()
            .map(|p| json!({"x": p[0], "y": p[1], "z": 0.2}))
            .collect();
        json!({
            "type": 0, "pose": pose_json(0.0, 0.0, 0.0, 0.0), "thickness": thickness,
            "scale_invariant": false, "points": points, "color": colour(c),
            "colors": [], "indices": []
        })
    };
    let graph = field.graph();
    let lines = graph
        .separatrices
        .iter()
        .map(|s| strip(&s.polyline, [150, 150, 150], 0.03))
        .chain(
            graph
                .edges
                .iter()
                .map(|e| strip(&e.polyline, [40, 90, 220], 0.06)),
        )
        .collect();
    entity(time_s, "topology", Vec::new(), lines)
}

/// A distinct colour per frontier group (cycled).
pub const GROUP_COLOURS: [[u8; 3]; 8] = [
    [230, 25, 75],
    [60, 180, 75],
    [0, 130, 200],
    [245, 130, 48],
    [145, 30, 180],
    [70, 240, 240],
    [240, 50, 230],
    [128, 128, 0],
];

fn colour(c: [u8; 3]) -> Value {
    json!({"r": f64::from(c[0]) / 255.0, "g": f64::from(c[1]) / 255.0, "b": f64::from(c[2]) / 255.0, "a": 1.0})
}

fn entity(time_s: f64, id: &str, spheres: Vec<Value>, lines: Vec<Value>) -> Value {
    json!({"deletions": [], "entities": [{
        "timestamp": stamp(time_s), "frame_id": "world", "id": id,
        "lifetime": {"sec": 0, "nsec": 0}, "frame_locked": false, "metadata": [],
        "arrows": [], "cubes": [], "spheres": spheres, "cylinders": [], "lines": lines,
        "triangles": [], "texts": [], "models": []
    }]})
}

/// `/plan/frontiers`: one sphere per frontier cell, coloured by its group (segment).
pub fn frontiers_message(time_s: f64, map: &Map) -> Value {
    let g = map.grid();
    let mut spheres = Vec::new();
    for (group, seg) in map.frontiers().iter().enumerate() {
        let c = colour(GROUP_COLOURS[group % GROUP_COLOURS.len()]);
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
    let line = json!({
        "type": 0, "pose": pose_json(0.0, 0.0, 0.0, 0.0), "thickness": 0.05,
        "scale_invariant": false, "points": points, "color": colour([30, 90, 220]),
        "colors": [], "indices": []
    });
    entity(time_s, "astar_path", Vec::new(), vec![line])
}

/// `/plan/tour`: the planner's tour (THP: anchors and groups in TSP order; NBV-TSP: viewpoints in GA
/// order) as an orange line strip with a sphere per stop, the first one larger. Empty without a tour.
pub fn tour_message(time_s: f64, tour: &[Point2<f64>]) -> Value {
    let orange = colour([245, 130, 48]);
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
    let line = json!({
        "type": 0, "pose": pose_json(0.0, 0.0, 0.0, 0.0), "thickness": 0.04,
        "scale_invariant": false, "points": points, "color": orange,
        "colors": [], "indices": []
    });
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
    fn on_step(&mut self, view: &StepView) {
        self.put(
            &topics::POSE,
            view.time_s,
            &pose_message(view.time_s, view.pose),
        );
        if let Some(frame) = view.frame {
            let n = self.cfg.depth_every_n;
            if n > 0 && self.frames_seen.is_multiple_of(n) {
                self.put(
                    &topics::DEPTH,
                    view.time_s,
                    &depth_message(view.time_s, frame),
                );
            }
            self.frames_seen += 1;
        }
        if view.time_s + 1e-9 >= self.next_key_frame_s {
            self.put(
                &topics::MAP_GRID,
                view.time_s,
                &grid_message(view.time_s, view.map),
            );
            if self.cfg.field {
                // The planner's own field when it has one (what THP and TENSOR steer by, path
                // constraints included); else one built here from the map.
                let field = match view.field {
                    Some(f) => Some(f),
                    None => {
                        let (cfg, map) = (&self.field_cfg, view.map);
                        let own = self
                            .field
                            .get_or_insert_with(|| TensorField::new(*map.grid(), cfg));
                        // The field's grid is the map's, so update cannot fail on a grid mismatch.
                        own.update(map).is_ok().then_some(&*own)
                    }
                };
                if let Some(field) = field {
                    let tensor = field_tensor_message(view.time_s, field);
                    let degenerate = degenerate_message(view.time_s, field);
                    let topology = topology_message(view.time_s, field);
                    self.put(&topics::FIELD_TENSOR, view.time_s, &tensor);
                    self.put(&topics::FIELD_DEGENERATE, view.time_s, &degenerate);
                    self.put(&topics::FIELD_TOPOLOGY, view.time_s, &topology);
                }
            }
            while self.next_key_frame_s <= view.time_s + 1e-9 {
                self.next_key_frame_s += self.cfg.map_every_s;
            }
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
}
