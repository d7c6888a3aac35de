//! Pose and motion error (`[noise.pose]`, `[noise.motion]`): the robot executes its commands only
//! approximately, and knows its pose only through an estimate.
//!
//! - **Actuation** (`[noise.motion]`): each step's commanded motion is split as in the odometry
//!   motion model of S. Thrun, W. Burgard and D. Fox, *Probabilistic Robotics*, MIT Press 2005
//!   (§5.4, Table 5.6): a turn `δ₁`, a straight `δ_t` and a turn `δ₂`. Each part is executed with a
//!   Gaussian error of variance `α₁δ₁² + α₂δ_t²` (turns) and `α₃δ_t² + α₄(δ₁² + δ₂²)` (straight):
//!   errors proportional to the command. The robot really ends up there; collisions and the
//!   metrics see it.
//! - **Estimate** (`[noise.pose]`):
//!   - `odometry`: dead reckoning. Each step's true motion is measured with the same model's error
//!     (its own alphas) and added to the estimate, so the error grows without bound.
//!   - `localized`: a localisation system's estimate, the truth plus an error in x, y and yaw, each
//!     an Ornstein–Uhlenbeck process `e ← ρ e + σ √(1 − ρ²) n`, `ρ = exp(−dt/τ)`: stationary with
//!     standard deviation σ and autocorrelation `exp(−t/τ)`, pulled back towards the truth. It
//!     starts at zero (the start pose is known).
//!
//! The map, the planners and the motion executor's guard see the estimate; the sensor renders
//! from the truth. Every draw is a pure function of (seed, stream, step, channel)
//! ([`crate::util::CounterRng`]).
//!
//! Simplification, stated: the model is applied once per step of `sim.dt_s` (the odometry
//! interval), so its accumulated error depends on `dt`; the presets' alphas are for dt = 0.1 s.

use crate::config::{Config, PoseModel};
use crate::util::{wrap_angle, CounterRng};
use crate::Pose2;

const MOTION_STREAM: u64 = 0x6d6f_7469_6f6e;
const POSE_STREAM: u64 = 0x706f_7365;

/// A relative motion as the odometry motion model splits it: turn `rot1`, drive `trans` straight,
/// turn `rot2` (radians, metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Delta {
    pub rot1: f64,
    pub trans: f64,
    pub rot2: f64,
}

impl Delta {
    /// The motion from `a` to `b`. A step backwards (the chord more than 90° off the heading: a
    /// slip, or a turn in place that moved the robot a hair back) is a negative `trans` with a small
    /// turn, not a half turn each way: the model's turn errors grow with the turns, and a robot that
    /// slipped back did not turn about.
    pub fn between(a: Pose2, b: Pose2) -> Delta {
        let (dx, dy) = (b.x - a.x, b.y - a.y);
        let mut trans = dx.hypot(dy);
        let mut rot1 = if trans < 1e-12 {
            0.0
        } else {
            wrap_angle(dy.atan2(dx) - a.yaw)
        };
        if rot1.abs() > std::f64::consts::FRAC_PI_2 {
            trans = -trans;
            rot1 = wrap_angle(rot1 + std::f64::consts::PI);
        }
        Delta {
            rot1,
            trans,
            rot2: wrap_angle(b.yaw - a.yaw - rot1),
        }
    }

    /// The pose reached from `p` by this motion.
    pub fn apply(self, p: Pose2) -> Pose2 {
        let yaw1 = p.yaw + self.rot1;
        Pose2::new(
            p.x + self.trans * yaw1.cos(),
            p.y + self.trans * yaw1.sin(),
            wrap_angle(yaw1 + self.rot2),
        )
    }

    /// Standard deviations of the three parts' errors under `alpha` (Thrun et al., Table 5.6).
    pub fn sigmas(self, alpha: &[f64; 4]) -> [f64; 3] {
        let (r1, t, r2) = (
            self.rot1 * self.rot1,
            self.trans * self.trans,
            self.rot2 * self.rot2,
        );
        [
            (alpha[0] * r1 + alpha[1] * t).sqrt(),
            (alpha[2] * t + alpha[3] * (r1 + r2)).sqrt(),
            (alpha[0] * r2 + alpha[1] * t).sqrt(),
        ]
    }

    /// This motion with the model's error under `alpha`, drawn from `rng` at counter `step`.
    fn perturbed(self, alpha: &[f64; 4], rng: &CounterRng, step: u64) -> Delta {
        let s = self.sigmas(alpha);
        Delta {
            rot1: self.rot1 + s[0] * rng.normal(step, 0, 0),
            trans: self.trans + s[1] * rng.normal(step, 0, 1),
            rot2: self.rot2 + s[2] * rng.normal(step, 0, 2),
        }
    }
}

/// How the robot knows its pose.
#[derive(Clone, Debug)]
enum Estimator {
    /// The true pose.
    Exact,
    /// Dead reckoning with the model's error under these alphas.
    Odometry { alpha: [f64; 4] },
    /// The truth plus an Ornstein–Uhlenbeck error (x, y, yaw) of these deviations; `rho` is the
    /// error's correlation over one step.
    Localized {
        sigma: [f64; 3],
        rho: f64,
        error: [f64; 3],
    },
}

/// A run's actuation error and pose estimate.
#[derive(Clone, Debug)]
pub struct Odometry {
    /// Actuation error's alphas, when on.
    motion: Option<[f64; 4]>,
    motion_rng: CounterRng,
    estimator: Estimator,
    pose_rng: CounterRng,
    estimate: Pose2,
}

impl Odometry {
    /// The run's pose and motion error, starting at the (known) `start`; `None` when both are off.
    pub fn new(cfg: &Config, start: Pose2) -> Option<Odometry> {
        if !cfg.noise.pose_is_noisy() {
            return None;
        }
        let (m, p) = (&cfg.noise.motion, &cfg.noise.pose);
        let estimator = match p.model {
            PoseModel::None => Estimator::Exact,
            PoseModel::Odometry => Estimator::Odometry {
                alpha: [p.alpha1, p.alpha2, p.alpha3, p.alpha4],
            },
            PoseModel::Localized => Estimator::Localized {
                sigma: [p.sigma_xy_m, p.sigma_xy_m, p.sigma_yaw_rad],
                rho: (-cfg.sim.dt_s / p.time_constant_s).exp(),
                error: [0.0; 3],
            },
        };
        Some(Odometry {
            motion: m
                .enabled
                .then_some([m.alpha1, m.alpha2, m.alpha3, m.alpha4]),
            motion_rng: CounterRng::new(cfg.seed, MOTION_STREAM),
            estimator,
            pose_rng: CounterRng::new(cfg.seed, POSE_STREAM),
            estimate: start,
        })
    }

    /// The robot's estimate of its pose.
    pub fn estimate(&self) -> Pose2 {
        self.estimate
    }

    /// The pose the robot really reaches at step `step` when commanded from `from` to
    /// `commanded`.
    pub fn execute(&self, step: u64, from: Pose2, commanded: Pose2) -> Pose2 {
        match &self.motion {
            None => commanded,
            Some(alpha) => Delta::between(from, commanded)
                .perturbed(alpha, &self.motion_rng, step)
                .apply(from),
        }
    }

    /// Updates the estimate after the robot truly moved from `from` to `to` in step `step`.
    pub fn observe(&mut self, step: u64, from: Pose2, to: Pose2) {
        let rng = &self.pose_rng;
        match &mut self.estimator {
            Estimator::Exact => self.estimate = to,
            Estimator::Odometry { alpha } => {
                let measured = Delta::between(from, to).perturbed(alpha, rng, step);
                self.estimate = measured.apply(self.estimate);
            }
            Estimator::Localized { sigma, rho, error } => {
                let kick = (1.0 - *rho * *rho).sqrt();
                for (k, e) in error.iter_mut().enumerate() {
                    *e = *rho * *e + sigma[k] * kick * rng.normal(step, 1, k as u64);
                }
                self.estimate = Pose2::new(
                    to.x + error[0],
                    to.y + error[1],
                    wrap_angle(to.yaw + error[2]),
                );
            }
        }
    }
}

/// Absolute trajectory error between `estimate` and `truth` (pose by pose, the same times), in
/// position only and without alignment (both start at the same known pose): root mean square and
/// maximum, metres. What `evo_ape tum true.txt est.txt` reports without `-a`.
pub fn ate(estimate: &[Pose2], truth: &[Pose2]) -> (f64, f64) {
    let n = estimate.len().min(truth.len());
    if n == 0 {
        return (0.0, 0.0);
    }
    let (mut sum, mut max) = (0.0f64, 0.0f64);
    for (e, t) in estimate.iter().zip(truth) {
        let d2 = (e.x - t.x).powi(2) + (e.y - t.y).powi(2);
        sum += d2;
        max = max.max(d2.sqrt());
    }
    ((sum / n as f64).sqrt(), max)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn moments(v: &[f64]) -> (f64, f64) {
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
        (mean, var.sqrt())
    }

    fn within(got: f64, want: f64, what: &str) {
        assert!((got / want - 1.0).abs() < 0.05, "{what}: {got} vs {want}");
    }

    /// A motion split and put back together gives the same pose.
    #[test]
    fn delta_round_trips() {
        let a = Pose2::new(1.0, -2.0, 3.0);
        let b = Pose2::new(1.3, -1.9, -2.9);
        let c = Delta::between(a, b).apply(a);
        assert!((c.x - b.x).abs() < 1e-12 && (c.y - b.y).abs() < 1e-12);
        assert!(wrap_angle(c.yaw - b.yaw).abs() < 1e-12);
        let turn = Delta::between(a, Pose2::new(1.0, -2.0, 2.5));
        assert_eq!((turn.rot1, turn.trans), (0.0, 0.0));
        assert!((turn.rot2 + 0.5).abs() < 1e-12);
        // A step back is a negative straight, with no turn.
        let a = Pose2::new(0.0, 0.0, 0.3);
        let back = Pose2::new(-0.01 * 0.3f64.cos(), -0.01 * 0.3f64.sin(), 0.3);
        let d = Delta::between(a, back);
        assert!((d.trans + 0.01).abs() < 1e-12 && d.rot1.abs() < 1e-9 && d.rot2.abs() < 1e-9);
        let c = d.apply(a);
        assert!((c.x - back.x).abs() < 1e-12 && (c.y - back.y).abs() < 1e-12);
    }

    /// Actuation error: over 20,000 steps of the same command, each part's error has mean 0 and
    /// the model's standard deviation, within 5 %.
    #[test]
    fn actuation_error_has_the_model_statistics() {
        let mut cfg = Config::default();
        cfg.noise.motion.enabled = true;
        (cfg.noise.motion.alpha1, cfg.noise.motion.alpha2) = (0.01, 0.002);
        (cfg.noise.motion.alpha3, cfg.noise.motion.alpha4) = (0.004, 0.001);
        let from = Pose2::new(2.0, 1.0, 0.4);
        let commanded = crate::sim::robot::integrate(from, 0.8, 0.6, 0.1);
        let odo = Odometry::new(&cfg, from).unwrap();
        let d = Delta::between(from, commanded);
        let want = d.sigmas(&[0.01, 0.002, 0.004, 0.001]);
        let mut parts = [Vec::new(), Vec::new(), Vec::new()];
        for step in 0..20_000 {
            let e = Delta::between(from, odo.execute(step, from, commanded));
            parts[0].push(e.rot1 - d.rot1);
            parts[1].push(e.trans - d.trans);
            parts[2].push(wrap_angle(e.rot2 - d.rot2));
        }
        for k in 0..3 {
            let (mean, sd) = moments(&parts[k]);
            assert!(mean.abs() < 0.05 * want[k], "part {k}: mean {mean}");
            within(sd, want[k], &format!("part {k} σ"));
        }
    }

    /// Dead reckoning drifts as a random walk: after n straight steps of length d, the error
    /// along the path has variance n·α₃·d² and the heading's n·α₂·d² (to first order), over 4,000
    /// independent runs (seeds), within 5 %; the error grows as √n.
    #[test]
    fn odometry_drift_grows_as_a_random_walk() {
        let (n, d) = (100u64, 0.1);
        let alpha = [0.0025, 0.0001, 0.0009, 0.0001];
        let mut along = Vec::new();
        let mut heading = Vec::new();
        for seed in 0..4_000u64 {
            let mut cfg = Config {
                seed,
                ..Config::default()
            };
            cfg.noise.pose.model = PoseModel::Odometry;
            let p = &mut cfg.noise.pose;
            (p.alpha1, p.alpha2, p.alpha3, p.alpha4) = (alpha[0], alpha[1], alpha[2], alpha[3]);
            let mut truth = Pose2::new(0.0, 0.0, 0.0);
            let mut odo = Odometry::new(&cfg, truth).unwrap();
            for step in 0..n {
                let next = Pose2::new(truth.x + d, 0.0, 0.0);
                odo.observe(step, truth, next);
                truth = next;
            }
            along.push(odo.estimate().x - truth.x);
            heading.push(odo.estimate().yaw);
        }
        let nf = n as f64;
        let (m_along, sd_along) = moments(&along);
        // Along the path: each step's straight error (α₃ d²). The heading error shortens the path
        // by about d·α₂·d²·n²/2 = 0.5 mm, under 2 % of σ.
        within(sd_along, (nf * alpha[2] * d * d).sqrt(), "along-track σ");
        assert!(m_along.abs() < 0.1 * sd_along, "{m_along}");
        // Heading: two turns a step, each of variance α₂ d².
        let (_, sd_heading) = moments(&heading);
        within(
            sd_heading,
            (2.0 * nf * alpha[1] * d * d).sqrt(),
            "heading σ",
        );
    }

    /// The localized estimate's error is stationary with the set standard deviation and time
    /// constant (from its autocorrelation exp(−dt/τ) per step), within 5 %, over 1,000,000 steps
    /// (20,000 time constants).
    #[test]
    fn localized_error_is_a_bounded_correlated_walk() {
        let mut cfg = Config::default();
        cfg.noise.pose.model = PoseModel::Localized;
        let (sigma, tau, dt) = (0.05, 5.0, cfg.sim.dt_s);
        let mut odo = Odometry::new(&cfg, Pose2::new(0.0, 0.0, 0.0)).unwrap();
        let still = Pose2::new(0.0, 0.0, 0.0);
        let mut ex = Vec::new();
        let mut eyaw = Vec::new();
        for step in 0..1_000_000u64 {
            odo.observe(step, still, still);
            if step >= 1_000 {
                ex.push(odo.estimate().x);
                eyaw.push(odo.estimate().yaw);
            }
        }
        let (mean, sd) = moments(&ex);
        within(sd, sigma, "x σ");
        assert!(mean.abs() < 0.1 * sigma, "{mean}");
        within(moments(&eyaw).1, cfg.noise.pose.sigma_yaw_rad, "yaw σ");
        // The time constant from the lag-one autocorrelation ρ = exp(−dt/τ).
        let c: f64 =
            ex.iter().zip(&ex[1..]).map(|(a, b)| a * b).sum::<f64>() / (ex.len() - 1) as f64;
        within(-dt / (c / (sd * sd)).ln(), tau, "time constant");
    }

    /// ATE of a known offset, and none of identical trajectories.
    #[test]
    fn ate_known_answer() {
        let t: Vec<Pose2> = (0..4).map(|k| Pose2::new(k as f64, 0.0, 0.0)).collect();
        assert_eq!(ate(&t, &t), (0.0, 0.0));
        let mut e = t.clone();
        e[1].y = 3.0;
        e[3].x += 4.0;
        let (rmse, max) = ate(&e, &t);
        assert!((rmse - (25.0f64 / 4.0).sqrt()).abs() < 1e-12);
        assert_eq!(max, 4.0);
    }
}
