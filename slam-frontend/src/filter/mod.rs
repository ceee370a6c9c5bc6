//! The filters of the literature beside the graph: EKF-SLAM ([`ekf`]) and
//! FastSLAM 1.0 and 2.0 ([`fastslam`]). They read the same log as the graph
//! front end and share its motion models ([`crate::motion`]), its data
//! association ([`crate::frontend::association`]), its landmark bookkeeping
//! and lap detection ([`crate::sighting`]) and its localisation mode; their
//! measurement model is range and bearing.

mod closure;
pub mod ekf;
pub mod fastslam;
mod particle;
mod place;

use crate::color::Color;
use crate::files::Association;
use crate::frontend::align;
use crate::frontend::association::{Candidates, Correlation, Pair, associate};
use crate::frontend::dispersion::InnovationScale;
use crate::frontend::place_votes::PlaceVotes;
use crate::frontend::{Beside, FrontEndConfig, Mode, Timing, chi2_99};
use crate::log::{Detection, Record};
use crate::map::Cone;
use crate::motion::{Correction, Odometry};
use crate::sighting::{ColorRate, Sighting, hits_and_misses};
use cairn_core::SE2;
use cairn_core::se2::normalize_angle;
use nalgebra::{Matrix2, Matrix3, SMatrix, Vector2};
use std::collections::{HashMap, HashSet};

/// A landmark's predicted range and bearing from a pose, with Jacobians.
#[derive(Clone, Copy, Debug)]
pub struct RangeBearing {
    /// (range, bearing) in the vehicle frame.
    pub z: Vector2<f64>,
    /// ∂z/∂(x, y, θ) of the pose.
    pub h_pose: SMatrix<f64, 2, 3>,
    /// ∂z/∂(x, y) of the landmark.
    pub h_landmark: Matrix2<f64>,
}

/// Range and bearing of landmark `m` seen from `pose`; `None` when the
/// landmark sits on the vehicle's reference point.
pub fn predict(pose: &SE2, m: &Vector2<f64>) -> Option<RangeBearing> {
    let d = m - pose.t;
    let q = d.norm_squared();
    if q < 1e-12 {
        return None;
    }
    let r = q.sqrt();
    let h_landmark = Matrix2::new(d.x / r, d.y / r, -d.y / q, d.x / q);
    let mut h_pose = SMatrix::<f64, 2, 3>::zeros();
    h_pose
        .fixed_view_mut::<2, 2>(0, 0)
        .copy_from(&(-h_landmark));
    h_pose[(1, 2)] = -1.0;
    Some(RangeBearing {
        z: Vector2::new(r, normalize_angle(d.y.atan2(d.x) - pose.theta)),
        h_pose,
        h_landmark,
    })
}

/// The landmark a (range, bearing) measurement puts in the world, with its
/// Jacobians with respect to the pose and to the measurement.
pub fn landmark_from(
    pose: &SE2,
    z: &Vector2<f64>,
) -> (Vector2<f64>, SMatrix<f64, 2, 3>, Matrix2<f64>) {
    let (s, c) = (pose.theta + z.y).sin_cos();
    let m = pose.t + z.x * Vector2::new(c, s);
    let mut j_pose = SMatrix::<f64, 2, 3>::zeros();
    j_pose
        .fixed_view_mut::<2, 2>(0, 0)
        .copy_from(&Matrix2::identity());
    j_pose[(0, 2)] = -z.x * s;
    j_pose[(1, 2)] = z.x * c;
    let j_z = Matrix2::new(c, -z.x * s, s, z.x * c);
    (m, j_pose, j_z)
}

/// z − ẑ with the bearing wrapped to (−π, π].
pub fn innovation(z: &Vector2<f64>, predicted: &Vector2<f64>) -> Vector2<f64> {
    Vector2::new(z.x - predicted.x, normalize_angle(z.y - predicted.y))
}

/// A detection as (range, bearing) and its covariance: the log's when it
/// gives one (converted from the vehicle frame), else the assumed noise.
pub fn measurement(config: &FrontEndConfig, d: &Detection) -> (Vector2<f64>, Matrix2<f64>) {
    let (r, b) = d
        .range_bearing
        .unwrap_or_else(|| (d.position.norm(), d.position.y.atan2(d.position.x)));
    let cov = match d.covariance {
        Some(c) if r > 1e-9 => {
            // ∂(r, b)/∂(x, y) at the detection.
            let (s, co) = b.sin_cos();
            let j = Matrix2::new(co, s, -s / r, co / r);
            j * c * j.transpose()
        }
        _ => config.range_bearing_cov(r),
    };
    (Vector2::new(r, b), cov)
}

/// What a filter decides for one detection.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Choice {
    /// An existing landmark.
    Landmark(usize),
    /// Start a new landmark.
    New,
    /// Ignore the detection (ambiguous, spurious, or localising).
    Reject,
}

/// State every filter keeps about the run besides its estimate: settings,
/// mode, odometry, timings, the tracker, and known correspondences.
#[derive(Clone, Debug)]
struct Run {
    config: FrontEndConfig,
    mode: Mode,
    motion: Odometry,
    started: bool,
    start: SE2,
    scans: usize,
    timing: Timing,
    loop_closures: usize,
    /// Tracker id → landmark it was last associated with.
    tracker: HashMap<u64, usize>,
    /// (scan, detection) → true cone, when correspondences are known.
    known: Option<HashMap<(usize, usize), Option<usize>>>,
    /// True cone → landmark, when correspondences are known.
    known_landmark: HashMap<usize, usize>,
    /// A given map, until the car has been placed on it.
    unplaced: Option<Vec<(Vector2<f64>, Color)>>,
    /// Localising on a map given from outside, which stays fixed. A map the
    /// filter built itself is refined by every later sighting.
    map_given: bool,
    placement: align::Placement,
    /// The pose of the first scan, where a lap ends.
    first_pose: Option<SE2>,
    /// The scans' votes for where place recognition puts the car.
    place_votes: PlaceVotes,
    /// The first scan of the car's approach to the start, while on one.
    approach_scan: Option<usize>,
    colors: ColorRate,
    /// How much wider the innovations run than assumed, and the factor it
    /// gives JCBB's joint test (as the graph's, [`InnovationScale`]).
    innovation_scale: InnovationScale,
    joint_scale: f64,
}

impl Run {
    fn new(config: FrontEndConfig) -> Self {
        Self {
            motion: Odometry::new(config.motion, config.motion_noise())
                .with_scan_latency(config.scan_latency),
            colors: ColorRate::new(&config),
            config,
            mode: Mode::Mapping,
            started: false,
            start: SE2::identity(),
            scans: 0,
            timing: Timing::default(),
            loop_closures: 0,
            tracker: HashMap::new(),
            known: None,
            known_landmark: HashMap::new(),
            unplaced: None,
            map_given: false,
            placement: align::Placement::default(),
            first_pose: None,
            place_votes: PlaceVotes::default(),
            approach_scan: None,
            innovation_scale: InnovationScale::new(),
            joint_scale: 1.0,
        }
    }

    /// Learns from a scan's χ² of each detection's nearest landmark how much
    /// wider the innovations run than assumed; later scans' joint tests are
    /// widened by it.
    fn spread(&mut self, nearest: &[f64]) {
        self.innovation_scale.observe(nearest);
        self.joint_scale = self.innovation_scale.scale();
    }

    /// Localises on `map` from the first scan, once placed on it.
    fn start_on(&mut self, map: &[Cone]) {
        self.mode = Mode::Localising;
        self.map_given = true;
        self.unplaced = Some(map.iter().map(|c| (c.position, c.color)).collect());
    }

    /// Where the car stands on a given map it has not been placed on yet
    /// (`Ok(None)` when there is none, `Err` while the scan does not fit).
    fn place(&mut self, here: &SE2, cones: &[Detection]) -> Result<Option<SE2>, ()> {
        let Some(map) = &self.unplaced else {
            return Ok(None);
        };
        let pose = self.placement.try_place(map, cones, here).ok_or(())?;
        self.unplaced = None;
        Ok(Some(pose))
    }

    fn set_known(&mut self, truth: &[Association]) {
        self.known = Some(
            truth
                .iter()
                .map(|a| ((a.scan, a.det), a.landmark))
                .collect(),
        );
    }

    /// Takes in odometry and the start pose; returns a scan to process.
    fn next_scan<'a>(&mut self, record: &'a Record) -> Option<(f64, &'a [Detection])> {
        match record {
            Record::Start { pose, .. } if !self.started => {
                self.start = *pose;
                None
            }
            Record::Odom {
                t,
                v,
                yaw_rate,
                steer,
                vy,
            } => {
                self.motion
                    .record(*t, (*v, *vy), *yaw_rate, *steer, Correction::NONE);
                None
            }
            Record::Cones { t, cones } => {
                let t = self.motion.advance_to_scan(*t, Correction::NONE);
                self.colors.learn(cones, &mut self.config);
                self.started = true;
                Some((t, cones))
            }
            _ => None,
        }
    }

    /// The landmark each detection's tracker id pointed at, via `resolve`
    /// (which says whether that landmark still exists).
    fn tracked(&self, cones: &[Detection], alive: impl Fn(usize) -> bool) -> Vec<Option<usize>> {
        cones
            .iter()
            .map(|d| {
                d.id.and_then(|id| self.tracker.get(&id))
                    .copied()
                    .filter(|&l| alive(l))
            })
            .collect()
    }

    /// Chooses for every detection of `scan`. `nearest[i]` is the χ² of the
    /// nearest landmark even beyond the gate; `beside(i, taken)` says what
    /// lies within 0.8 m of detection `i` (`crate::frontend::beside`), `taken(l)`
    /// being whether landmark `l` explains a detection of the scan.
    fn choose(
        &self,
        scan: usize,
        candidates: &Candidates,
        nearest: &[f64],
        tracked: &[Option<usize>],
        correlation: Correlation,
        beside: impl Fn(usize, &dyn Fn(usize) -> bool) -> Beside,
    ) -> Vec<Choice> {
        if let Some(known) = &self.known {
            return (0..candidates.len())
                .map(|i| match known.get(&(scan, i)).copied().flatten() {
                    None => Choice::Reject,
                    Some(cone) => match self.known_landmark.get(&cone) {
                        Some(&l) => Choice::Landmark(l),
                        None if self.mode == Mode::Mapping => Choice::New,
                        None => Choice::Reject,
                    },
                })
                .collect();
        }
        let assigned = associate(
            self.config.association,
            candidates,
            tracked,
            |pairs| self.joint_scale * chi2_99(2 * pairs),
            correlation,
        );
        let mut taken = vec![false; assigned.iter().flatten().max().map_or(0, |&l| l + 1)];
        for &l in assigned.iter().flatten() {
            taken[l] = true;
        }
        assigned
            .iter()
            .enumerate()
            .map(|(i, a)| match a {
                Some(l) => Choice::Landmark(*l),
                None if self.mode == Mode::Mapping => {
                    let taken = |l: usize| taken.get(l).copied().unwrap_or(false);
                    let clear = match beside(i, &taken) {
                        Beside::Nothing => nearest[i] > self.config.new_landmark_gate,
                        Beside::TakenOnly => nearest[i] > self.config.gate,
                        Beside::Free => false,
                    };
                    if clear { Choice::New } else { Choice::Reject }
                }
                None => Choice::Reject,
            })
            .collect()
    }

    /// Records that detection `i` of `scan` became `landmark`: its tracker
    /// id points there now, and so does its true cone when correspondences
    /// are known.
    fn remember(&mut self, scan: usize, i: usize, d: &Detection, landmark: usize) {
        if let Some(id) = d.id {
            self.tracker.insert(id, landmark);
        }
        if let Some(cone) = self
            .known
            .as_ref()
            .and_then(|k| k.get(&(scan, i)).copied().flatten())
        {
            self.known_landmark.insert(cone, landmark);
        }
    }

    /// Times a scan update that began with `closures` loop closures: every
    /// update, and those that closed a loop, whole, as loop closures.
    fn record_update(&mut self, seconds: f64, closures: usize) {
        self.timing.updates.push(seconds);
        if self.loop_closures > closures {
            self.timing.loop_closures.push(seconds);
        }
    }

    /// Counts a loop closure and switches to localisation if configured.
    fn close_loop(&mut self) {
        self.loop_closures += 1;
        self.place_votes.clear();
        if self.config.localise_after_loop {
            self.mode = Mode::Localising;
        }
    }
}

/// A landmark as the association sees it.
struct Landmark<'a> {
    mean: Vector2<f64>,
    cov: Matrix2<f64>,
    /// Covariance with the pose, P_rm.
    cross: SMatrix<f64, 3, 2>,
    sighting: &'a Sighting,
}

/// The landmark's share of the innovation covariance, cross terms included.
fn s_landmark(pred: &RangeBearing, lm: &Landmark) -> Matrix2<f64> {
    let cross = pred.h_pose * lm.cross * pred.h_landmark.transpose();
    pred.h_landmark * lm.cov * pred.h_landmark.transpose() + cross + cross.transpose()
}

/// Candidates against landmarks given as (index, mean, covariance,
/// bookkeeping), for detections as (range, bearing) with covariances, seen
/// from `pose` with covariance `pose_cov`. Also returns each detection's
/// nearest χ² even beyond the gate (the colour penalty included; the gate
/// itself is on the position alone). `cross` is the landmark's covariance
/// with the pose (P_rm, zero for FastSLAM), so the innovation covariance is
/// the joint one: Hₚ P_rr Hₚᵀ + Hₘ P_mm Hₘᵀ + Hₚ P_rm Hₘᵀ + (…)ᵀ + R.
fn candidates<'a>(
    config: &FrontEndConfig,
    pose: &SE2,
    pose_cov: &Matrix3<f64>,
    measurements: &[(Vector2<f64>, Matrix2<f64>)],
    cones: &[Detection],
    landmarks: impl Iterator<Item = (usize, Landmark<'a>)>,
) -> (Candidates, Vec<f64>) {
    let reach = config.max_range + 5.0;
    let nearby: Vec<_> = landmarks
        .filter(|(_, lm)| (lm.mean - pose.t).norm() < reach)
        .filter_map(|(l, lm)| Some((l, predict(pose, &lm.mean)?, lm)))
        .collect();
    measurements
        .iter()
        .zip(cones)
        .map(|((z, r), d)| {
            let mut pairs: Vec<Pair> = nearby
                .iter()
                .filter_map(|(l, pred, lm)| {
                    let nu = innovation(z, &pred.z);
                    // Far outside any gate: skip the 2×2 algebra.
                    if nu.x.abs() > 4.0 || nu.y.abs() > 0.6 {
                        return None;
                    }
                    let penalty = if lm.sighting.contradicts(d.color) {
                        config.color_penalty
                    } else {
                        0.0
                    };
                    Pair::new(
                        *l,
                        nu,
                        pred.h_pose,
                        r,
                        &s_landmark(pred, lm),
                        pose_cov,
                        penalty,
                        config.new_landmark_gate,
                    )
                })
                .collect();
            pairs.sort_by(|a, b| a.d2.total_cmp(&b.d2));
            let nearest = pairs.first().map_or(f64::INFINITY, |p| p.d2);
            // The gate is the position's: a contradicting colour ranks a
            // pair lower but does not drop it (a cone read in the wrong
            // colour had gone unmatched whenever its χ² exceeded the gate
            // less the penalty, about a fifth of the time).
            pairs.retain(|p| p.within(config.gate));
            (pairs, nearest)
        })
        .unzip()
}

/// The landmarks that colours and detections over the whole run call
/// clutter ([`Sighting::is_clutter`], as the graph judges its map at the
/// end of the run): leaning to clutter by their colours, and in view from
/// many of the (scan, pose) `poses` whose scans `matched` (scan, landmark)
/// does not pair them with. A filter has no final poses: these are its
/// estimates as it went, so a landmark's colours must lean to clutter
/// before its misses count, and a cone's never do.
fn judged_clutter<'a>(
    config: &FrontEndConfig,
    poses: &[(usize, SE2)],
    matched: impl IntoIterator<Item = (usize, usize)>,
    landmarks: impl IntoIterator<Item = (usize, Vector2<f64>, &'a Sighting)>,
) -> HashSet<usize> {
    let mut seen: HashMap<usize, Vec<usize>> = HashMap::new();
    for (scan, l) in matched {
        seen.entry(l).or_default().push(scan);
    }
    for scans in seen.values_mut() {
        scans.sort_unstable();
    }
    let inverses: Vec<(usize, SE2)> = poses.iter().map(|(k, p)| (*k, p.inverse())).collect();
    landmarks
        .into_iter()
        .filter(|(_, _, sighting)| sighting.clutter_log_odds(config) > 0.0)
        .filter(|(l, mean, sighting)| {
            let scans = seen.get(l).map_or(&[][..], Vec::as_slice);
            let in_view = inverses.iter().map(|(k, inverse)| (*k, inverse));
            let (hits, misses) = hits_and_misses(config, in_view, mean, scans);
            sighting.is_clutter(hits, misses, config)
        })
        .map(|(l, _, _)| l)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Central differences of `f` at `x` along each coordinate.
    fn numeric<const N: usize, const M: usize>(
        x: SMatrix<f64, N, 1>,
        f: impl Fn(SMatrix<f64, N, 1>) -> SMatrix<f64, M, 1>,
    ) -> SMatrix<f64, M, N> {
        let h = 1e-6;
        SMatrix::from_fn(|i, j| {
            let mut a = x;
            let mut b = x;
            a[j] += h;
            b[j] -= h;
            let d = f(a) - f(b);
            // Bearings wrap; the difference of two nearby bearings does not.
            let d = if M == 2 && i == 1 {
                normalize_angle(d[i])
            } else {
                d[i]
            };
            d / (2.0 * h)
        })
    }

    proptest! {
        #[test]
        fn range_bearing_jacobians_match_differences(
            x in -20.0..20.0f64, y in -20.0..20.0f64, th in -3.1..3.1f64,
            mx in -20.0..20.0f64, my in -20.0..20.0f64,
        ) {
            let pose = SE2::new(x, y, th);
            let m = Vector2::new(mx, my);
            prop_assume!((m - pose.t).norm() > 0.5);
            let pred = predict(&pose, &m).unwrap();
            let by_pose = numeric(pose.to_vector(), |p| predict(&SE2::from_vector(&p), &m).unwrap().z);
            let by_landmark = numeric(m, |m| predict(&pose, &m).unwrap().z);
            prop_assert!((pred.h_pose - by_pose).abs().max() < 1e-5, "{} vs {}", pred.h_pose, by_pose);
            prop_assert!((pred.h_landmark - by_landmark).abs().max() < 1e-5);
        }

        #[test]
        fn inverse_measurement_jacobians_match_differences(
            x in -20.0..20.0f64, y in -20.0..20.0f64, th in -3.1..3.1f64,
            r in 0.5..15.0f64, b in -1.5..1.5f64,
        ) {
            let pose = SE2::new(x, y, th);
            let z = Vector2::new(r, b);
            let (m, j_pose, j_z) = landmark_from(&pose, &z);
            // The landmark seen from the pose gives the measurement back.
            let back = predict(&pose, &m).unwrap().z;
            prop_assert!((back - z).norm() < 1e-9);
            let by_pose = numeric(pose.to_vector(), |p| landmark_from(&SE2::from_vector(&p), &z).0);
            let by_z = numeric(z, |z| landmark_from(&pose, &z).0);
            prop_assert!((j_pose - by_pose).abs().max() < 1e-5);
            prop_assert!((j_z - by_z).abs().max() < 1e-5);
        }
    }

    #[test]
    fn a_contradicting_colour_ranks_a_pair_lower_but_is_no_gate() {
        let config = FrontEndConfig::default();
        let mut sighting = Sighting::new(Color::Yellow, 0, 0.0, 0.0);
        for _ in 0..4 {
            sighting.count(Color::Yellow, 3);
        }
        let landmark = || {
            let lm = Landmark {
                mean: Vector2::new(10.0, 0.0),
                cov: Matrix2::zeros(),
                cross: SMatrix::zeros(),
                sighting: &sighting,
            };
            std::iter::once((0, lm))
        };
        // Blue detections of the yellow landmark, their range off by √χ²
        // times its σ there (σ = a + b·r): within the gate by position,
        // and beyond it.
        let (a, b) = (config.range_sigma, config.range_sigma_relative);
        let detection = |chi2: f64| {
            let k = chi2.sqrt();
            let r = (10.0 + a * k) / (1.0 - b * k);
            let d = Detection {
                position: Vector2::new(r, 0.0),
                range_bearing: Some((r, 0.0)),
                color: Color::Blue,
                id: None,
                covariance: None,
            };
            (measurement(&config, &d), d)
        };
        let gate = config.gate;
        let (inside, beyond) = (detection(gate - 1.0), detection(gate + 1.0));
        let (pose, pose_cov) = (SE2::identity(), Matrix3::zeros());
        let (pairs, nearest) = candidates(
            &config,
            &pose,
            &pose_cov,
            &[inside.0, beyond.0],
            &[inside.1, beyond.1],
            landmark(),
        );
        assert!(config.color_penalty > 1.0);
        let expected = gate - 1.0 + config.color_penalty;
        assert_eq!(pairs[0].len(), 1, "{pairs:?}");
        assert!((pairs[0][0].d2 - expected).abs() < 1e-6, "{pairs:?}");
        assert!((nearest[0] - expected).abs() < 1e-6);
        assert!(pairs[1].is_empty(), "{pairs:?}");
    }

    #[test]
    fn a_measurement_converts_a_logged_covariance_to_range_and_bearing() {
        let config = FrontEndConfig::default();
        let d = Detection {
            position: Vector2::new(0.0, 4.0),
            range_bearing: None,
            color: Color::Blue,
            id: None,
            covariance: Some(Matrix2::new(0.09, 0.0, 0.0, 0.01)),
        };
        let (z, cov) = measurement(&config, &d);
        assert!((z - Vector2::new(4.0, std::f64::consts::FRAC_PI_2)).norm() < 1e-12);
        // Straight to the left: range is y (σ² 0.01), bearing is −x / r.
        assert!((cov[(0, 0)] - 0.01).abs() < 1e-12, "{cov}");
        assert!((cov[(1, 1)] - 0.09 / 16.0).abs() < 1e-12, "{cov}");
    }
}
