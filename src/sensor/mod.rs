//! The depth camera: a pinhole model whose rays are cast into the scene mesh's BVH.

pub mod camera;
pub mod raycast;

pub use camera::{DepthCamera, DepthFrame};
pub use raycast::MeshBvh;
