//! Evaluation: what a run is measured against and how. The ground truth's reachable region, the
//! observable set (what the camera could ever see from that region, and its disk cache) and the
//! metrics (completeness, surface coverage, what is left unseen, the map's quality against the
//! truth). It sits between `map` and `sim`:
//! it reuses the map's sensor model and voxel traversal, and the simulator calls it every step.

pub(crate) mod ground_truth;
pub(crate) mod map_quality;
pub(crate) mod metrics;
pub mod observable;
pub(crate) mod reachable;

pub use ground_truth::{
    build_ground_truth, build_ground_truth_for_start, info, GroundTruth, SceneInfo,
};
pub use map_quality::{map_quality, MapQuality};
pub use metrics::{
    frontiers_left, surface_coverage, unseen_patches, ExploredVolume, FrontierGroup, FrontiersLeft,
    UnseenPatch, FRONTIER_GROUPS, UNSEEN_PATCHES,
};
pub use observable::{
    CacheOutcome, ObservableCache, ObservableParams, ObservableSet, SampleProgress,
};
