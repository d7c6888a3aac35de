//! The depth camera: a pinhole model whose frames are rendered from the scene mesh by rasterisation
//! (the default) or by casting one ray per pixel into the mesh's BVH (the reference, and the
//! collision queries), and the depth noise of a real camera (`noise`).

pub(crate) mod camera;
pub(crate) mod noise;
pub(crate) mod raster;
pub mod raycast;

pub use camera::{DepthCamera, DepthFrame};
pub use noise::DepthNoise;
pub use raster::MeshRaster;
pub use raycast::MeshBvh;
