//! The topic registry: every channel a run log can hold, its schema name and JSON schema.
//! Adding a topic is one `Topic` constant here, one entry in [`TOPICS`] and one builder function in
//! `record.rs`. Schemas follow Foxglove's published JSON schemas (trimmed to the fields we write).

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

pub const POSE: Topic = Topic {
    name: "/robot/pose",
    schema_name: "foxglove.PoseInFrame",
    schema_json: schema!(
        "foxglove.PoseInFrame",
        r#"{"timestamp":{"type":"object","properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}},"frame_id":{"type":"string"},"pose":{"type":"object","properties":{"position":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}},"orientation":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}}}}}"#
    ),
    verified: true,
};

pub const DEPTH: Topic = Topic {
    name: "/camera/depth",
    schema_name: "foxglove.RawImage",
    schema_json: schema!(
        "foxglove.RawImage",
        r#"{"timestamp":{"type":"object","properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}},"frame_id":{"type":"string"},"width":{"type":"integer"},"height":{"type":"integer"},"encoding":{"type":"string"},"step":{"type":"integer"},"data":{"type":"string","contentEncoding":"base64"}}"#
    ),
    verified: true,
};

const GRID_SCHEMA: &str = schema!(
    "foxglove.Grid",
    r#"{"timestamp":{"type":"object","properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}},"frame_id":{"type":"string"},"pose":{"type":"object","properties":{"position":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}},"orientation":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}}}},"column_count":{"type":"integer"},"cell_size":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"}}},"row_stride":{"type":"integer"},"cell_stride":{"type":"integer"},"fields":{"type":"array","items":{"type":"object","properties":{"name":{"type":"string"},"offset":{"type":"integer"},"type":{"type":"integer"}}}},"data":{"type":"string","contentEncoding":"base64"}}"#
);

pub const MAP_GRID: Topic = Topic {
    name: "/map/grid",
    schema_name: "foxglove.Grid",
    schema_json: GRID_SCHEMA,
    verified: true,
};

const SCENE_UPDATE_SCHEMA: &str = schema!(
    "foxglove.SceneUpdate",
    r#"{"deletions":{"type":"array","items":{"type":"object"}},"entities":{"type":"array","items":{"type":"object","properties":{"timestamp":{"type":"object"},"frame_id":{"type":"string"},"id":{"type":"string"},"lifetime":{"type":"object"},"frame_locked":{"type":"boolean"},"metadata":{"type":"array"},"arrows":{"type":"array"},"cubes":{"type":"array"},"spheres":{"type":"array"},"cylinders":{"type":"array"},"lines":{"type":"array"},"triangles":{"type":"array"},"texts":{"type":"array"},"models":{"type":"array"}}}}}"#
);

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
pub const TOPICS: [&Topic; 10] = [
    &POSE,
    &DEPTH,
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
}
