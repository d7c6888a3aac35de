//! Small-sample statistics for bench summaries: Student-t 95 % confidence intervals of a mean, and
//! paired differences between two planners.

use serde::Serialize;

/// Two-sided 95 % critical values of Student's t for 1..=30 degrees of freedom.
const T_975: [f64; 30] = [
    12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
    2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
    2.052, 2.048, 2.045, 2.042,
];

/// The 0.975 quantile of Student's t with `df` degrees of freedom (`df` ≥ 1): the table up to 30,
/// above it the Cornish–Fisher expansion around the normal quantile (error below 1e-3).
pub fn t_975(df: usize) -> f64 {
    assert!(df >= 1, "t quantile needs at least one degree of freedom");
    if df <= T_975.len() {
        return T_975[df - 1];
    }
    let z: f64 = 1.959_963_985;
    let n = df as f64;
    let g1 = (z.powi(3) + z) / 4.0;
    let g2 = (5.0 * z.powi(5) + 16.0 * z.powi(3) + 3.0 * z) / 96.0;
    let g3 = (3.0 * z.powi(7) + 19.0 * z.powi(5) + 17.0 * z.powi(3) - 15.0 * z) / 384.0;
    z + g1 / n + g2 / (n * n) + g3 / (n * n * n)
}

/// Mean, sample standard deviation and the half-width of the Student-t 95 % confidence interval of
/// the mean (absent below two values).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct MeanCi {
    pub n: usize,
    pub mean: f64,
    pub std: f64,
    pub ci95: Option<f64>,
}

impl MeanCi {
    pub fn of(v: &[f64]) -> MeanCi {
        if v.is_empty() {
            return MeanCi::default();
        }
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        if v.len() < 2 {
            return MeanCi {
                n: 1,
                mean,
                std: 0.0,
                ci95: None,
            };
        }
        let std = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        MeanCi {
            n: v.len(),
            mean,
            std,
            ci95: Some(t_975(v.len() - 1) * std / n.sqrt()),
        }
    }

    /// The interval `[mean − h, mean + h]`, if there is one.
    pub fn interval(&self) -> Option<(f64, f64)> {
        self.ci95.map(|h| (self.mean - h, self.mean + h))
    }

    /// `mean ± h` with `digits` decimals (`mean` alone without an interval).
    pub fn show(&self, digits: usize) -> String {
        match self.ci95 {
            Some(h) => format!("{:.*} ± {:.*}", digits, self.mean, digits, h),
            None => format!("{:.*}", digits, self.mean),
        }
    }
}

/// Which way a metric is better.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Better {
    Lower,
    Higher,
}

/// A paired difference `planner − reference` over matched runs, with its confidence interval and
/// the count of pairs the planner won, tied (within `tie`) and lost.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct PairedDiff {
    pub diff: MeanCi,
    pub wins: usize,
    pub ties: usize,
    pub losses: usize,
}

impl PairedDiff {
    /// From `(planner value, reference value)` pairs. A pair is a tie when the values differ by at
    /// most `tie(reference value)`.
    pub fn of(pairs: &[(f64, f64)], better: Better, tie: impl Fn(f64) -> f64) -> PairedDiff {
        let diffs: Vec<f64> = pairs.iter().map(|(p, r)| p - r).collect();
        let (mut wins, mut ties, mut losses) = (0, 0, 0);
        for &(p, r) in pairs {
            let d = p - r;
            if d.abs() <= tie(r) {
                ties += 1;
            } else if (d < 0.0) == (better == Better::Lower) {
                wins += 1;
            } else {
                losses += 1;
            }
        }
        PairedDiff {
            diff: MeanCi::of(&diffs),
            wins,
            ties,
            losses,
        }
    }

    /// What the interval supports: `lower`/`higher` when it excludes zero, else that no difference
    /// was shown (or that there are too few pairs for an interval).
    pub fn reading(&self, lower: &str, higher: &str) -> String {
        match self.diff.interval() {
            None => "too few pairs for an interval".into(),
            Some((lo, _)) if lo > 0.0 => higher.into(),
            Some((_, hi)) if hi < 0.0 => lower.into(),
            Some(_) => "no difference shown at 95 %".into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t_quantiles_known_values() {
        assert_eq!(t_975(1), 12.706);
        assert_eq!(t_975(30), 2.042);
        // Published values: df 40 → 2.021, 60 → 2.000, 120 → 1.980.
        assert!((t_975(40) - 2.021).abs() < 1e-3, "{}", t_975(40));
        assert!((t_975(60) - 2.000).abs() < 1e-3, "{}", t_975(60));
        assert!((t_975(120) - 1.980).abs() < 1e-3, "{}", t_975(120));
        // Monotone towards the normal quantile.
        assert!((31..200).all(|d| t_975(d) > t_975(d + 1) && t_975(d) > 1.96));
    }

    #[test]
    fn mean_ci_known_answer() {
        // n = 4, mean 5, s = sqrt(20/3); h = 3.182 · s / 2.
        let m = MeanCi::of(&[2.0, 4.0, 6.0, 8.0]);
        assert_eq!(m.mean, 5.0);
        let s = (20.0f64 / 3.0).sqrt();
        assert!((m.std - s).abs() < 1e-12);
        assert!((m.ci95.unwrap() - 3.182 * s / 2.0).abs() < 1e-12);
        assert_eq!(m.show(1), "5.0 ± 4.1");
        assert_eq!(MeanCi::of(&[3.0]).ci95, None);
        assert_eq!(MeanCi::of(&[3.0]).show(2), "3.00");
        assert_eq!(MeanCi::of(&[]), MeanCi::default());
    }

    #[test]
    fn paired_counts_and_reading() {
        // Path lengths (planner, reference): two shorter, one within 1 %, one longer.
        let pairs = [(8.0, 10.0), (9.0, 10.0), (10.05, 10.0), (12.0, 10.0)];
        let d = PairedDiff::of(&pairs, Better::Lower, |r| 0.01 * r);
        assert_eq!((d.wins, d.ties, d.losses), (2, 1, 1));
        assert!((d.diff.mean - (-2.0 - 1.0 + 0.05 + 2.0) / 4.0).abs() < 1e-12);
        assert_eq!(
            d.reading("shorter", "longer"),
            "no difference shown at 95 %"
        );
        let clear = PairedDiff::of(
            &[(8.0, 10.0), (8.5, 10.0), (7.9, 10.0)],
            Better::Lower,
            |_| 0.0,
        );
        assert_eq!(clear.reading("shorter", "longer"), "shorter");
        let higher = PairedDiff::of(
            &[(0.9, 0.8), (0.91, 0.8), (0.92, 0.8)],
            Better::Higher,
            |_| 0.0,
        );
        assert_eq!((higher.wins, higher.losses), (3, 0));
        assert_eq!(higher.reading("lower", "higher"), "higher");
    }
}
