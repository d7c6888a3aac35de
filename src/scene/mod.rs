//! Scenes: mesh loading, importers, the generator and the ground truth.

pub mod mesh;
pub use mesh::TriMesh;
