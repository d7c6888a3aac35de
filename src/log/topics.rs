//! The topic registry: every channel a run log can hold, its schema name and JSON schema.
//! Adding a topic is one `Topic` constant here, one entry in [`TOPICS`] and one builder function in
//! `record.rs`. Every `foxglove.*` channel carries Foxglove's official JSON schema of its name, whole (vendored in
//! `assets/foxglove-schemas/`); `/metrics` carries a schema of ours.

/// One channel of the log.
#[derive(Debug)]
pub struct Topic {
    pub name: &'static str,
    /// Foxglove well-known schema name, or ours for `/metrics`.
    pub schema_name: &'static str,
    pub schema_json: &'static str,
    /// Whether `replay --verify` compares it (all but wall-clock fields are deterministic).
    pub verified: bool,
}

macro_rules! schema {
    ($title:literal, $props:literal) => {
        concat!(
            r#"{"title":""#,
            $title,
            r#"","type":"object","properties":"#,
            $props,
            "}"
        )
    };
}

/// Foxglove's official JSON schema named `foxglove.$name`, whole, from the vendored
/// `@foxglove/schemas` 2.1.0 files in `assets/foxglove-schemas/` (MIT).
macro_rules! foxglove_schema {
    ($name:literal) => {
        include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/assets/foxglove-schemas/",
            $name,
            ".json"
        ))
    };
}

const POSE_IN_FRAME_SCHEMA: &str = foxglove_schema!("PoseInFrame");
const RAW_IMAGE_SCHEMA: &str = foxglove_schema!("RawImage");
const GRID_SCHEMA: &str = foxglove_schema!("Grid");
const SCENE_UPDATE_SCHEMA: &str = foxglove_schema!("SceneUpdate");
const FRAME_TRANSFORMS_SCHEMA: &str = foxglove_schema!("FrameTransforms");
const CAMERA_CALIBRATION_SCHEMA: &str = foxglove_schema!("CameraCalibration");

pub const POSE: Topic = Topic {
    name: "/robot/pose",
    schema_name: "foxglove.PoseInFrame",
    schema_json: POSE_IN_FRAME_SCHEMA,
    verified: true,
};

/// `world → base_link` every step and the fixed `base_link → camera` (optical frame) with it.
pub const TF: Topic = Topic {
    name: "/tf",
    schema_name: "foxglove.FrameTransforms",
    schema_json: FRAME_TRANSFORMS_SCHEMA,
    verified: true,
};

pub const DEPTH: Topic = Topic {
    name: "/camera/depth",
    schema_name: "foxglove.RawImage",
    schema_json: RAW_IMAGE_SCHEMA,
    verified: true,
};

/// The depth camera's pinhole model, with every depth image.
pub const CAMERA_INFO: Topic = Topic {
    name: "/camera/calibration",
    schema_name: "foxglove.CameraCalibration",
    schema_json: CAMERA_CALIBRATION_SCHEMA,
    verified: true,
};

pub const MAP_GRID: Topic = Topic {
    name: "/map/grid",
    schema_name: "foxglove.Grid",
    schema_json: GRID_SCHEMA,
    verified: true,
};

/// The scene mesh, once, as a faint triangle list in `world`.
pub const SCENE: Topic = Topic {
    name: "/scene",
    schema_name: "foxglove.SceneUpdate",
    schema_json: SCENE_UPDATE_SCHEMA,
    verified: true,
};

/// The robot's footprint (a disc in `base_link`) and the travelled trajectory (a line in `world`).
pub const ROBOT: Topic = Topic {
    name: "/robot/footprint",
    schema_name: "foxglove.SceneUpdate",
    schema_json: SCENE_UPDATE_SCHEMA,
    verified: true,
};

pub const TRAJECTORY: Topic = Topic {
    name: "/robot/trajectory",
    schema_name: "foxglove.SceneUpdate",
    schema_json: SCENE_UPDATE_SCHEMA,
    verified: true,
};

pub const PLAN_FRONTIERS: Topic = Topic {
    name: "/plan/frontiers",
    schema_name: "foxglove.SceneUpdate",
    schema_json: SCENE_UPDATE_SCHEMA,
    verified: true,
};

pub const PLAN_PATH: Topic = Topic {
    name: "/plan/path",
    schema_name: "foxglove.SceneUpdate",
    schema_json: SCENE_UPDATE_SCHEMA,
    verified: true,
};

pub const PLAN_TOUR: Topic = Topic {
    name: "/plan/tour",
    schema_name: "foxglove.SceneUpdate",
    schema_json: SCENE_UPDATE_SCHEMA,
    verified: true,
};

pub const FIELD_TENSOR: Topic = Topic {
    name: "/field/tensor",
    schema_name: "foxglove.Grid",
    schema_json: GRID_SCHEMA,
    verified: true,
};

pub const FIELD_DEGENERATE: Topic = Topic {
    name: "/field/degenerate",
    schema_name: "foxglove.SceneUpdate",
    schema_json: SCENE_UPDATE_SCHEMA,
    verified: true,
};

pub const FIELD_TOPOLOGY: Topic = Topic {
    name: "/field/topology",
    schema_name: "foxglove.SceneUpdate",
    schema_json: SCENE_UPDATE_SCHEMA,
    verified: true,
};

pub const METRICS: Topic = Topic {
    name: "/metrics",
    schema_name: "tensorscout.Metrics",
    schema_json: schema!(
        "tensorscout.Metrics",
        r#"{"step":{"type":"integer"},"time_s":{"type":"number"},"completeness":{"type":"number"},"explored_volume_m3":{"type":"number"},"path_length_m":{"type":"number"},"collisions":{"type":"integer"},"replans":{"type":"integer"},"stage_ms":{"type":"object","description":"wall-clock milliseconds per stage; not deterministic","additionalProperties":{"type":"number"}}}"#
    ),
    verified: true,
};

/// Every topic, in channel-id order.
pub const TOPICS: [&Topic; 15] = [
    &POSE,
    &TF,
    &ROBOT,
    &TRAJECTORY,
    &SCENE,
    &DEPTH,
    &CAMERA_INFO,
    &MAP_GRID,
    &FIELD_TENSOR,
    &FIELD_DEGENERATE,
    &FIELD_TOPOLOGY,
    &PLAN_FRONTIERS,
    &PLAN_PATH,
    &PLAN_TOUR,
    &METRICS,
];

/// The registry entry named `name`.
#[cfg(test)]
pub fn by_name(name: &str) -> Option<&'static Topic> {
    TOPICS.iter().copied().find(|t| t.name == name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schemas_are_valid_json_and_names_unique() {
        for t in TOPICS {
            let v: serde_json::Value = serde_json::from_str(t.schema_json).unwrap();
            assert_eq!(v["title"], t.schema_name, "{}", t.name);
            assert_eq!(by_name(t.name).unwrap().name, t.name);
        }
        let mut names: Vec<_> = TOPICS.iter().map(|t| t.name).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), TOPICS.len());
    }

    #[test]
    fn foxglove_layout_names_only_logged_topics() {
        let layout: serde_json::Value = serde_json::from_str(include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/assets/foxglove-layout.json"
        )))
        .unwrap();
        let panels = layout["configById"].as_object().unwrap();
        let three_d = &panels["3D!tensorscout"]["topics"];
        for t in three_d.as_object().unwrap().keys() {
            assert!(by_name(t).is_some(), "layout topic {t} is not logged");
        }
        for t in ["/scene", "/tf", "/field/tensor", "/plan/tour"] {
            assert!(by_name(t).is_some());
        }
        let image = &panels["Image!tensorscoutdepth"]["imageMode"];
        assert_eq!(image["imageTopic"], DEPTH.name);
        assert_eq!(image["calibrationTopic"], CAMERA_INFO.name);
        assert_eq!(panels["3D!tensorscout"]["followTf"], "base_link");
    }
}
