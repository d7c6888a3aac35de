//! The map: 3D occupancy voxels and the 2D layers derived from them.

pub mod occupancy;
