//! How much wider the innovations run than the covariances say, read
//! scan by scan for JCBB's joint test. That test sums the χ² of every pair
//! of a hypothesis, so with the detector twice as noisy as assumed (four
//! times the variance) the right hypothesis of a six-cone scan sums to about
//! 48 against a gate of 26 and is cut down to the few pairs that happen to
//! fit, while the individual gates, one pair at a time, still pass most of
//! them. The estimate is the median χ² of each detection's nearest landmark
//! over the last few scans: most detections see a landmark already mapped,
//! so the median stays on the right pairs when wrong neighbours sit in the
//! upper tail, and it needs no matches (which the tight test would bias) to
//! form. Detections with no landmark near (new cones) are left out; the
//! nearest χ² is cut where that starts (`new_landmark_gate`), which makes
//! the median read low when the noise is far wider than assumed (a third
//! low at three times the σ), never high.

/// χ² values kept: about twenty scans of six cones.
const WINDOW: usize = 128;

/// Fewest values an estimate is made from (one scan's worth).
const MIN_VALUES: usize = 4;

/// The median of χ² with 2 degrees of freedom, 2 ln 2.
const CHI2_2_MEDIAN: f64 = std::f64::consts::LN_2 * 2.0;

/// Largest scale read: σ five times the assumed.
const MAX_SCALE: f64 = 25.0;

/// The latest nearest-landmark χ² values, in a ring.
#[derive(Clone, Debug)]
pub(crate) struct InnovationScale {
    values: Vec<f64>,
    next: usize,
    scratch: Vec<f64>,
}

impl InnovationScale {
    pub(crate) fn new() -> Self {
        Self {
            values: Vec::with_capacity(WINDOW),
            next: 0,
            scratch: Vec::with_capacity(WINDOW),
        }
    }

    /// Adds one scan's χ² of each detection's nearest landmark (infinite
    /// where none is near, which is left out).
    pub(crate) fn observe(&mut self, nearest: &[f64]) {
        for &x in nearest.iter().filter(|x| x.is_finite()) {
            if self.values.len() < WINDOW {
                self.values.push(x);
            } else {
                self.values[self.next] = x;
            }
            self.next = (self.next + 1) % WINDOW;
        }
    }

    /// The variance scale the innovations show, never below 1: the joint
    /// test is only ever widened by it, so a log as noisy as assumed keeps
    /// its gates.
    pub(crate) fn scale(&mut self) -> f64 {
        if self.values.len() < MIN_VALUES {
            return 1.0;
        }
        self.scratch.clear();
        self.scratch.extend_from_slice(&self.values);
        let at = self.scratch.len() / 2;
        let (_, median, _) = self.scratch.select_nth_unstable_by(at, f64::total_cmp);
        (*median / CHI2_2_MEDIAN).clamp(1.0, MAX_SCALE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand::rngs::StdRng;
    use rand_distr::{ChiSquared, Distribution};

    /// The scale read from `scans` scans of six detections whose variance is
    /// `truth` times the assumed, cut at a gate of 25 as the front end's
    /// nearest χ², one in six a new cone with no landmark near.
    fn read(truth: f64, scans: usize) -> f64 {
        let mut rng = StdRng::seed_from_u64(11);
        let chi2 = ChiSquared::new(2.0).unwrap();
        let mut scale = InnovationScale::new();
        for _ in 0..scans {
            let mut scan: Vec<f64> = (0..5)
                .map(|_| truth * chi2.sample(&mut rng))
                .map(|x| if x > 25.0 { f64::INFINITY } else { x })
                .collect();
            scan.push(f64::INFINITY);
            scale.observe(&scan);
        }
        scale.scale()
    }

    #[test]
    fn it_reads_a_wider_detector_and_keeps_an_honest_one() {
        // The cut at 25 leaves the median at χ²₂'s 38th percentile when the
        // variance is 9 times the assumed (0.68 of the truth), at its 48th
        // when 4 times (0.94).
        for (truth, low) in [(4.0, 0.75), (9.0, 0.55)] {
            let read = read(truth, 40);
            assert!(read > low * truth && read < 1.2 * truth, "{truth}: {read}");
        }
        assert!(read(1.0, 40) < 1.2);
        assert_eq!(read(0.25, 40), 1.0);
        assert_eq!(InnovationScale::new().scale(), 1.0);
        let mut wide = InnovationScale::new();
        wide.observe(&[1e4; 8]);
        assert_eq!(wide.scale(), MAX_SCALE);
    }

    #[test]
    fn it_forgets_what_is_older_than_its_window() {
        let mut scale = InnovationScale::new();
        scale.observe(&[100.0; WINDOW]);
        scale.observe(&[CHI2_2_MEDIAN; WINDOW]);
        assert_eq!(scale.scale(), 1.0);
        scale.observe(&[f64::NAN; 3]);
        assert_eq!(scale.scale(), 1.0);
    }
}
