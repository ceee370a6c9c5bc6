//! How fast the gyro's bias wanders, learnt from a solved trajectory.
//!
//! Where landmarks fix the headings, the turn the solution makes beyond the
//! gyro's (one constant bias taken out) adds up to a heading drift d(t). Its
//! second difference over a lag L, d(t + 2L) − 2d(t + L) + d(t), cancels any
//! constant bias. A bias that random-walks at q rad/s/√s gives it a variance
//! of ⅔·q²·L³ (the Allan variance of a rate random walk, times 2L²), beside
//! the gyro's white noise over 2L, which the odometry states and is taken
//! out; the landmarks' own errors only add to it. Each lag therefore bounds
//! q from above, and the tightest bound is the estimate.

/// Lags (s) of the second differences. The walk's share grows as L³ and the
/// white noise's as L, so the long lags separate them.
const LAGS: [f64; 4] = [5.0, 10.0, 20.0, 40.0];

/// A lag is used where the trajectory spans at least this many lags: two
/// second differences that share no data.
const SPAN_IN_LAGS: f64 = 4.0;

/// The heading drift of a solved trajectory, sample by sample.
#[derive(Clone, Debug, Default)]
pub(super) struct Drift {
    /// Increasing times (s).
    pub(super) times: Vec<f64>,
    /// The turn beyond the gyro's since the first sample (rad).
    pub(super) drift: Vec<f64>,
    /// The variance the gyro's white noise adds to the drift since the first
    /// sample (rad²).
    pub(super) white: Vec<f64>,
}

impl Drift {
    /// The bias's random walk (rad/s/√s) the drift allows at most; `None`
    /// where the trajectory is too short for the shortest lag.
    pub(super) fn walk(&self) -> Option<f64> {
        debug_assert!(self.times.len() == self.drift.len() && self.drift.len() == self.white.len());
        let span = self.times.last()? - self.times.first()?;
        LAGS.iter()
            .filter(|&&lag| span >= SPAN_IN_LAGS * lag)
            .filter_map(|&lag| {
                let excess = self.second_difference_excess(lag)?;
                Some((1.5 * excess.max(0.0) / lag.powi(3)).sqrt())
            })
            .reduce(f64::min)
    }

    /// The mean square of d(t + 2L) − 2d(t + L) + d(t) over every sample t
    /// (d interpolated between samples, so that a constant bias cancels
    /// exactly), less the white noise's share.
    fn second_difference_excess(&self, lag: f64) -> Option<f64> {
        let times = &self.times;
        let (mut middle, mut end) = (0, 0);
        let (mut sum, mut count) = (0.0, 0usize);
        for (start, &t) in times.iter().enumerate() {
            while middle < times.len() && times[middle] < t + lag {
                middle += 1;
            }
            while end < times.len() && times[end] < t + 2.0 * lag {
                end += 1;
            }
            if end == times.len() {
                break;
            }
            let (d_middle, _) = self.at(middle, t + lag);
            let (d_end, white_end) = self.at(end, t + 2.0 * lag);
            let d = d_end - 2.0 * d_middle + self.drift[start];
            sum += d * d - (white_end - self.white[start]);
            count += 1;
        }
        (count > 0 && sum.is_finite()).then(|| sum / count as f64)
    }

    /// The drift and white variance at `time`, between sample `next` (the
    /// first at or after it) and the one before.
    fn at(&self, next: usize, time: f64) -> (f64, f64) {
        if next == 0 {
            return (self.drift[0], self.white[0]);
        }
        let (t0, t1) = (self.times[next - 1], self.times[next]);
        let f = if t1 > t0 {
            (time - t0) / (t1 - t0)
        } else {
            1.0
        };
        let mix = |v: &[f64]| v[next - 1] + f * (v[next] - v[next - 1]);
        (mix(&self.drift), mix(&self.white))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{SeedableRng, rngs::StdRng};
    use rand_distr::{Distribution, Normal};

    /// 200 s at 10 Hz of a bias walking at `walk` from `start`, a gyro whose
    /// white noise turns the heading by `gyro` rad per step (as stated), and
    /// headings the landmarks fix to `fix` rad.
    fn drift(walk: f64, start: f64, gyro: f64, fix: f64, seed: u64) -> Drift {
        let mut rng = StdRng::seed_from_u64(seed);
        let unit = Normal::new(0.0, 1.0).unwrap();
        let dt = 0.1;
        let (mut bias, mut heading) = (start, 0.0);
        let mut d = Drift::default();
        for k in 0..2000 {
            d.times.push(k as f64 * dt);
            d.drift.push(heading + fix * unit.sample(&mut rng));
            d.white.push(k as f64 * gyro * gyro);
            heading += bias * dt + gyro * unit.sample(&mut rng);
            bias += walk * dt.sqrt() * unit.sample(&mut rng);
        }
        d
    }

    #[test]
    fn a_walking_bias_is_found_to_within_a_factor_of_two() {
        for walk in [3e-4, 1e-3, 3e-3] {
            let mut estimates: Vec<f64> = (0..20)
                .map(|seed| drift(walk, 0.003, 5e-4, 0.002, seed).walk().unwrap())
                .collect();
            estimates.sort_by(f64::total_cmp);
            // The smallest of four bounds is biased low; no run is far out.
            let median = estimates[10];
            assert!(
                median > 0.5 * walk && median < 1.2 * walk,
                "{walk}: {estimates:?}"
            );
            assert!(
                estimates[0] > 0.25 * walk && estimates[19] < 2.0 * walk,
                "{estimates:?}"
            );
        }
    }

    #[test]
    fn a_constant_bias_and_the_stated_white_noise_give_a_small_walk() {
        for seed in 0..20 {
            let walk = drift(0.0, 0.004, 5e-4, 0.002, seed).walk().unwrap();
            // The gyro's stated noise is taken out only on average: what
            // is left of it and the fixes' errors read as a walk of 0–1e-4.
            assert!(walk < 1e-4, "{walk}");
        }
        // Gyro noise the odometry states is not taken for a walk: the bound
        // with it unstated is several times higher.
        let mut unstated = drift(0.0, 0.004, 2e-3, 0.0, 3);
        let stated = unstated.walk().unwrap();
        unstated.white.iter_mut().for_each(|w| *w = 0.0);
        assert!(
            unstated.walk().unwrap() > 3.0 * stated.max(1e-6),
            "{stated}"
        );
        // A constant bias alone: a straight drift, no walk at all.
        assert!(drift(0.0, 0.004, 0.0, 0.0, 0).walk().unwrap() < 1e-12);
    }

    #[test]
    fn a_short_trajectory_has_no_estimate() {
        let d = drift(5e-4, 0.0, 0.0, 0.0, 1);
        let cut = |n: usize| Drift {
            times: d.times[..n].to_vec(),
            drift: d.drift[..n].to_vec(),
            white: d.white[..n].to_vec(),
        };
        assert_eq!(cut(150).walk(), None);
        assert!(cut(250).walk().is_some());
        assert_eq!(Drift::default().walk(), None);
    }
}
