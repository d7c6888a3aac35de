//! The forward-facing pinhole depth camera: one ray per pixel centre, cast into the scene mesh or
//! rendered by rasterisation along the same rays.

use super::raster::{MeshRaster, RasterCamera};
use super::raycast::MeshBvh;
use crate::config::CameraConfig;
use crate::Pose2;
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

/// A depth camera mounted on the robot, looking along its heading with a horizontal optical axis.
#[derive(Clone, Debug)]
pub struct DepthCamera {
    width: usize,
    height: usize,
    mount_height: f32,
    min_range: f32,
    max_range: f32,
    /// Tangents of the half fields of view (horizontal, vertical).
    tan_h: f32,
    tan_v: f32,
    /// Unit ray directions in the camera frame (x forward, y left, z up), row-major from the top row.
    /// Computed once: through the centres of the pixels of a pinhole image plane, so they are evenly
    /// spaced in tangent, not in angle.
    cam_dirs: Vec<Vector3<f32>>,
}

/// One depth frame: the rays of one capture, in the world frame.
#[derive(Clone, Debug, Default)]
pub struct DepthFrame {
    /// Optical centre in the world.
    pub origin: Point3<f32>,
    /// Unit optical axis in the world (horizontal, along the robot's heading).
    pub axis: Vector3<f32>,
    /// Unit ray directions in the world, row-major from the top row.
    pub dirs: Vec<Vector3<f32>>,
    /// Distance along each ray to the first hit, metres; `f32::INFINITY` = no hit within `max_range`;
    /// `NaN` = invalid (a hit nearer than the camera's minimum range: no reading, not integrated).
    pub range: Vec<f32>,
    pub width: usize,
    pub height: usize,
    /// The camera's maximum range, metres: a ray with no hit marks free space up to it.
    pub max_range: f32,
}

impl DepthCamera {
    /// Builds the camera from a validated config.
    pub fn new(cfg: &CameraConfig) -> DepthCamera {
        let (w, h) = (cfg.width, cfg.height);
        let tan_h = (cfg.hfov_deg.to_radians() / 2.0).tan();
        let tan_v = (cfg.vfov_deg.to_radians() / 2.0).tan();
        let mut cam_dirs = Vec::with_capacity(w * h);
        for row in 0..h {
            // Image-plane coordinates at unit focal distance: +right and +down, in [-tan, tan].
            let down = ((row as f64 + 0.5) / h as f64 * 2.0 - 1.0) * tan_v;
            for col in 0..w {
                let right = ((col as f64 + 0.5) / w as f64 * 2.0 - 1.0) * tan_h;
                let d = Vector3::new(1.0, -right, -down).normalize();
                cam_dirs.push(d.cast::<f32>());
            }
        }
        DepthCamera {
            width: w,
            height: h,
            mount_height: cfg.mount_height_m.get() as f32,
            min_range: cfg.min_range_m.get() as f32,
            max_range: cfg.max_range_m.get() as f32,
            tan_h: tan_h as f32,
            tan_v: tan_v as f32,
            cam_dirs,
        }
    }

    /// Height of the optical centre above the floor, metres.
    pub fn mount_height(&self) -> f32 {
        self.mount_height
    }

    /// Nearest and farthest depth, metres (a nearer hit gives no reading).
    pub fn range_limits(&self) -> (f32, f32) {
        (self.min_range, self.max_range)
    }

    /// Image size in pixels: (width, height).
    pub fn image_size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Number of rays per frame.
    pub fn rays(&self) -> usize {
        self.width * self.height
    }

    /// Unit ray directions in the camera frame (x forward, y left, z up), row-major from the top row.
    pub fn camera_dirs(&self) -> &[Vector3<f32>] {
        &self.cam_dirs
    }

    /// Sets `frame`'s pose, size and range and sizes its buffers for a frame taken at `pose`; returns
    /// the optical centre and the sine and cosine of the heading.
    fn start_frame(&self, pose: Pose2, frame: &mut DepthFrame) -> (Point3<f32>, f32, f32) {
        let (sin, cos) = (pose.yaw.sin() as f32, pose.yaw.cos() as f32);
        let origin = Point3::new(pose.x as f32, pose.y as f32, self.mount_height);
        frame.origin = origin;
        frame.axis = Vector3::new(cos, sin, 0.0);
        frame.width = self.width;
        frame.height = self.height;
        frame.max_range = self.max_range;
        let n = self.rays();
        frame.dirs.resize(n, Vector3::zeros());
        frame.range.resize(n, 0.0);
        (origin, sin, cos)
    }

    /// Captures one frame from the robot at `pose`.
    pub fn capture(&self, bvh: &MeshBvh, pose: Pose2) -> DepthFrame {
        let mut frame = DepthFrame::default();
        self.capture_into(bvh, pose, &mut frame);
        frame
    }

    /// Captures into `frame`, reusing its buffers. Rays are cast in parallel; each ray's result depends
    /// only on the ray, so the frame is the same whatever the thread count.
    pub fn capture_into(&self, bvh: &MeshBvh, pose: Pose2, frame: &mut DepthFrame) {
        let (origin, sin, cos) = self.start_frame(pose, frame);
        let (min_range, max_range) = (self.min_range, self.max_range);
        frame
            .dirs
            .par_iter_mut()
            .zip(frame.range.par_iter_mut())
            .zip(self.cam_dirs.par_iter())
            .with_min_len(256)
            .for_each(|((dir, range), c)| {
                *dir = world_dir(cos, sin, c);
                *range = match bvh.cast(origin, *dir, max_range) {
                    None => f32::INFINITY,
                    Some(d) if d < min_range => f32::NAN,
                    Some(d) => d,
                };
            });
    }

    /// Renders a frame from the robot at `pose` by rasterising `raster`'s mesh (see
    /// [`super::raster`]): the same rays, distances and range rule as [`DepthCamera::capture`].
    pub fn render(&self, raster: &MeshRaster, pose: Pose2) -> DepthFrame {
        let mut frame = DepthFrame::default();
        self.render_into(raster, pose, &mut frame);
        frame
    }

    /// [`DepthCamera::render`] into `frame`, reusing its buffers. The frame does not depend on the
    /// thread count.
    pub fn render_into(&self, raster: &MeshRaster, pose: Pose2, frame: &mut DepthFrame) {
        let (origin, sin, cos) = self.start_frame(pose, frame);
        let turn = |(dir, c): (&mut Vector3<f32>, &Vector3<f32>)| *dir = world_dir(cos, sin, c);
        // On one thread, in this one: handing the rays to a pool's worker and waiting costs wakeups.
        if rayon::current_num_threads() > 1 {
            (frame.dirs.par_iter_mut())
                .zip(self.cam_dirs.par_iter())
                .with_min_len(4096)
                .for_each(turn);
        } else {
            frame.dirs.iter_mut().zip(&self.cam_dirs).for_each(turn);
        }
        let cam = RasterCamera {
            width: self.width,
            height: self.height,
            tan_h: self.tan_h,
            tan_v: self.tan_v,
            max_range: self.max_range,
        };
        raster.render_ranges(
            &cam,
            parry3d::math::Vector::new(origin.x, origin.y, origin.z),
            (cos, sin),
            &frame.dirs,
            &mut frame.range,
        );
        let (min_range, max_range) = (self.min_range, self.max_range);
        let rule = |r: &mut f32| {
            *r = if *r >= max_range {
                f32::INFINITY
            } else if *r < min_range {
                f32::NAN
            } else {
                *r
            };
        };
        if rayon::current_num_threads() > 1 {
            frame.range.par_iter_mut().with_min_len(4096).for_each(rule);
        } else {
            frame.range.iter_mut().for_each(rule);
        }
    }
}

impl DepthCamera {
    /// Moves `frame` to `pose`, keeping its ranges: the frame as the robot believes it was taken,
    /// from its estimated pose, where the map integrates it.
    pub fn repose(&self, pose: Pose2, frame: &mut DepthFrame) {
        let (_, sin, cos) = self.start_frame(pose, frame);
        (frame.dirs.iter_mut())
            .zip(&self.cam_dirs)
            .for_each(|(dir, c)| *dir = world_dir(cos, sin, c));
    }
}

/// A camera-frame direction in the world, for a robot heading `(cos, sin)`: yaw only, a rotation
/// about z. The one formula both the caster and the rasteriser use, so their rays are the same.
#[inline(always)]
fn world_dir(cos: f32, sin: f32, c: &Vector3<f32>) -> Vector3<f32> {
    Vector3::new(cos * c.x - sin * c.y, sin * c.x + cos * c.y, c.z)
}

impl DepthFrame {
    /// Depth along the optical axis (z-depth), metres, row-major from the top row; 0 where there is no
    /// reading (no hit within range, or too near).
    pub fn depth_image(&self) -> Vec<f32> {
        self.dirs
            .iter()
            .zip(&self.range)
            .map(|(d, &r)| {
                if r.is_finite() {
                    r * d.dot(&self.axis)
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// How far ray `i` marks space as passed: its range, or `max_range` if it hit nothing; `None` for
    /// an invalid (NaN) reading, which is not integrated.
    #[inline]
    pub fn free_length(&self, i: usize) -> Option<f32> {
        let range = self.range[i];
        if range.is_nan() {
            None
        } else if range.is_finite() {
            Some(range)
        } else {
            Some(self.max_range)
        }
    }

    /// Number of rays.
    pub fn len(&self) -> usize {
        self.range.len()
    }

    /// Whether the frame has no rays.
    pub fn is_empty(&self) -> bool {
        self.range.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::super::raycast::testing::push_box;
    use super::*;
    use crate::scene::TriMesh;
    use crate::Config;

    fn camera(width: usize, height: usize) -> DepthCamera {
        let mut cfg = Config::default().camera;
        cfg.width = width;
        cfg.height = height;
        DepthCamera::new(&cfg)
    }

    #[test]
    fn centre_ray_is_along_the_heading_at_mount_height() {
        // Odd sizes put a pixel centre on the optical axis.
        let cam = camera(81, 61);
        let yaw = 0.7f64;
        let bvh = MeshBvh::new(&wall_mesh()).unwrap();
        let f = cam.capture(&bvh, Pose2::new(1.0, 2.0, yaw));
        let centre = f.dirs[30 * 81 + 40];
        assert!((centre.x - yaw.cos() as f32).abs() < 1e-6);
        assert!((centre.y - yaw.sin() as f32).abs() < 1e-6);
        assert!(centre.z.abs() < 1e-6);
        assert_eq!(f.origin, Point3::new(1.0, 2.0, 0.6));
        for d in &f.dirs {
            assert!((d.norm() - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn corner_rays_lie_half_a_pixel_inside_the_fov() {
        let cam = camera(80, 60);
        let d = cam.camera_dirs();
        let tan_h = (29.0f64).to_radians().tan();
        let tan_v = (22.5f64).to_radians().tan();
        // Top-left pixel: left (+y) and up (+z).
        let tl = d[0];
        assert!(((tl.y / tl.x) as f64 - tan_h * (1.0 - 1.0 / 80.0)).abs() < 1e-6);
        assert!(((tl.z / tl.x) as f64 - tan_v * (1.0 - 1.0 / 60.0)).abs() < 1e-6);
        // Bottom-right pixel: right (−y) and down (−z).
        let br = d[80 * 60 - 1];
        assert!(((br.y / br.x) as f64 + tan_h * (1.0 - 1.0 / 80.0)).abs() < 1e-6);
        assert!(((br.z / br.x) as f64 + tan_v * (1.0 - 1.0 / 60.0)).abs() < 1e-6);
        // Pinhole spacing is even in tangent, not in angle.
        let t = |i: usize| (d[i].y / d[i].x) as f64;
        let step = t(0) - t(1);
        assert!((t(40) - t(41) - step).abs() < 1e-6);
        let ang = |i: usize| (d[i].y / d[i].x).atan() as f64;
        assert!((ang(0) - ang(1)) < (ang(40) - ang(41)) - 1e-4);
    }

    /// A wall at x = 3 (2 m wide in y, 2 m high), and a post at x = 0.2 off to the left.
    fn wall_mesh() -> TriMesh {
        let mut m = TriMesh::default();
        push_box(&mut m, [3.0, -1.0, 0.0], [3.2, 1.0, 2.0]);
        m
    }

    #[test]
    fn wall_distances_no_hit_and_near_hit() {
        let cam = camera(81, 61);
        let bvh = MeshBvh::new(&wall_mesh()).unwrap();
        let f = cam.capture(&bvh, Pose2::new(0.0, 0.0, 0.0));
        let centre = 30 * 81 + 40;
        assert!((f.range[centre] - 3.0).abs() < 1e-5);
        let depth = f.depth_image();
        // Every ray hitting the wall face has z-depth 3.
        let mut hits = 0;
        for (i, &r) in f.range.iter().enumerate() {
            if r.is_finite() {
                hits += 1;
                assert!((depth[i] - 3.0).abs() < 1e-4, "{i}: {}", depth[i]);
            } else {
                assert_eq!(r, f32::INFINITY);
                assert_eq!(depth[i], 0.0);
            }
        }
        // The wall spans ±1 m at 3 m: tan 18.4° < tan 29°, so the outer columns miss it.
        assert!(hits > 0 && hits < f.len());
        assert_eq!(f.range[30 * 81], f32::INFINITY);
        // Looking away: nothing within 5 m.
        let f = cam.capture(&bvh, Pose2::new(0.0, 0.0, std::f64::consts::PI));
        assert!(f.range.iter().all(|&r| r == f32::INFINITY));
        // Right in front of the wall: every ray that hits does so nearer than 0.3 m → NaN.
        let f = cam.capture(&bvh, Pose2::new(2.8, 0.0, 0.0));
        assert!(f.range[centre].is_nan());
        assert_eq!(f.depth_image()[centre], 0.0);
    }

    #[test]
    fn frames_do_not_depend_on_the_thread_count() {
        let cam = camera(80, 60);
        let bvh = MeshBvh::new(&crate::sensor::raycast::testing::furnished_room(8.0)).unwrap();
        let pose = Pose2::new(3.1, 4.2, 0.9);
        let run = |threads: usize| {
            let f = crate::util::on_threads(threads, || cam.capture(&bvh, pose));
            f.range.iter().map(|r| r.to_bits()).collect::<Vec<_>>()
        };
        let one = run(1);
        assert_eq!(one, run(3));
        assert!(one.iter().any(|&r| f32::from_bits(r).is_finite()));
    }

    #[test]
    fn capture_into_reuses_and_matches_capture() {
        let cam = camera(20, 10);
        let bvh = MeshBvh::new(&wall_mesh()).unwrap();
        let mut f = cam.capture(&bvh, Pose2::new(0.0, 0.5, 0.3));
        let g = cam.capture(&bvh, Pose2::new(0.5, 0.0, -0.2));
        cam.capture_into(&bvh, Pose2::new(0.5, 0.0, -0.2), &mut f);
        assert_eq!(f.dirs, g.dirs);
        assert_eq!(
            f.range.iter().map(|r| r.to_bits()).collect::<Vec<_>>(),
            g.range.iter().map(|r| r.to_bits()).collect::<Vec<_>>()
        );
    }
}
