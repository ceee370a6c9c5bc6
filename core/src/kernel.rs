//! Robust kernels acting on the squared error s = eᵀΩe, as in g2o: an edge
//! contributes ρ(s) to χ² and is weighted by ρ′(s) when linearised
//! (iteratively reweighted least squares).

/// A robust kernel with its width δ.
///
/// ```
/// use cairn_core::RobustKernel;
/// let k = RobustKernel::Huber(1.0);
/// assert_eq!(k.robustify(0.25), [0.25, 1.0, 0.0]); // quadratic inside δ²
/// assert_eq!(k.robustify(4.0)[0], 3.0); // 2δ√s − δ² outside
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RobustKernel {
    /// s inside δ², linear in √s outside.
    Huber(f64),
    /// 2δ²(√(1 + s/δ²) − 1): smooth Huber.
    PseudoHuber(f64),
    /// δ² ln(1 + s/δ²).
    Cauchy(f64),
    /// s·δ/(δ + s) (g2o's form, with δ not squared).
    GemanMcClure(f64),
    /// δ²(1 − exp(−s/δ²)).
    Welsch(f64),
    /// 2δ²(√s/δ − ln(1 + √s/δ)).
    Fair(f64),
    /// δ²/3 (1 − (1 − s/δ²)³) inside δ², constant outside.
    Tukey(f64),
    /// s inside δ², δ² outside.
    Saturated(f64),
    /// Dynamic covariance scaling with Φ = δ: s·w², w = min(1, 2Φ/(Φ + s)).
    Dcs(f64),
}

impl RobustKernel {
    /// Whether ρ′ is the derivative of ρ, so that Σρ is the cost the
    /// weights ρ′ minimise. False for DCS only, whose value follows g2o
    /// (s·w², bounded by 4Φ), not the integral of its weight w²: a
    /// solution with outliers down-weighted can have a higher Σρ than a
    /// wrong one.
    pub fn value_matches_weight(&self) -> bool {
        !matches!(self, Self::Dcs(_))
    }

    /// Every kernel's name, as accepted by [`RobustKernel::from_name`].
    pub const NAMES: [&'static str; 9] = [
        "huber",
        "pseudo-huber",
        "cauchy",
        "geman-mcclure",
        "welsch",
        "fair",
        "tukey",
        "saturated",
        "dcs",
    ];

    /// The kernel called `name` (case-insensitive, `_` or `-`) with width `delta`.
    pub fn from_name(name: &str, delta: f64) -> Option<Self> {
        let key = name.to_ascii_lowercase().replace('_', "-");
        Some(match key.as_str() {
            "huber" => Self::Huber(delta),
            "pseudo-huber" | "pseudohuber" => Self::PseudoHuber(delta),
            "cauchy" => Self::Cauchy(delta),
            "geman-mcclure" | "gemanmcclure" => Self::GemanMcClure(delta),
            "welsch" => Self::Welsch(delta),
            "fair" => Self::Fair(delta),
            "tukey" => Self::Tukey(delta),
            "saturated" => Self::Saturated(delta),
            "dcs" => Self::Dcs(delta),
            _ => return None,
        })
    }

    /// The width δ.
    pub fn width(&self) -> f64 {
        match *self {
            Self::Huber(d)
            | Self::PseudoHuber(d)
            | Self::Cauchy(d)
            | Self::GemanMcClure(d)
            | Self::Welsch(d)
            | Self::Fair(d)
            | Self::Tukey(d)
            | Self::Saturated(d)
            | Self::Dcs(d) => d,
        }
    }

    /// [ρ(s), ρ′(s), ρ″(s)] for the squared error `s` (g2o's `robustify`; ρ and ρ′
    /// are g2o's, ρ″ is the exact derivative where g2o's differs — Fair,
    /// Geman-McClure — though neither uses ρ″ when linearising).
    pub fn robustify(&self, s: f64) -> [f64; 3] {
        let d = self.width();
        let d2 = d * d;
        match *self {
            Self::Huber(_) if s <= d2 => [s, 1.0, 0.0],
            Self::Huber(_) => {
                let r = s.sqrt();
                let w = d / r;
                [2.0 * d * r - d2, w, -0.5 * w / s]
            }
            // The forms below avoid cancellation for s ≪ δ².
            Self::PseudoHuber(_) => {
                let a = s / d2 + 1.0;
                let root = a.sqrt();
                [2.0 * s / (root + 1.0), 1.0 / root, -0.5 / (d2 * root * a)]
            }
            Self::Cauchy(_) => {
                let a = s / d2 + 1.0;
                [d2 * (s / d2).ln_1p(), 1.0 / a, -1.0 / (d2 * a * a)]
            }
            Self::GemanMcClure(_) => {
                let a = d / (d + s);
                [s * a, a * a, -2.0 * a * a * a / d]
            }
            Self::Welsch(_) => {
                let x = (-s / d2).exp();
                [-d2 * (-s / d2).exp_m1(), x, -x / d2]
            }
            Self::Fair(_) => {
                let r = s.sqrt();
                let a = r / d;
                [
                    2.0 * d2 * (a - a.ln_1p()),
                    1.0 / (1.0 + a),
                    -0.5 / (d * r * (1.0 + a) * (1.0 + a)),
                ]
            }
            Self::Tukey(_) if s <= d2 => {
                let (x, a) = (s / d2, 1.0 - s / d2);
                [d2 * x * (3.0 - 3.0 * x + x * x) / 3.0, a * a, -2.0 * a / d2]
            }
            Self::Tukey(_) => [d2 / 3.0, 0.0, 0.0],
            Self::Saturated(_) if s <= d2 => [s, 1.0, 0.0],
            Self::Saturated(_) => [d2, 0.0, 0.0],
            Self::Dcs(_) => {
                let w = (2.0 * d / (d + s)).min(1.0);
                [s * w * w, w * w, 0.0]
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kernels() -> Vec<RobustKernel> {
        RobustKernel::NAMES
            .iter()
            .map(|n| RobustKernel::from_name(n, 1.5).unwrap())
            .collect()
    }

    #[test]
    fn names_round_trip_and_unknown_names_are_none() {
        assert_eq!(kernels().len(), 9);
        assert_eq!(
            RobustKernel::from_name("Geman_McClure", 2.0),
            Some(RobustKernel::GemanMcClure(2.0))
        );
        assert_eq!(RobustKernel::from_name("l2", 1.0), None);
    }

    #[test]
    fn every_kernel_is_quadratic_near_zero_and_bounded_in_weight() {
        for k in kernels() {
            let [rho, w, _] = k.robustify(1e-12);
            assert!((rho - 1e-12).abs() < 1e-17, "{k:?}: ρ(s) ≈ s near zero");
            assert!(
                (w - 1.0).abs() < 1e-6 || matches!(k, RobustKernel::GemanMcClure(_)),
                "{k:?}: weight {w}"
            );
            for s in [0.1, 1.0, 10.0, 1e3, 1e6] {
                let [rho, w, _] = k.robustify(s);
                assert!(rho <= s + 1e-12 && rho >= 0.0, "{k:?}: ρ({s}) = {rho}");
                assert!((0.0..=1.0 + 1e-12).contains(&w), "{k:?}: ρ′({s}) = {w}");
            }
            // Large errors weigh less than small ones.
            assert!(k.robustify(1e6)[1] < k.robustify(0.01)[1], "{k:?}");
        }
    }

    #[test]
    fn first_derivative_matches_the_value_except_for_dcs() {
        // DCS's ρ′ is its IRLS weight, not the derivative of s·w², as in g2o.
        for k in kernels()
            .into_iter()
            .filter(|k| !matches!(k, RobustKernel::Dcs(_)))
        {
            for s in [0.3, 1.7, 2.2, 9.0, 50.0] {
                let h = 1e-6 * s;
                let numeric = (k.robustify(s + h)[0] - k.robustify(s - h)[0]) / (2.0 * h);
                assert!((numeric - k.robustify(s)[1]).abs() < 1e-6, "{k:?} at {s}");
                let second = (k.robustify(s + h)[1] - k.robustify(s - h)[1]) / (2.0 * h);
                assert!((second - k.robustify(s)[2]).abs() < 1e-5, "{k:?} ρ″ at {s}");
            }
        }
    }

    #[test]
    fn reference_values() {
        let d = 2.0;
        assert_eq!(
            RobustKernel::Huber(d).robustify(9.0)[0],
            2.0 * 2.0 * 3.0 - 4.0
        );
        assert!((RobustKernel::Cauchy(d).robustify(4.0)[0] - 4.0 * 2f64.ln()).abs() < 1e-15);
        assert_eq!(
            RobustKernel::Tukey(d).robustify(100.0),
            [4.0 / 3.0, 0.0, 0.0]
        );
        assert_eq!(RobustKernel::Saturated(d).robustify(100.0)[0], 4.0);
        assert_eq!(RobustKernel::GemanMcClure(d).robustify(2.0)[0], 1.0);
        assert!(
            (RobustKernel::Welsch(d).robustify(4.0)[0] - 4.0 * (1.0 - (-1.0f64).exp())).abs()
                < 1e-15
        );
        assert_eq!(RobustKernel::Dcs(d).robustify(1.0), [1.0, 1.0, 0.0]); // inside: w = 1
        assert_eq!(RobustKernel::Dcs(d).robustify(6.0), [6.0 * 0.25, 0.25, 0.0]); // w = 4/8
    }
}
