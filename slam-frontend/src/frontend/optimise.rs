//! The full optimisation after a loop closure: every pose and confirmed
//! landmark on Cairn's solver, with the gyro's yaw-rate bias estimated
//! beside the poses, then duplicate landmarks merged.

use super::bias::{OdometryBias, PoseBias, SightingBias, StartPrior};
use super::bias_walk::Drift;
use super::{GraphSlam, Observation, OdometryEdge, OptimiseError};
use cairn_core::se2::normalize_angle;
use cairn_core::{EdgeSE2XY, Graph, RobustKernel, SE2};
use cairn_solvers::{Initialization, Optimizer, SolverConfig};
use nalgebra::Vector2;
use std::collections::HashMap;

impl GraphSlam {
    /// Full optimisation of the pose/landmark graph on Cairn's solver, as
    /// `batch` says: every `stride`-th pose (the poses between follow the
    /// one before them) and at most `sightings` sightings per landmark.
    /// Where the solved headings show the gyro's bias wandering more than
    /// twice as fast as assumed, the walk learnt is kept and the graph solved
    /// again with it. The scan latency is learnt once, in the first solve
    /// `batch` allows it; a latency the log does not show is solved again
    /// without.
    pub(super) fn optimise(&mut self, batch: Batch) -> Result<(), OptimiseError> {
        for _ in 0..MAX_SOLVES {
            let used = self.calibration.yaw_rate_bias_walk;
            let learn = batch.covariances
                && self.config.learn_scan_latency
                && self.calibration.scan_latency_sigma.is_none();
            let kept = self.solve_full(batch, learn)?;
            if kept && self.calibration.yaw_rate_bias_walk <= RESOLVE_WALK * used {
                break;
            }
        }
        Ok(())
    }

    /// One full optimisation, after which the bias walk the solution shows is
    /// learnt; with `learn_latency`, the scan latency beside the poses.
    /// Returns whether the solution stands: false where a latency was
    /// solved for and the log did not show it.
    fn solve_full(&mut self, batch: Batch, learn_latency: bool) -> Result<bool, OptimiseError> {
        let n = self.poses.len();
        if n == 0 {
            return Ok(true);
        }
        let stride = batch.stride.max(1);
        // The kept poses: every stride-th and the last.
        let is_kept = |k: usize| k.is_multiple_of(stride) || k + 1 == n;
        let kept: Vec<usize> = (0..n).filter(|&k| is_kept(k)).collect();
        let mut graph = Graph::new();
        let mut add = || -> Result<Vec<Option<i64>>, cairn_core::GraphError> {
            // Each pose carries the yaw-rate bias, starting from the
            // calibration its odometry was integrated with.
            for &k in &kept {
                let bias = self
                    .odometry
                    .get(k)
                    .or(self.odometry.last())
                    .map_or(0.0, |o| o.yaw_rate_bias);
                let pose = self.poses[k].pose;
                let latency = 0.0;
                graph.add_vertex(
                    k as i64,
                    PoseBias {
                        pose,
                        bias,
                        latency,
                    },
                )?;
            }
            let start = graph.value::<PoseBias, 5>(0)?;
            graph.add_unary_edge(0, StartPrior(start), StartPrior::information())?;
            for pair in kept.windows(2) {
                let (a, b) = (pair[0], pair[1]);
                let (edge, info) = OdometryBias::new(
                    &OdometryEdge::chain(&self.odometry[a..b]),
                    self.calibration.yaw_rate_bias_walk,
                );
                graph.add_edge(a as i64, b as i64, edge, info)?;
            }
            // A cone is seen from dozens of poses (hundreds on tight tracks);
            // sightings spread over its history keep the Hessian sparse.
            let mut by_landmark: Vec<Vec<&Observation>> = vec![Vec::new(); self.landmarks.len()];
            for o in self.observations.iter().filter(|o| is_kept(o.pose)) {
                by_landmark[self.resolve(o.landmark)].push(o);
            }
            let mut vertex = vec![None; self.landmarks.len()];
            let mut chosen = Vec::new();
            for (l, lm) in self.landmarks.iter().enumerate() {
                if !self.in_map(l) || by_landmark[l].is_empty() {
                    continue;
                }
                let v = (n + l) as i64;
                vertex[l] = Some(v);
                graph.add_vertex(v, lm.mean)?;
                batch.choose(&by_landmark[l], &mut chosen);
                for o in &chosen {
                    let (speed, yaw_rate) = if learn_latency {
                        self.motion_at(o.pose)
                    } else {
                        (0.0, 0.0)
                    };
                    let sighting = EdgeSE2XY::new(o.z);
                    let edge = SightingBias {
                        sighting,
                        speed,
                        yaw_rate,
                    };
                    let e = graph.add_edge(o.pose as i64, v, edge, o.information)?;
                    if batch.robust {
                        graph.set_robust_kernel(e, Some(RobustKernel::Cauchy(CAUCHY_DELTA)));
                    }
                }
            }
            Ok(vertex)
        };
        let vertex = add()?;
        let mut config = SolverConfig {
            max_iterations: batch.iterations,
            relative_decrease: 1e-3,
            init: Initialization::File,
            ..SolverConfig::default()
        };
        // Landmarks seen from many poses give dense fronts; faer's automatic
        // choice picks the slower simplicial factorisation here.
        config.linear.factorization = cairn_solvers::Factorization::Supernodal;
        let mut optimizer = Optimizer::new(&graph, config)?;
        optimizer.optimize(&mut graph)?;
        // A lap that drifted far is linearised far from its optimum, and one
        // step leaves it short: it goes on to `far_iterations`.
        if batch.far_iterations > batch.iterations {
            let last = graph.value::<PoseBias, 5>(n as i64 - 1)?.pose;
            let shift = self.poses[n - 1].pose.inverse().compose(&last);
            if shift.t.norm() > FAR.0 || shift.theta.abs() > FAR.1 {
                let mut config = optimizer.config().clone();
                config.max_iterations = batch.far_iterations - batch.iterations;
                optimizer.set_config(config);
                optimizer.optimize(&mut graph)?;
            }
        }
        // The latency is judged before the landmarks' covariances are
        // taken: a solve that does not stand is made again, and takes them.
        let mut stands = true;
        if learn_latency {
            let last = n as i64 - 1;
            let late = graph.value::<PoseBias, 5>(last)?.latency;
            let marginal = optimizer.marginals(&graph, &[last]);
            let sigma = marginal.map_or(f64::INFINITY, |m| m[0][(4, 4)].max(0.0).sqrt());
            stands = self.judge_latency(late, sigma);
        }
        if batch.covariances && stands {
            self.take_marginals(&mut optimizer, &graph, &vertex);
        }
        self.learn_bias_walk(&graph, &kept)?;
        // Poses between kept ones move with the kept pose before them.
        let mut moved = SE2::identity();
        for k in 0..n {
            if is_kept(k) {
                let new = graph.value::<PoseBias, 5>(k as i64)?.pose;
                moved = new.compose(&self.poses[k].pose.inverse());
                self.poses[k].pose = new;
            } else {
                self.poses[k].pose = moved.compose(&self.poses[k].pose);
            }
        }
        // The bias the whole lap fits is better than the online estimate
        // (within 3e-4 rad/s on the `standard` preset: slam tests).
        self.calibration.yaw_rate_bias = graph.value::<PoseBias, 5>(n as i64 - 1)?.bias;
        self.window.set_bias(self.calibration.yaw_rate_bias, 3e-4);
        for (l, v) in vertex.iter().enumerate() {
            if let Some(v) = v {
                self.landmarks[l].mean = graph.value(*v)?;
            }
        }
        if let Some(last) = self.poses.last() {
            self.pose = last.pose;
        }
        self.refold();
        self.merge_duplicates();
        Ok(stands)
    }

    /// Learns the bias's random walk from the solved headings of `kept`
    /// (the walk only grows: the config's value is the least assumed).
    fn learn_bias_walk(&mut self, graph: &Graph, kept: &[usize]) -> Result<(), OptimiseError> {
        if !self.config.learn_yaw_rate_bias_walk {
            return Ok(());
        }
        let mut d = Drift {
            times: vec![0.0],
            drift: vec![0.0],
            white: vec![0.0],
        };
        let (mut t, mut sum, mut white) = (0.0, 0.0, 0.0);
        for pair in kept.windows(2) {
            let a = graph.value::<PoseBias, 5>(pair[0] as i64)?;
            let b = graph.value::<PoseBias, 5>(pair[1] as i64)?;
            let o = OdometryEdge::chain(&self.odometry[pair[0]..pair[1]]);
            // The turn beyond the raw gyro's (the online bias estimate put
            // back); the second differences cancel a constant bias.
            let turn = normalize_angle(b.pose.theta - a.pose.theta);
            let gyro = o.delta.theta + o.yaw_rate_bias * o.dt;
            sum += normalize_angle(turn - gyro);
            t += o.dt;
            white += o.heading_variance;
            d.times.push(t);
            d.drift.push(sum);
            d.white.push(white);
        }
        if let Some(walk) = d.walk() {
            let learnt = &mut self.calibration.yaw_rate_bias_walk;
            *learnt = learnt.max(walk.min(MAX_BIAS_WALK));
        }
        Ok(())
    }

    /// Each landmark's covariance from the graph's marginals: its position's
    /// uncertainty in the world frame, the start pose given, where the EKF's
    /// is relative to the poses that saw it. On epfl_fsds_competition_1
    /// (`standard`, 50 seeds) the far cones' marginals, which carry the
    /// heading's drift, predict a map RMSE of 0.106 m; the maps' is 0.120 m
    /// (NEES 2.4, where the EKF's covariances gave about 250).
    /// One selected inversion gives them all (with the linearisation and
    /// factorisation it needs): 220–260 ms of the final optimisation's
    /// 0.8–1.0 s on the 828 m hairpins track (986 landmarks), 9 ms of 41 ms
    /// on epfl_fsds_competition_1. A failed factorisation leaves the EKF's.
    fn take_marginals(&mut self, optimizer: &mut Optimizer, graph: &Graph, vertex: &[Option<i64>]) {
        let ids: Vec<i64> = vertex.iter().flatten().copied().collect();
        let Ok(marginals) = optimizer.marginals(graph, &ids) else {
            return;
        };
        let mut marginals = marginals.into_iter();
        for (l, v) in vertex.iter().enumerate() {
            if v.is_some()
                && let Some(m) = marginals.next()
            {
                self.landmarks[l].cov = m.fixed_view::<2, 2>(0, 0).into_owned();
            }
        }
    }

    /// Landmarks of one colour closer than [`MERGE_RADIUS`] are one cone seen twice
    /// (typically once per lap before the loop closed), unless one scan saw
    /// both: then they are two cones, like the start's big orange pairs.
    fn merge_duplicates(&mut self) {
        let live = self.map_rows();
        let points: Vec<(usize, Vector2<f64>)> =
            live.iter().map(|&l| (l, self.landmarks[l].mean)).collect();
        let close: Vec<(usize, usize)> = pairs_within(&points, MERGE_RADIUS)
            .into_iter()
            .filter(|&(a, b)| {
                let (ca, cb) = (
                    self.landmarks[a].sighting.color(),
                    self.landmarks[b].sighting.color(),
                );
                ca.compatible(cb)
            })
            .collect();
        if close.is_empty() {
            return;
        }
        let mut scans = self.scans_seeing(&close);
        for &(a, b) in &close {
            // A merge earlier in this loop may have made either the other's
            // twin; its scans go with it (a landmark a later lap started
            // beside a big orange pair was merged into one cone, then the
            // pair's other cone, never seen together with it, into the same).
            let (a, b) = (self.resolve(a), self.resolve(b));
            if a == b || shares_a_scan(&scans[&a], &scans[&b]) {
                continue;
            }
            let (keep, drop) = if self.landmarks[a].sighting.seen >= self.landmarks[b].sighting.seen
            {
                (a, b)
            } else {
                (b, a)
            };
            self.absorb(keep, drop);
            let mut merged = scans.remove(&drop).unwrap_or_default();
            merged.extend_from_slice(&scans[&keep]);
            merged.sort_unstable();
            scans.insert(keep, merged);
        }
    }

    /// Makes landmark `drop` an alias of `keep`, which takes its colour
    /// votes and sightings.
    pub(super) fn absorb(&mut self, keep: usize, drop: usize) {
        let dropped = self.landmarks[drop].sighting.clone();
        let kept = &mut self.landmarks[keep].sighting;
        for k in 0..5 {
            kept.votes[k] += dropped.votes[k];
        }
        kept.seen += dropped.seen;
        self.alias[drop] = keep;
    }

    /// The scans that matched a detection to each landmark of `pairs`, in
    /// ascending order (from the association record, which is in scan order).
    pub(super) fn scans_seeing(&self, pairs: &[(usize, usize)]) -> HashMap<usize, Vec<usize>> {
        let mut scans: HashMap<usize, Vec<usize>> = pairs
            .iter()
            .flat_map(|&(a, b)| [(a, Vec::new()), (b, Vec::new())])
            .collect();
        for &(scan, _, landmark) in &self.detections {
            if let Some(list) = landmark.and_then(|l| scans.get_mut(&self.resolve(l))) {
                list.push(scan);
            }
        }
        scans
    }
}

/// Whether two ascending lists share an element.
pub(super) fn shares_a_scan(a: &[usize], b: &[usize]) -> bool {
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => return true,
        }
    }
    false
}

/// The pairs `(a, b)`, a < b, of the labelled points closer than `radius`,
/// sorted: a sweep along x instead of comparing every pair (a thousand
/// landmarks on a long track).
pub(super) fn pairs_within(points: &[(usize, Vector2<f64>)], radius: f64) -> Vec<(usize, usize)> {
    let mut by_x: Vec<&(usize, Vector2<f64>)> = points.iter().collect();
    by_x.sort_unstable_by(|a, b| a.1.x.total_cmp(&b.1.x));
    let mut pairs = Vec::new();
    for (i, &&(a, pa)) in by_x.iter().enumerate() {
        for &&(b, pb) in &by_x[i + 1..] {
            if pb.x - pa.x >= radius {
                break;
            }
            if (pa - pb).norm() < radius {
                pairs.push((a.min(b), a.max(b)));
            }
        }
    }
    pairs.sort_unstable();
    pairs
}

/// Landmarks of compatible colours closer than this after a loop closure are one cone (m).
pub(crate) const MERGE_RADIUS: f64 = 0.7;

/// Range (m) within which the loop closure takes a landmark's sightings.
/// Cones seen across a hairpin from 10–15 m couple poses of different legs
/// and fill the factor; the near sightings carry most of the information
/// (the noise grows with range), and the final optimisation takes them
/// all. On the hairpins (seed 0, maximum likelihood) the factor shrank from
/// 506,000 to 231,000 non-zeros and the loop closure from 25 to 14 ms run
/// alone; 15 tracks × 5 seeds × 4 methods gave the same final map RMSE
/// and association (`standard` 0.080–0.081 m and 99.74–99.97% against
/// 0.080–0.081 m and 99.75–99.97%; `hard` 0.137–0.181 m, 97.19–99.49%
/// against 0.139–0.181 m, 97.20–99.48%). Without the latest sighting the
/// loops closed on far sightings of the start area came apart (epfl
/// competition 1: association 44%).
const NEAR_SIGHTING: f64 = 8.0;

/// Sightings per landmark in the optimisation at a loop closure, spread
/// over the landmark's history. The final optimisation takes them all, so
/// the loop closure only has to give the later laps a map to localise on:
/// on 15 tracks × 10 seeds, both presets, 8, 12, 16 and 24 sightings gave
/// the same final map RMSE (0.0762 / 0.1635 m), association (99.84% /
/// 97.5% of detections) and closures (150 / 149), per track within 0.06
/// points; the longest loop closure (hairpins, run alone) took 15, 18, 21
/// and 23 ms. (Before the final optimisation took every sighting, 12 cost
/// accuracy: 0.188 against 0.144 m with 24.)
pub(super) const MAX_SIGHTINGS: usize = 8;

/// A learnt bias walk this many times the one a solve assumed is solved
/// again with.
const RESOLVE_WALK: f64 = 2.0;

/// Solves, at most, of one optimisation as the walk learnt grows (a walk
/// assumed too small flattens the drift it is learnt from).
const MAX_SOLVES: usize = 3;

/// The largest bias walk learnt (rad/s/√s): 0.06 rad/s after an hour.
const MAX_BIAS_WALK: f64 = 1e-3;

/// How much of the graph a full optimisation takes.
#[derive(Clone, Copy, Debug)]
pub(super) struct Batch {
    /// Every how many poses one is optimised.
    pub stride: usize,
    /// Sightings per landmark, at most.
    pub sightings: usize,
    /// Gauss–Newton iterations, at most.
    pub iterations: usize,
    /// Iterations, at most, when the first moved the last pose by more
    /// than [`FAR`].
    pub far_iterations: usize,
    /// Sightings farther than this (m) are left out of a landmark seen at
    /// least twice nearer, all but its latest.
    pub near: f64,
    /// Sightings under a Cauchy kernel, so that the few wrong associations
    /// pull less. Only once the map holds together: at a loop closure the
    /// large residuals are the lap's drift, which the kernel would keep.
    pub robust: bool,
    /// Whether the landmarks take their covariances from the optimised
    /// graph's marginals: the run's last optimisation, which also learns the
    /// scan latency (with the config's `learn_scan_latency`), once the
    /// detector's noise has been read from the map (a noise assumed too
    /// small makes a latency seem certain) and with nothing left to match
    /// the moved sightings again.
    pub covariances: bool,
}

/// The Cauchy kernel's δ on the sightings' √χ²: √5.99, the 95% quantile of
/// χ² with 2 degrees of freedom. On 15 tracks × 10 seeds (final map RMSE)
/// it took `hard` from 0.201 to 0.163 m and `standard` from 0.078 to
/// 0.076 m; Huber gave 0.175 and 0.077 m, and a Cauchy kernel at the loop
/// closure too lost association (98.19% → 96.61% on `hard`).
const CAUCHY_DELTA: f64 = 2.45;

/// How far (m, rad) the first iteration must move the last pose for the
/// optimisation to go on to [`Batch::far_iterations`].
const FAR: (f64, f64) = (1.0, 0.017);

impl Batch {
    /// At a loop closure, in the real-time loop: every 4th pose (every 8th
    /// when the end of the run matches everything again in hindsight),
    /// [`MAX_SIGHTINGS`] sightings per landmark and one Gauss–Newton step from the
    /// smoother's estimate. The final optimisation refines it all, so the
    /// loop closure only has to give the later laps a good map. Measured on
    /// 15 tracks × 10 seeds (standard preset, final map RMSE and
    /// association; longest loop closure, on the 828 m hairpins track run
    /// alone): every pose and up to 10 steps 0.081 m, 99.36%, 160 ms; every
    /// 4th pose 0.080 m, 99.36%; and one step 0.080 m, 99.36%, 50 ms; every
    /// 8th pose 0.079 m but 99.22%. The second step lowered χ² by 0.01%
    /// (44441 → 44436 on the hairpins). Matched again in hindsight, every
    /// 8th pose gives the same association as every 4th (15 tracks × 5
    /// seeds, tracking: 99.97% and 99.48% against 99.49% `hard`) and halves
    /// the hairpins' loop closure (20–33 → 12–16 ms run alone); without it,
    /// maximum likelihood lost 99.83 → 99.71% `standard`. Matched again
    /// alone, the other methods keep their association too (15 tracks × 10
    /// seeds: `standard` 99.82–99.83%, both strides; `hard` maximum
    /// likelihood 98.40 → 98.39%, SCNN 98.23 → 98.21%, JCBB 97.99 → 98.28%)
    /// and maximum likelihood's loop closure on the hairpins, run alone,
    /// goes from 11.0 to 7.1 ms (5 seeds). A lap that drifted metres (the
    /// `hard` preset on the large tracks) needs more: after one step the
    /// car was still 2 m off on random track 1 seed 7, so when the step
    /// moves the last pose by more than [`FAR`] it goes on to 10 (`hard`,
    /// 15 tracks × 10 seeds: association 97.92% → 98.19%; `standard`
    /// unchanged, the hairpins never go on).
    pub fn loop_closure(hindsight: bool) -> Self {
        Self {
            stride: if hindsight { 8 } else { 4 },
            sightings: MAX_SIGHTINGS,
            near: NEAR_SIGHTING,
            iterations: 1,
            far_iterations: 10,
            robust: false,
            covariances: false,
        }
    }

    /// At the end of the run: everything, the sightings robust; with
    /// `covariances` the landmarks' covariances from the result.
    pub fn last(covariances: bool) -> Self {
        Self {
            stride: 1,
            sightings: usize::MAX,
            near: f64::INFINITY,
            iterations: 10,
            far_iterations: 10,
            robust: true,
            covariances,
        }
    }
}

impl Batch {
    /// The sightings of one landmark (in pose order) to optimise, into
    /// `chosen`: at most [`Self::sightings`], spread over the landmark's
    /// history and its sightings nearer than [`Self::near`] if there are
    /// two, and always its latest, which at a loop closure is the one that
    /// closes it.
    fn choose<'a>(&self, list: &[&'a Observation], chosen: &mut Vec<&'a Observation>) {
        chosen.clear();
        let Some(&latest) = list.last() else { return };
        let near: Vec<&'a Observation> = list
            .iter()
            .copied()
            .filter(|o| o.z.norm() <= self.near)
            .collect();
        let pool = if near.len() >= 2 { &near[..] } else { list };
        let latest_is_far = !std::ptr::eq(pool[pool.len() - 1], latest);
        let room = self.sightings.saturating_sub(usize::from(latest_is_far));
        chosen.extend(spread(pool, room).copied());
        if latest_is_far {
            chosen.push(latest);
        }
    }
}

/// At most `k` items of `list`, evenly spread and including both ends.
fn spread<'a, T>(list: &'a [T], k: usize) -> impl Iterator<Item = &'a T> + 'a {
    let n = list.len();
    let take = n.min(k);
    (0..take).map(move |i| {
        let index = if take <= 1 {
            n - 1
        } else {
            i * (n - 1) / (take - 1)
        };
        &list[index]
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng, rngs::StdRng};

    #[test]
    fn the_sweep_finds_the_same_close_pairs_as_comparing_every_pair() {
        let mut rng = StdRng::seed_from_u64(3);
        for _ in 0..100 {
            let n = rng.random_range(0..60);
            // Labels out of order, points in a few metres, some on one x.
            let points: Vec<(usize, Vector2<f64>)> = (0..n)
                .map(|i| {
                    let x = (rng.random_range(0.0..6.0) * 4.0_f64).round() / 4.0;
                    ((i * 7) % 61, Vector2::new(x, rng.random_range(0.0..3.0)))
                })
                .collect();
            let mut every = Vec::new();
            for (i, &(a, pa)) in points.iter().enumerate() {
                for &(b, pb) in &points[i + 1..] {
                    if (pa - pb).norm() < MERGE_RADIUS {
                        every.push((a.min(b), a.max(b)));
                    }
                }
            }
            every.sort_unstable();
            assert_eq!(pairs_within(&points, MERGE_RADIUS), every);
        }
    }

    /// Sightings of one landmark from poses 0, 1, … at these ranges (m).
    fn sightings(ranges: &[f64]) -> Vec<Observation> {
        ranges
            .iter()
            .enumerate()
            .map(|(pose, &r)| Observation {
                pose,
                landmark: 0,
                z: Vector2::new(0.6 * r, 0.8 * r),
                information: nalgebra::Matrix2::identity(),
            })
            .collect()
    }

    fn chosen_poses(batch: &Batch, ranges: &[f64]) -> Vec<usize> {
        let list = sightings(ranges);
        let refs: Vec<&Observation> = list.iter().collect();
        let mut chosen = Vec::new();
        batch.choose(&refs, &mut chosen);
        chosen.iter().map(|o| o.pose).collect()
    }

    #[test]
    fn a_loop_closure_takes_near_sightings_spread_out_and_the_latest() {
        let batch = Batch {
            sightings: 4,
            ..Batch::loop_closure(false)
        };
        let near = NEAR_SIGHTING - 1.0;
        let far = NEAR_SIGHTING + 4.0;
        // Seen far across a hairpin, then near along its own leg, then far
        // again as the loop closes: the near ones, and the one closing it.
        let ranges = [far, far, near, near, near, near, near, far, far];
        assert_eq!(chosen_poses(&batch, &ranges), vec![2, 4, 6, 8]);
        // Ending near, the latest is among the near ones.
        let ranges = [far, near, near, near, near, near, near];
        assert_eq!(chosen_poses(&batch, &ranges), vec![1, 2, 4, 6]);
        // Fewer than two near: spread over all of them.
        let ranges = [far, far, near, far, far, far, far];
        assert_eq!(chosen_poses(&batch, &ranges), vec![0, 2, 4, 6]);
        assert_eq!(chosen_poses(&batch, &[far]), vec![0]);
        assert_eq!(chosen_poses(&batch, &[]), Vec::<usize>::new());
    }

    #[test]
    fn the_final_optimisation_takes_every_sighting() {
        let ranges: Vec<f64> = (0..50).map(|k| f64::from(k % 17)).collect();
        let every: Vec<usize> = (0..50).collect();
        assert_eq!(chosen_poses(&Batch::last(false), &ranges), every);
    }
}
