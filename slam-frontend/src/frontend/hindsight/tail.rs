//! The detector's heavy tail, learnt in hindsight: a share of detections
//! lands far further from its cone than the assumed Gaussian allows (a
//! partly seen cone, a merged cluster; Student-t noise). Left to the
//! Gaussian, each becomes clutter and its cone misses a sighting.
//!
//! A detection's likelihood given its landmark is the mixture
//! (1 − w)·N(0, S) + w·N(0, k²S) with k = [`SPREAD`]; the weight w is the
//! maximum-likelihood fit (EM) to each detection's nearest landmark, beside
//! clutter spread evenly over the view, whose rate per scan is fitted with
//! it (never below the config's). On a Gaussian detector the weight stays
//! near 0 (clutter beside a cone is what the tail then has to explain) and
//! the costs are the Gaussian's.

use crate::frontend::GraphSlam;
use crate::frontend::association::Pair;

/// The weight of the detector's tail from which it is reported. Gaussian
/// logs learn up to 0.6% (clutter beside cones: the `hard` preset's random
/// track 0, seed 0, of the 600 runs of docs/fs-slam.md, the only ones at
/// 0.5% or more); Student-t noise of 3 degrees of freedom 1.5–1.9% (five
/// logs of random tracks 501–503 and two shared tracks, seed 505).
const REPORTED_TAIL: f64 = 0.01;

/// The tail's σ against the detector's: one shape, its weight learnt.
/// Student-t noise of 3 degrees of freedom at the detector's σ puts 1.4%
/// of each axis beyond 3σ, and most of that within 3 × 4σ.
pub(super) const SPREAD: f64 = 4.0;

/// EM rounds at most; it stops once the weight moves less than `1e-6`.
const ROUNDS: usize = 100;

/// The weight is never learnt above this: a tail carrying more is the
/// detector's noise itself, which the σ should say.
const MAX_WEIGHT: f64 = 0.5;

/// The learnt tail, and the clutter beside it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Tail {
    /// The tail's weight w in a cone's likelihood.
    pub(super) weight: f64,
    /// False positives per scan.
    pub(super) clutter_rate: f64,
    /// −2 ln of the clutter's density over the view, on the scale of
    /// [`Pair::cost`].
    pub(super) clutter: f64,
}

impl Tail {
    /// No tail, and clutter at `rate` per scan over a view of `area` m².
    pub(super) fn none(rate: f64, area: f64) -> Tail {
        // Clutter is spread evenly over the view; a cone's likelihood is a
        // Gaussian's, −2 ln of either up to the same 2 ln 2π.
        let density = (rate / area).max(1e-9);
        Tail {
            weight: 0.0,
            clutter_rate: rate,
            clutter: -2.0 * density.ln() - 2.0 * std::f64::consts::TAU.ln(),
        }
    }

    /// The tail's weight and the clutter rate that best explain the
    /// detections of `scans` scans over a view of `area` m², each given
    /// by its nearest landmark (`None`: none within reach, so clutter),
    /// the clutter never below the `rate` per scan assumed. (Below it, the
    /// wide rounds of matching in hindsight, whose every detection has a
    /// landmark near, would read no clutter at all.)
    pub(super) fn learn(nearest: &[Option<&Pair>], scans: usize, area: f64, rate: f64) -> Tail {
        let mut tail = Tail {
            weight: 0.05,
            ..Tail::none(rate, area)
        };
        if scans == 0 {
            return tail;
        }
        for _ in 0..ROUNDS {
            let (mut inlier, mut outlier, mut clutter) = (0.0, 0.0, 0.0);
            for pair in nearest {
                let Some(pair) = pair else {
                    clutter += 1.0;
                    continue;
                };
                let (a, b) = tail.log_parts(pair);
                let c = -0.5 * tail.clutter;
                let m = a.max(b).max(c);
                let (ea, eb, ec) = ((a - m).exp(), (b - m).exp(), (c - m).exp());
                let total = ea + eb + ec;
                inlier += ea / total;
                outlier += eb / total;
                clutter += ec / total;
            }
            let weight = if inlier + outlier > 0.0 {
                (outlier / (inlier + outlier)).min(MAX_WEIGHT)
            } else {
                0.0
            };
            let next = Tail {
                weight,
                ..Tail::none((clutter / scans as f64).max(rate), area)
            };
            let moved = (next.weight - tail.weight).abs()
                + (next.clutter_rate - tail.clutter_rate).abs() / (1.0 + tail.clutter_rate);
            tail = next;
            if moved < 1e-6 {
                break;
            }
        }
        tail
    }

    /// ln of the Gaussian's and of the tail's part of `pair`'s likelihood,
    /// each with its weight (the colour penalty applies to both whole).
    fn log_parts(&self, pair: &Pair) -> (f64, f64) {
        let ln_det = pair.cost - pair.d2;
        let k2 = SPREAD * SPREAD;
        let tail_d2 = pair.position_d2() / k2 + pair.penalty + 2.0 * k2.ln();
        (
            (1.0 - self.weight).ln() - 0.5 * (pair.d2 + ln_det),
            self.weight.ln() - 0.5 * (tail_d2 + ln_det),
        )
    }

    /// −2 ln of `pair`'s likelihood under the mixture, on the scale of
    /// [`Pair::cost`] (equal to it with no tail).
    pub(super) fn cost(&self, pair: &Pair) -> f64 {
        let (a, b) = self.log_parts(pair);
        let m = a.max(b);
        if m == f64::NEG_INFINITY {
            return f64::INFINITY;
        }
        -2.0 * (m + ((a - m).exp() + (b - m).exp()).ln())
    }

    /// Whether `pair` may be matched: within the Gaussian's `gate` by its
    /// position (a contradicting colour ranks it, never gates it), or
    /// beyond it where the tail explains it better than the Gaussian.
    pub(super) fn admits(&self, pair: &Pair, gate: f64) -> bool {
        if pair.within(gate) {
            return true;
        }
        let (a, b) = self.log_parts(pair);
        b > a
    }
}

impl GraphSlam {
    /// Says what the detections showed beyond the assumed noise and
    /// clutter, where it matters.
    pub(super) fn report_tail(&mut self, tail: &Tail) {
        if tail.weight >= REPORTED_TAIL {
            self.warnings.push(format!(
                "{:.1}% of the detections fell {SPREAD} times as wide (σ) as the assumed noise; matched by a heavy-tailed likelihood",
                100.0 * tail.weight
            ));
        }
        let assumed = self.config.false_positives;
        if tail.clutter_rate > 1.5 * assumed {
            self.warnings.push(format!(
                "the detector made {:.2} false positives per scan ({assumed} assumed); matched again at that rate",
                tail.clutter_rate
            ));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, SMatrix, Vector2};
    use rand::{Rng, SeedableRng, rngs::StdRng};
    use rand_distr::{Distribution, StandardNormal};

    /// A pair of unit innovation covariance and χ² `d2`.
    fn pair(d2: f64) -> Pair {
        Pair {
            landmark: 0,
            d2,
            cost: d2,
            penalty: 0.0,
            innovation: Vector2::new(d2.sqrt(), 0.0),
            h_pose: SMatrix::zeros(),
            s_pose: Matrix2::zeros(),
            s_local: Matrix2::identity(),
            bhattacharyya: 0.0,
        }
    }

    /// χ² of `n` detections, a share `tail` of them at σ × SPREAD.
    fn sample(n: usize, tail: f64, rng: &mut StdRng) -> Vec<Pair> {
        (0..n)
            .map(|_| {
                let k = if rng.random::<f64>() < tail {
                    SPREAD
                } else {
                    1.0
                };
                let x: f64 = StandardNormal.sample(rng);
                let y: f64 = StandardNormal.sample(rng);
                pair(k * k * (x * x + y * y))
            })
            .collect()
    }

    #[test]
    fn the_learnt_weight_is_the_tails_share() {
        let mut rng = StdRng::seed_from_u64(7);
        for share in [0.0, 0.02, 0.1] {
            let pairs = sample(20_000, share, &mut rng);
            let nearest: Vec<Option<&Pair>> = pairs.iter().map(Some).collect();
            // Clutter over a vast view: far less likely than any detection.
            let tail = Tail::learn(&nearest, 1000, 1e9, 0.001);
            let w = tail.weight;
            assert!((w - share).abs() < 0.01 + 0.2 * share, "{share}: {w}");
            assert!(tail.clutter_rate < 0.01, "{}", tail.clutter_rate);
        }
    }

    #[test]
    fn clutter_is_counted_and_takes_the_far_detections_from_the_tail() {
        // 500 scans, each with 10 detections of their cones, one detection
        // far from any landmark and, every fifth scan, one at χ² 100 beside
        // one: 1.2 false positives per scan over 10⁴ m² (σ = 1 m), which
        // the tail of a Gaussian detector must not take.
        let mut rng = StdRng::seed_from_u64(8);
        let pairs = sample(5_000, 0.0, &mut rng);
        let beside = vec![pair(100.0); 100];
        let nearest: Vec<Option<&Pair>> = pairs
            .iter()
            .chain(&beside)
            .map(Some)
            .chain(std::iter::repeat_n(None, 500))
            .collect();
        let tail = Tail::learn(&nearest, 500, 1e4, 0.3);
        assert!(tail.weight < 0.005, "{}", tail.weight);
        assert!(
            (tail.clutter_rate - 1.2).abs() < 0.08,
            "{}",
            tail.clutter_rate
        );
        assert!(tail.cost(&pair(100.0)) > tail.clutter);
    }

    #[test]
    fn without_a_tail_the_costs_and_gate_are_the_gaussians() {
        let none = Tail::none(0.3, 300.0);
        for d2 in [0.0, 3.0, 18.0, 40.0] {
            assert!((none.cost(&pair(d2)) - d2).abs() < 1e-12);
            assert_eq!(none.admits(&pair(d2), 18.42), d2 <= 18.42);
        }
        let tail = Tail {
            weight: 0.02,
            ..none
        };
        // Near the landmark the Gaussian dominates; far, the tail is cheaper.
        assert!((tail.cost(&pair(1.0)) - (1.0 - 2.0 * 0.98f64.ln())).abs() < 1e-2);
        assert!(tail.cost(&pair(60.0)) < 60.0);
        assert!(tail.admits(&pair(60.0), 18.42));
        // Beyond the gate a pair is admitted where the tail explains it
        // better: past χ² 14.2 for this weight, past 25.5 for a rare one.
        assert!(tail.admits(&pair(19.0), 18.42));
        let rare = Tail {
            weight: 1e-4,
            ..none
        };
        assert!(!rare.admits(&pair(25.0), 18.42));
        assert!(rare.admits(&pair(26.0), 18.42));
        // A contradicting colour ranks a pair lower but is no gate: within
        // the gate by position, admitted whatever its penalty.
        let recoloured = Pair {
            d2: 18.0 + 6.0,
            cost: 18.0 + 6.0,
            penalty: 6.0,
            ..pair(18.0)
        };
        assert!(none.admits(&recoloured, 18.42));
        assert!(none.cost(&recoloured) > none.cost(&pair(18.0)));
    }
}
