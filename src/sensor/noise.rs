//! Depth noise: what a real depth camera does to an exact frame (`[noise.depth]`).
//!
//! Two models of the error along the optical axis, both with lateral error and invalid pixels:
//!
//! - **`kinect`** (structured light, Kinect v1), after C. V. Nguyen, S. Izadi and D. Lovell,
//!   "Modeling Kinect Sensor Noise for Improved 3D Reconstruction and Tracking", 3DIMPVT 2012: the
//!   axial standard deviation `σ_z(z, θ) = 0.0012 + 0.0019 (z − 0.4)² + 0.0001/√z · θ²/(π/2 − θ)²`
//!   metres (z in metres, θ the angle between the ray and the surface normal) and the lateral one
//!   `σ_L(θ) = 0.8 + 0.035 θ/(π/2 − θ)` pixels of the sensor. Each coefficient is a key.
//! - **`stereo`** (active stereo, RealSense D400), after L. Keselman, J. I. Woodfill,
//!   A. Grunnet-Jepsen and A. Bhowmik, "Intel RealSense Stereoscopic Depth Cameras", CVPR Workshops
//!   2017: depth is `f·B/d` for a disparity `d` in pixels; the disparity carries a Gaussian error of
//!   `subpixel_px` and is quantised to `disparity_step_px`, so the depth RMS error is
//!   `z² · subpixel / (f · B)` (to first order; quantisation adds `step²/12` to the disparity's
//!   variance).
//!
//! **Invalid pixels**: a pixel gives no reading (NaN, not integrated) with probability `dropout`,
//! more at grazing incidence (rising linearly from `grazing_start_deg` to `grazing_dropout` more
//! at 90°) and at depth edges (`edge_dropout` more where a 4-neighbour's depth jumps by more than
//! `edge_jump` of the pixel's own or has no hit). A noisy reading outside the camera's range gives
//! none either: a real sensor reports nothing beyond its range. A ray that hit nothing (no
//! surface within range, which the map reads as free space up to the range) stays so, unless it
//! drops out.
//!
//! **Determinism**: every draw is a pure function of (seed, step, pixel, channel)
//! ([`crate::util::CounterRng`]), so a frame's noise does not depend on the thread count, on the
//! renderer or on which frames came before.
//!
//! Simplifications, stated: the incidence angle is estimated from the exact frame's neighbouring
//! pixels (the surface normal of their points), as a reconstruction would from its own data; lateral
//! error moves the pixel's sample to the nearest pixel of this camera, so at the default 80 × 60
//! pixels (each about seven Kinect pixels wide) it rarely changes a reading; it matters at full
//! resolution (`configs/kinect_full_resolution.toml`).

use super::camera::DepthFrame;
use crate::config::{CameraConfig, Config, DepthNoiseConfig, DepthNoiseModel};
use crate::util::{normal_quantile, CounterRng};
use nalgebra::Vector3;
use rayon::prelude::*;
use std::f64::consts::FRAC_PI_2;

/// The stream of the run's counter generator that depth noise draws from.
const DEPTH_STREAM: u64 = 0x0064_6570_7468;

/// The largest incidence angle the formulas take, radians (85°): the angle terms grow without
/// bound towards 90°, and Nguyen et al. measured up to about 80°.
const MAX_THETA: f64 = 85.0 * std::f64::consts::PI / 180.0;

/// Nguyen et al.'s lateral standard deviation at incidence `theta` (clamped to 85°), in the pixels
/// of a camera of focal length `focal_px`.
fn lateral_sigma(c: &DepthNoiseConfig, focal_px: f64, theta: f64) -> f64 {
    let t = theta.min(MAX_THETA);
    (c.lateral_px + c.lateral_angle_px * t / (FRAC_PI_2 - t)) * focal_px / c.focal_px
}

/// The uniform `u₁` below which a Box–Muller pair of standard deviation `sigma` may round to a
/// shift of a pixel: `σ √(−2 ln u₁) ≥ 0.5` ⇔ `u₁ ≤ exp(−1/(8σ²))`; 0 when σ is 0.
fn reach(sigma: f64) -> f64 {
    if sigma > 0.0 {
        (-0.125 / (sigma * sigma)).exp()
    } else {
        0.0
    }
}

/// The depth noise of one run: the model, its generator and scratch buffers.
#[derive(Clone, Debug)]
pub struct DepthNoise {
    cfg: DepthNoiseConfig,
    rng: CounterRng,
    /// This camera's horizontal focal length in its own pixels.
    focal_px: f64,
    min_range: f32,
    max_range: f32,
    /// Below this uniform, the lateral error may move a pixel's sample at the largest angle (see
    /// [`DepthNoise::pixel`]).
    lateral_reach: f64,
    /// Grazing dropout's start angle and the span from it to 90°, radians.
    grazing: (f64, f64),
    /// The exact frame's ranges, read while the noisy ones are written.
    exact: Vec<f32>,
}

/// acos(x) for x in [0, 1], within 2e-8 rad (Abramowitz and Stegun, Handbook of Mathematical
/// Functions, 4.4.46): a third of the library call's time, and far below the error of the normal
/// the angle is estimated from.
fn acos_unit(x: f64) -> f64 {
    const A: [f64; 8] = [
        1.570_796_305_0,
        -0.214_598_801_6,
        0.088_978_987_4,
        -0.050_174_304_6,
        0.030_891_881_0,
        -0.017_088_125_6,
        0.006_670_090_1,
        -0.001_262_491_1,
    ];
    let x = x.clamp(0.0, 1.0);
    (1.0 - x).sqrt() * A.iter().rev().fold(0.0, |acc, &a| acc * x + a)
}

impl DepthNoise {
    /// The run's depth noise, `None` when `noise.depth.model = "none"`.
    pub fn new(cfg: &Config) -> Option<DepthNoise> {
        (cfg.noise.depth.model != DepthNoiseModel::None)
            .then(|| Self::with(&cfg.noise.depth, &cfg.camera, cfg.seed))
    }

    /// Depth noise of `noise` for a camera of `camera`, drawn from `seed`'s stream.
    pub fn with(noise: &DepthNoiseConfig, camera: &CameraConfig, seed: u64) -> DepthNoise {
        let tan_h = (camera.hfov_deg.to_radians() / 2.0).tan();
        let focal_px = camera.width as f64 / (2.0 * tan_h);
        let start = noise.grazing_start_deg.to_radians();
        DepthNoise {
            cfg: noise.clone(),
            rng: CounterRng::new(seed, DEPTH_STREAM),
            focal_px,
            min_range: camera.min_range_m.get() as f32,
            max_range: camera.max_range_m.get() as f32,
            lateral_reach: reach(lateral_sigma(noise, focal_px, MAX_THETA)),
            grazing: (start, FRAC_PI_2 - start),
            exact: Vec::new(),
        }
    }

    /// The axial standard deviation of the model at depth `z` (metres) and incidence `theta`
    /// (radians, clamped to 85°), metres, for a pixel whose disparity is not quantised.
    pub fn sigma_z(&self, z: f64, theta: f64) -> f64 {
        let c = &self.cfg;
        match c.model {
            DepthNoiseModel::None => 0.0,
            DepthNoiseModel::Kinect => {
                let t = theta.clamp(0.0, MAX_THETA);
                let angle = t * t / ((FRAC_PI_2 - t) * (FRAC_PI_2 - t));
                c.axial_base_m
                    + c.axial_quadratic_per_m * (z - c.axial_offset_m).powi(2)
                    + c.axial_angle_m / z.sqrt() * angle
            }
            DepthNoiseModel::Stereo => z * z * c.subpixel_px / (c.focal_px * c.baseline_m),
        }
    }

    /// Replaces `frame`'s exact ranges by noisy ones; `step` is the frame's counter (the step it
    /// was taken at). The result does not depend on the thread count.
    pub fn apply(&mut self, frame: &mut DepthFrame, step: u64) {
        self.exact.clear();
        self.exact.extend_from_slice(&frame.range);
        let this = &*self;
        let (dirs, axis, w, h) = (&frame.dirs, frame.axis, frame.width, frame.height);
        let noisy = |(i, r): (usize, &mut f32)| *r = this.pixel(dirs, axis, w, h, i, step);
        if rayon::current_num_threads() > 1 {
            (frame.range.par_iter_mut().enumerate())
                .with_min_len(4096)
                .for_each(noisy);
        } else {
            frame.range.iter_mut().enumerate().for_each(noisy);
        }
    }

    /// The noisy range of pixel `i`.
    fn pixel(
        &self,
        dirs: &[Vector3<f32>],
        axis: Vector3<f32>,
        w: usize,
        h: usize,
        i: usize,
        step: u64,
    ) -> f32 {
        let c = &self.cfg;
        let exact = self.exact[i];
        if exact.is_nan() {
            return f32::NAN;
        }
        // One key per pixel; each draw from it costs one mix: 0 dropout, 1–2 lateral, 3 axial.
        let key = self.rng.key(step, i as u64);
        let draw = |k: u64| CounterRng::uniform_of(key, k);
        if exact.is_infinite() {
            return if draw(0) < c.dropout {
                f32::NAN
            } else {
                f32::INFINITY
            };
        }
        let (col, row) = (i % w, i / w);
        let (theta, edge) = self.incidence(dirs, w, h, col, row);
        let grazing = ((theta - self.grazing.0) / self.grazing.1).clamp(0.0, 1.0);
        let p_drop =
            c.dropout + c.grazing_dropout * grazing + if edge { c.edge_dropout } else { 0.0 };
        if draw(0) < p_drop {
            return f32::NAN;
        }
        // Lateral error: where the pixel samples the scene, in this camera's pixels, a Box–Muller
        // pair (σ r cos φ, σ r sin φ). Neither rounds away from 0 while σ r < 0.5, that is while
        // u₁ > exp(−1/(8σ²)) ([`reach`]): at this camera's coarse pixels the common case, decided
        // first against the largest σ, then against the pixel's own (the same draws either way).
        let u1 = draw(1);
        let sigma_l = || lateral_sigma(c, self.focal_px, theta);
        let j = if u1 >= self.lateral_reach || u1 >= reach(sigma_l()) {
            i
        } else {
            let sigma_l = sigma_l();
            let r = sigma_l * (-2.0 * u1.ln()).sqrt();
            let (sin, cos) = (std::f64::consts::TAU * draw(2)).sin_cos();
            let shift = |v: usize, n: usize, d: f64| {
                (v as f64 + d.round()).clamp(0.0, (n - 1) as f64) as usize
            };
            shift(row, h, r * sin) * w + shift(col, w, r * cos)
        };
        let sampled = self.exact[j];
        if !sampled.is_finite() {
            return sampled;
        }
        let z = f64::from(sampled * dirs[j].dot(&axis));
        let normal = normal_quantile(draw(3));
        let z_noisy = match c.model {
            DepthNoiseModel::None => z,
            DepthNoiseModel::Kinect => z + self.sigma_z(z, theta) * normal,
            DepthNoiseModel::Stereo => {
                let fb = c.focal_px * c.baseline_m;
                let mut d = fb / z + c.subpixel_px * normal;
                if c.disparity_step_px > 0.0 {
                    d = (d / c.disparity_step_px).round() * c.disparity_step_px;
                }
                if d <= 0.0 {
                    return f32::NAN;
                }
                fb / d
            }
        };
        let range = (z_noisy / f64::from(dirs[i].dot(&axis))) as f32;
        if range.is_finite() && range >= self.min_range && range < self.max_range {
            range
        } else {
            f32::NAN
        }
    }

    /// The incidence angle at pixel `(col, row)` (radians, between the ray and the surface normal
    /// estimated from the exact points of its 4-neighbours; 0 where no neighbour lies on its
    /// surface) and whether the pixel is a depth edge.
    fn incidence(
        &self,
        dirs: &[Vector3<f32>],
        w: usize,
        h: usize,
        col: usize,
        row: usize,
    ) -> (f64, bool) {
        let i = row * w + col;
        let r = self.exact[i];
        let point = |j: usize| dirs[j].cast::<f64>() * f64::from(self.exact[j]);
        let p = point(i);
        let mut edge = false;
        // A neighbour on the same surface: a finite reading without a depth jump.
        let mut same = |j: usize| {
            let rj = self.exact[j];
            let ok = rj.is_finite() && (rj - r).abs() <= (self.cfg.edge_jump as f32) * r;
            edge |= !ok;
            ok.then_some(j)
        };
        let left = (col > 0).then(|| same(i - 1)).flatten();
        let right = (col + 1 < w).then(|| same(i + 1)).flatten();
        let up = (row > 0).then(|| same(i - w)).flatten();
        let down = (row + 1 < h).then(|| same(i + w)).flatten();
        let tangent = |a: Option<usize>, b: Option<usize>| match (a, b) {
            (Some(a), Some(b)) => Some(point(b) - point(a)),
            (Some(a), None) => Some(p - point(a)),
            (None, Some(b)) => Some(point(b) - p),
            (None, None) => None,
        };
        let theta = match (tangent(left, right), tangent(up, down)) {
            (Some(u), Some(v)) => {
                let n = u.cross(&v);
                let norm2 = n.norm_squared() * p.norm_squared();
                if norm2 > 0.0 {
                    acos_unit(n.dot(&p).abs() / norm2.sqrt())
                } else {
                    0.0
                }
            }
            _ => 0.0,
        };
        (theta, edge)
    }
}

#[cfg(test)]
mod tests {
    use super::super::raycast::testing::push_box;
    use super::super::{DepthCamera, MeshBvh};
    use super::*;
    use crate::config::Config;
    use crate::scene::TriMesh;
    use crate::Pose2;

    /// A camera of 160 × 120 pixels (19,200 per frame) and a config with `model` on.
    fn setup(model: DepthNoiseModel) -> Config {
        let mut cfg = Config::default();
        cfg.camera.width = 160;
        cfg.camera.height = 120;
        cfg.noise.depth.model = model;
        cfg
    }

    /// A frame of a flat wall facing the camera at `z` metres (the wall fills the view).
    fn wall_frame(cfg: &Config, z: f32) -> (DepthFrame, MeshBvh) {
        let mut mesh = TriMesh::default();
        push_box(&mut mesh, [z, -50.0, -50.0], [z + 0.2, 50.0, 50.0]);
        let bvh = MeshBvh::new(&mesh).unwrap();
        let frame = DepthCamera::new(&cfg.camera).capture(&bvh, Pose2::new(0.0, 0.0, 0.0));
        (frame, bvh)
    }

    /// Mean and standard deviation of the noisy z-depths of frames of the wall at `z`, and the
    /// share of pixels without a reading, over `frames` frames.
    fn wall_statistics(cfg: &Config, z: f32, frames: u64) -> (f64, f64, f64, usize) {
        let (exact, _) = wall_frame(cfg, z);
        let mut noise = DepthNoise::new(cfg).unwrap();
        let (mut n, mut s1, mut s2, mut invalid) = (0usize, 0.0, 0.0, 0usize);
        for step in 0..frames {
            let mut f = exact.clone();
            noise.apply(&mut f, step);
            for (d, &r) in f.dirs.iter().zip(&f.range) {
                if r.is_finite() {
                    let zd = f64::from(r * d.dot(&f.axis));
                    n += 1;
                    s1 += zd;
                    s2 += zd * zd;
                } else {
                    invalid += 1;
                }
            }
        }
        let mean = s1 / n as f64;
        let sd = (s2 / n as f64 - mean * mean).max(0.0).sqrt();
        (mean, sd, invalid as f64 / (n + invalid) as f64, n)
    }

    /// Kinect: on a frontal wall (θ = 0) the depth is unbiased and its standard deviation is
    /// Nguyen et al.'s 0.0012 + 0.0019 (z − 0.4)², within 5 %, over 19,200 pixels at each distance.
    #[test]
    fn kinect_wall_matches_nguyen() {
        let cfg = setup(DepthNoiseModel::Kinect);
        // Up to 3.5 m, where the wall fills the whole view and no noisy reading of it leaves the
        // 5 m range (the corner rays are 1.22 times longer than the axis).
        for z in [0.8f32, 1.5, 2.5, 3.0, 3.5] {
            let (mean, sd, invalid, n) = wall_statistics(&cfg, z, 1);
            assert!(n >= 10_000, "{n}");
            assert_eq!(invalid, 0.0);
            let z = f64::from(z);
            let sigma = 0.0012 + 0.0019 * (z - 0.4) * (z - 0.4);
            assert!((sd / sigma - 1.0).abs() < 0.05, "z {z}: σ {sd} vs {sigma}");
            // The mean is within 5 % of σ of the truth (σ/√n is under 1 % of σ here).
            assert!((mean - z).abs() < 0.05 * sigma, "z {z}: mean {mean}");
        }
    }

    /// Stereo: the depth RMS error is z² · σ_d / (f · B), with quantisation's step²/12 added to
    /// the disparity variance, within 5 %; the mean is the truth within 5 % of σ.
    #[test]
    fn stereo_wall_matches_the_disparity_model() {
        let mut cfg = setup(DepthNoiseModel::Stereo);
        cfg.noise.depth.focal_px = 426.0;
        let d = &cfg.noise.depth;
        let (f, b, s, q) = (d.focal_px, d.baseline_m, d.subpixel_px, d.disparity_step_px);
        for z in [0.8f32, 1.5, 2.5, 3.0, 3.5] {
            let (mean, sd, invalid, n) = wall_statistics(&cfg, z, 1);
            assert!(n >= 10_000 && invalid == 0.0, "z {z}: {invalid}");
            let z = f64::from(z);
            let sigma = z * z * (s * s + q * q / 12.0).sqrt() / (f * b);
            assert!((sd / sigma - 1.0).abs() < 0.05, "z {z}: σ {sd} vs {sigma}");
            assert!((mean - z).abs() < 0.05 * sigma, "z {z}: mean {mean}");
        }
    }

    /// Kinect at an incidence of 60°: each pixel's error, divided by the formula's σ at its own
    /// depth and angle, has mean 0 and standard deviation 1 within 5 %.
    #[test]
    fn kinect_tilted_wall_matches_the_angle_term() {
        let mut cfg = setup(DepthNoiseModel::Kinect);
        // Lateral error would sample a neighbour at another depth on a tilted wall; off here, so
        // that only the axial model is measured.
        cfg.noise.depth.lateral_px = 0.0;
        cfg.noise.depth.lateral_angle_px = 0.0;
        // A wall through (2.5, 0) whose normal lies 60° from the optical axis, in the floor plane.
        let mut mesh = TriMesh::default();
        let (s, c) = 60f32.to_radians().sin_cos();
        let t = nalgebra::Vector3::new(-s, c, 0.0); // along the wall
        let o = nalgebra::Vector3::new(2.5, 0.0, 0.0);
        let v = |a: f32, zz: f32| {
            let p = o + t * a;
            nalgebra::Point3::new(p.x, p.y, zz)
        };
        let base = mesh.vertices.len() as u32;
        mesh.vertices.extend([
            v(-20.0, -20.0),
            v(20.0, -20.0),
            v(20.0, 20.0),
            v(-20.0, 20.0),
        ]);
        mesh.triangles
            .extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
        let bvh = MeshBvh::new(&mesh).unwrap();
        let exact = DepthCamera::new(&cfg.camera).capture(&bvh, Pose2::new(0.0, 0.0, 0.0));
        let mut noisy = exact.clone();
        let mut noise = DepthNoise::new(&cfg).unwrap();
        noise.apply(&mut noisy, 3);
        let normal = nalgebra::Vector3::new(c, s, 0.0);
        let (mut n, mut s1, mut s2) = (0usize, 0.0, 0.0);
        for i in 0..exact.len() {
            let (r0, r1) = (exact.range[i], noisy.range[i]);
            if !(r0.is_finite() && r1.is_finite()) {
                continue;
            }
            let k = f64::from(exact.dirs[i].dot(&exact.axis));
            let z = f64::from(r0) * k;
            let theta = f64::from(exact.dirs[i].dot(&normal).abs()).acos();
            let e = (f64::from(r1) * k - z) / noise.sigma_z(z, theta);
            n += 1;
            s1 += e;
            s2 += e * e;
        }
        assert!(n >= 10_000, "{n}");
        let mean = s1 / n as f64;
        let sd = (s2 / n as f64 - mean * mean).sqrt();
        assert!(mean.abs() < 0.05, "{mean}");
        assert!((sd - 1.0).abs() < 0.05, "{sd}");
    }

    /// Dropout: the share of pixels without a reading is `dropout` within 5 %; grazing and edge
    /// dropout add nothing on a frontal wall that fills the view.
    #[test]
    fn dropout_rate_on_a_frontal_wall() {
        let mut cfg = setup(DepthNoiseModel::Kinect);
        cfg.noise.depth.dropout = 0.1;
        cfg.noise.depth.grazing_dropout = 0.9;
        cfg.noise.depth.edge_dropout = 0.9;
        let (_, _, invalid, _) = wall_statistics(&cfg, 2.0, 3);
        assert!((invalid / 0.1 - 1.0).abs() < 0.05, "{invalid}");
    }

    /// Edges and grazing angles drop out: a box in front of a wall loses its silhouette pixels at
    /// `edge_dropout = 1`, and nothing inside its faces.
    #[test]
    fn edge_pixels_drop_out() {
        let mut cfg = setup(DepthNoiseModel::Kinect);
        cfg.noise.depth.edge_dropout = 1.0;
        let mut mesh = TriMesh::default();
        push_box(&mut mesh, [4.0, -50.0, -50.0], [4.2, 50.0, 50.0]);
        push_box(&mut mesh, [2.0, -0.3, 0.3], [2.2, 0.3, 0.9]);
        let bvh = MeshBvh::new(&mesh).unwrap();
        let exact = DepthCamera::new(&cfg.camera).capture(&bvh, Pose2::new(0.0, 0.0, 0.0));
        let mut noisy = exact.clone();
        DepthNoise::new(&cfg).unwrap().apply(&mut noisy, 0);
        let (w, h) = (exact.width, exact.height);
        let near = |i: usize| exact.range[i] < 3.0;
        for row in 1..h - 1 {
            for col in 1..w - 1 {
                let i = row * w + col;
                let edge = [i - 1, i + 1, i - w, i + w]
                    .iter()
                    .any(|&j| near(j) != near(i));
                assert_eq!(noisy.range[i].is_nan(), edge, "pixel ({col}, {row})");
            }
        }
    }

    /// Readings beyond the range give nothing, and a ray with no hit stays a ray with no hit.
    #[test]
    fn nothing_beyond_the_range() {
        let mut cfg = setup(DepthNoiseModel::Stereo);
        cfg.noise.depth.subpixel_px = 2.0;
        // Without lateral error, which may sample a neighbour with no hit (and read none, as it).
        cfg.noise.depth.lateral_px = 0.0;
        // A wall just inside the 5 m range: many noisy readings of it land beyond the range.
        let (mut frame, _) = wall_frame(&cfg, 4.9);
        let hits = frame.range.iter().filter(|r| r.is_finite()).count();
        assert!(hits > 1000);
        let exact = frame.range.clone();
        DepthNoise::new(&cfg).unwrap().apply(&mut frame, 0);
        let max = frame.max_range;
        for (e, r) in exact.iter().zip(&frame.range) {
            if e.is_finite() {
                assert!(r.is_nan() || *r < max, "{e} became {r}");
            } else {
                assert_eq!(r, e);
            }
        }
        assert!(frame.range.iter().filter(|r| r.is_nan()).count() > hits / 10);
        // Nothing in view: every ray stays without a hit.
        let mut empty = DepthCamera::new(&cfg.camera).capture(
            &MeshBvh::new(&{
                let mut m = TriMesh::default();
                push_box(&mut m, [-9.0, -9.0, 0.0], [-8.0, -8.0, 1.0]);
                m
            })
            .unwrap(),
            Pose2::new(0.0, 0.0, 0.0),
        );
        DepthNoise::new(&cfg).unwrap().apply(&mut empty, 0);
        assert!(empty.range.iter().all(|r| *r == f32::INFINITY));
    }

    /// The noise is a function of (seed, step, pixel): the same under 1 and 2 threads, different
    /// for another step or seed.
    #[test]
    fn noise_is_keyed_by_seed_step_and_pixel() {
        let mut cfg = setup(DepthNoiseModel::Kinect);
        cfg.noise.depth.dropout = 0.05;
        let (exact, _) = wall_frame(&cfg, 2.0);
        let run = |cfg: &Config, step: u64, threads: usize| {
            crate::util::on_threads(threads, || {
                let mut f = exact.clone();
                DepthNoise::new(cfg).unwrap().apply(&mut f, step);
                f.range.iter().map(|r| r.to_bits()).collect::<Vec<u32>>()
            })
        };
        let a = run(&cfg, 4, 1);
        assert_eq!(a, run(&cfg, 4, 2));
        assert_ne!(a, run(&cfg, 5, 1));
        let mut other = cfg.clone();
        other.seed += 1;
        assert_ne!(a, run(&other, 4, 1));
    }
}
