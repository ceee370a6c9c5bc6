//! FastSLAM 1.0 and 2.0 (Montemerlo et al. 2002, 2003): a particle per path
//! hypothesis, each with its own map of 2×2 landmark EKFs and its own data
//! association. 1.0 samples the pose from the motion model; 2.0 folds the
//! scan's matched observations into the proposal it samples from.

use super::closure::{self, ScanEvidence, record};
use super::particle::{Landmark, Particle, proposal, push_step, refine};
use super::{Choice, Run, candidates, landmark_from, measurement};
use crate::files::{Association, StampedPose};
use crate::frontend::association::Correlation;
use crate::frontend::{FrontEndConfig, Mode, Timing, beside};
use crate::log::{Detection, Record};
use crate::map::Cone;
use crate::motion::compose_jacobians;
use crate::sighting::{START_AREA, Sighting, View, in_view};
use cairn_core::SE2;
use nalgebra::{Matrix2, Matrix3, SMatrix, Vector2, Vector3};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};
use std::rc::Rc;
use std::time::Instant;

mod output;
#[cfg(test)]
mod tests;

/// FastSLAM 1.0 or 2.0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Version {
    /// Poses sampled from the motion model; weights from the observations.
    One,
    /// Poses sampled from the motion model conditioned on the observations.
    Two,
}

/// Settings of the particle filter.
#[derive(Clone, Copy, Debug)]
pub struct ParticleConfig {
    /// 1.0 or 2.0.
    pub version: Version,
    /// Number of particles.
    pub particles: usize,
    /// Resample when the effective sample size drops below this fraction
    /// of the particle count.
    pub resample_below: f64,
    /// Log-likelihood of a detection that starts a new landmark or is
    /// rejected, relative to a perfect match (the new-landmark weight).
    pub new_landmark_log_weight: f64,
    /// Log-likelihood of a confirmed landmark inside the field of view that
    /// was not seen (ln of the miss probability).
    pub missed_log_weight: f64,
    /// Seed of the sampler.
    pub seed: u64,
    /// Smooth the chosen particle's path and map with Cairn's solver (its
    /// own odometry, sightings and associations) at a loop closure, before
    /// every particle carries on with it, and the best particle's at the
    /// end of the run. Without, a closure moves only the landmarks made on
    /// the way back into the start area.
    pub smooth: bool,
}

impl ParticleConfig {
    /// The defaults for a version: 100 particles, resampling below half.
    pub fn new(version: Version) -> Self {
        Self {
            version,
            particles: 100,
            resample_below: 0.5,
            // As likely as a match at the 99.9% χ² boundary (13.8 / 2).
            new_landmark_log_weight: -6.9,
            // Detection probability ≈ 0.9.
            missed_log_weight: (0.1f64).ln(),
            seed: 0,
            smooth: true,
        }
    }
}

/// The FastSLAM estimator. Feed it records with [`FastSlam::process`].
#[derive(Clone, Debug)]
pub struct FastSlam {
    run: Run,
    particles: Vec<Particle>,
    settings: ParticleConfig,
    rng: StdRng,
    resamplings: usize,
    /// Every scan's motion and measurements, for the smoothing.
    evidence: Vec<ScanEvidence>,
    warnings: Vec<String>,
}

impl FastSlam {
    /// A particle filter that starts mapping at the origin (or the log's `start`).
    pub fn new(config: FrontEndConfig, settings: ParticleConfig) -> Self {
        let particle = Particle {
            pose: SE2::identity(),
            log_weight: 0.0,
            map: Vec::new(),
            path: None,
            returned: 0,
        };
        Self {
            run: Run::new(config),
            particles: vec![particle; settings.particles.max(1)],
            rng: StdRng::seed_from_u64(settings.seed),
            settings,
            resamplings: 0,
            evidence: Vec::new(),
            warnings: Vec::new(),
        }
    }

    /// A particle filter that localises on `map`, placed by aligning the
    /// first scans to it.
    pub fn with_map(config: FrontEndConfig, settings: ParticleConfig, map: &[Cone]) -> Self {
        let mut slam = Self::new(config, settings);
        let landmarks: Vec<Rc<Landmark>> = map
            .iter()
            .map(|c| {
                Rc::new(Landmark {
                    mean: c.position,
                    cov: c.prior_covariance(),
                    removed: false,
                    sighting: Sighting::known(c.color),
                })
            })
            .collect();
        for p in &mut slam.particles {
            p.map = landmarks.clone();
        }
        slam.run.start_on(map);
        slam
    }

    /// Known correspondences from the truth file instead of a method.
    pub fn with_known(mut self, truth: &[Association]) -> Self {
        self.run.set_known(truth);
        self
    }

    /// Processes one log record.
    pub fn process(&mut self, record: &Record) {
        if let Some((t, cones)) = self.run.next_scan(record) {
            let (start, closures) = (Instant::now(), self.run.loop_closures);
            self.update(t, cones);
            self.run
                .record_update(start.elapsed().as_secs_f64(), closures);
        }
    }

    /// The end of the run: the best particle's path and map smoothed over
    /// the whole run ([`ParticleConfig::smooth`]).
    pub fn finish(&mut self) {
        if !self.settings.smooth || self.run.map_given {
            return;
        }
        let best = self.best_index();
        let (start, walk) = (self.run.start, self.run.config.yaw_rate_bias_walk);
        let smoothed = closure::smooth(
            &mut self.particles[best],
            &self.evidence,
            &[],
            (&start, walk),
        );
        self.warn("the end of the run", smoothed);
    }

    /// Smoothings that failed, the particle kept as it was.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    fn warn(&mut self, when: &str, smoothed: Result<(), closure::SmoothError>) {
        if let Err(e) = smoothed {
            let scan = self.run.scans;
            (self.warnings).push(format!(
                "smoothing at {when} (scan {scan}) failed ({e}); kept the particle"
            ));
        }
    }

    /// Mapping or localising.
    pub fn mode(&self) -> Mode {
        self.run.mode
    }

    /// Loop closures detected so far.
    pub fn loop_closures(&self) -> usize {
        self.run.loop_closures
    }

    /// Update times; a loop closure's is the time to hand the best map to
    /// every particle.
    pub fn timing(&self) -> &Timing {
        &self.run.timing
    }

    /// Times the particles were resampled.
    pub fn resamplings(&self) -> usize {
        self.resamplings
    }

    /// The pose of the most likely particle.
    pub fn pose(&self) -> SE2 {
        self.best().pose
    }

    fn best(&self) -> &Particle {
        self.particles
            .iter()
            .max_by(|a, b| a.log_weight.total_cmp(&b.log_weight))
            .unwrap_or(&self.particles[0])
    }

    fn update(&mut self, t: f64, cones: &[Detection]) {
        let scan = self.run.scans;
        self.run.scans += 1;
        let measurements: Vec<_> = cones
            .iter()
            .map(|d| measurement(&self.run.config, d))
            .collect();
        let noise = self.run.config.yaw_rate_noise;
        let (delta, q) = record(
            &mut self.evidence,
            t,
            &mut self.run.motion,
            noise,
            &measurements,
            cones,
        );
        if scan == 0 {
            for p in &mut self.particles {
                p.pose = self.run.start;
            }
        }
        let here = self.best().pose.compose(&delta);
        match self.run.place(&here, cones) {
            Err(()) => {
                for p in &mut self.particles {
                    p.pose = p.pose.compose(&delta);
                    let pose = StampedPose { t, pose: p.pose };
                    push_step(p, scan, pose, vec![None; cones.len()]);
                }
                return;
            }
            Ok(Some(pose)) => {
                // Spread the particles around the alignment.
                let spread = Vector3::new(0.5, 0.5, 0.2);
                for k in 0..self.particles.len() {
                    let noise = self.normal3().component_mul(&spread);
                    self.particles[k].pose = SE2::from_vector(&(pose.to_vector() + noise));
                }
            }
            Ok(None) => {}
        }
        // The motion's noise is L·n for a standard normal n.
        let q_l = (q + Matrix3::identity() * 1e-12)
            .cholesky()
            .map_or(Matrix3::zeros(), |c| c.l());
        let mut tracker_choices = Vec::new();

        let best_before = self.best_index();
        let mut spread = Vec::new();
        for k in 0..self.particles.len() {
            let noise = self.normal3();
            let (choices, nearest) =
                self.update_particle(k, scan, t, cones, &measurements, &delta, (&q, &q_l), &noise);
            if k == best_before {
                tracker_choices = choices;
                spread = nearest;
            }
        }
        // Every particle of a scan is judged at the same spread.
        self.run.spread(&spread);
        // The tracker follows the particle that was best before the scan.
        for (i, c) in tracker_choices.iter().enumerate() {
            if let Some(l) = c {
                self.run.remember(scan, i, &cones[i], *l);
            }
        }
        let best = self.best_index();
        let (pose, returned) = (self.particles[best].pose, self.particles[best].returned);
        let approach = self.run.approach(&pose, scan);

        let recognised = if self.run.lap_closed(&pose, returned) {
            Some(pose)
        } else if self.run.back_at_start(&pose) {
            let particle = &self.particles[best];
            let live = particle.map.iter().filter(|lm| !lm.removed);
            self.run.recognise(
                &particle.pose,
                cones,
                live.map(|lm| (lm.mean, &lm.sighting)),
            )
        } else {
            None
        };
        match recognised {
            Some(place) => self.close_lap(best, &place, approach.unwrap_or(scan), scan),
            None => self.resample(),
        }
    }

    /// Closes a lap at `place`: every particle carries on with the best
    /// particle's map, moved to where the start landmarks put it, its
    /// duplicates merged, the approach's detections (from scan `first` on)
    /// tied to the landmarks they fall on, and smoothed.
    fn close_lap(&mut self, best: usize, place: &SE2, first: usize, scan: usize) {
        self.run.close_loop();
        let mut chosen = self.particles[best].clone();
        for lm in &mut chosen.map {
            if lm.sighting.view == View::Returned {
                Rc::make_mut(lm).sighting.settle();
            }
        }
        let recent = self.run.motion.distance() - START_AREA;
        let correction = place.compose(&chosen.pose.inverse());
        let merged = closure::snap(&mut chosen, place, recent);
        // The start area's detections the gates left alone count as
        // sightings seen now, as if the gates had matched them.
        let (distance, confirm_after) = (self.run.motion.distance(), self.run.config.confirm_after);
        let seen = |sighting: &mut Sighting, color| {
            sighting.count(color, confirm_after);
            sighting.revisit(scan, distance, place.theta);
            sighting.settle();
        };
        closure::rematch(&mut chosen, &self.evidence, &correction, first, seen);
        if self.settings.smooth && !self.run.map_given {
            let (start, walk) = (self.run.start, self.run.config.yaw_rate_bias_walk);
            let smoothed = closure::smooth(&mut chosen, &self.evidence, &merged, (&start, walk));
            self.warn("the loop closure", smoothed);
        }
        for p in &mut self.particles {
            *p = chosen.clone();
            p.log_weight = 0.0;
        }
    }

    fn best_index(&self) -> usize {
        (0..self.particles.len())
            .max_by(|&a, &b| {
                self.particles[a]
                    .log_weight
                    .total_cmp(&self.particles[b].log_weight)
            })
            .unwrap_or(0)
    }

    /// A standard normal 3-vector.
    fn normal3(&mut self) -> Vector3<f64> {
        Vector3::from_fn(|_, _| StandardNormal.sample(&mut self.rng))
    }

    /// Moves, associates, weighs and updates particle `k` by the motion
    /// `delta` (covariance `q` = `q_l`·`q_l`ᵀ) with the standard-normal
    /// `noise`; returns what each detection became, and the χ² of each
    /// detection's nearest landmark.
    #[allow(clippy::too_many_arguments)]
    fn update_particle(
        &mut self,
        k: usize,
        scan: usize,
        t: f64,
        cones: &[Detection],
        measurements: &[(Vector2<f64>, Matrix2<f64>)],
        delta: &SE2,
        (q, q_l): (&Matrix3<f64>, &Matrix3<f64>),
        noise: &Vector3<f64>,
    ) -> (Vec<Option<usize>>, Vec<f64>) {
        let config = &self.run.config;
        let settings = self.settings;
        let localising = self.run.mode == Mode::Localising;
        let map_given = self.run.map_given;
        let particle = &self.particles[k];
        // The motion's covariance in the world frame at this particle.
        let (_, j_delta) = compose_jacobians(&particle.pose, delta);
        let motion_cov = j_delta * q * j_delta.transpose();
        let predicted = particle.pose.compose(delta);
        // 1.0 associates at its sample, 2.0 at the prediction with the
        // motion's uncertainty.
        let (at, at_cov) = match settings.version {
            Version::One => (
                SE2::from_vector(&(predicted.to_vector() + j_delta * (q_l * noise))),
                Matrix3::zeros(),
            ),
            Version::Two => (predicted, motion_cov),
        };
        let awaits_closure = self.run.awaiting_closure(&at);
        let live = particle.map.iter().enumerate().filter_map(|(l, lm)| {
            let gated = !lm.removed
                && (!localising || lm.sighting.confirmed)
                && !awaits_closure(&lm.sighting);
            gated.then_some((
                l,
                super::Landmark {
                    mean: lm.mean,
                    cov: lm.cov,
                    cross: SMatrix::zeros(),
                    sighting: &lm.sighting,
                },
            ))
        });
        let (candidates, nearest) = candidates(config, &at, &at_cov, measurements, cones, live);
        let tracked = self
            .run
            .tracked(cones, |l| particle.map.get(l).is_some_and(|lm| !lm.removed));
        let choices = self.run.choose(
            scan,
            &candidates,
            &nearest,
            &tracked,
            Correlation::ThroughPose(&at_cov),
            |i, taken| {
                let w = at.transform_point(&cones[i].position);
                let live = particle.map.iter().enumerate();
                beside(
                    &w,
                    live.filter(|(_, lm)| !lm.removed && !awaits_closure(&lm.sighting))
                        .map(|(l, lm)| (l, &lm.mean)),
                    taken,
                )
            },
        );
        // Weight of the matched observations: N(z; ẑ, S) with the pose part
        // of S for 2.0, as the pairs computed it.
        let mut log_weight = 0.0;
        for (i, c) in choices.iter().enumerate() {
            log_weight += match c {
                Choice::Landmark(l) => candidates[i]
                    .iter()
                    .find(|p| p.landmark == *l)
                    .map_or(settings.new_landmark_log_weight, |p| -0.5 * p.cost),
                _ => settings.new_landmark_log_weight,
            };
        }
        let pose = match settings.version {
            Version::One => at,
            Version::Two => proposal(
                &predicted,
                &motion_cov,
                &particle.map,
                &choices,
                measurements,
                noise,
            ),
        };

        let particle = &mut self.particles[k];
        particle.pose = pose;
        particle.returned = 0;

        let distance = self.run.motion.distance();
        let mut associated = vec![false; particle.map.len()];
        let mut out = vec![None; cones.len()];
        for (i, d) in cones.iter().enumerate() {
            let (z, r) = &measurements[i];
            let landmark = match choices[i] {
                Choice::Landmark(l) if l < particle.map.len() => {
                    let lm = Rc::make_mut(&mut particle.map[l]);

                    // After its own loop closes the particle still refines
                    // the map it built; a given map stays fixed.
                    if !map_given {
                        refine(lm, &pose, z, r);
                    }
                    if !localising {
                        lm.sighting.count(d.color, config.confirm_after);
                    }
                    Some(l)
                }
                Choice::New if !localising => {
                    let (mean, _, j_z) = landmark_from(&pose, z);
                    particle.map.push(Rc::new(Landmark {
                        mean,
                        cov: j_z * r * j_z.transpose(),
                        removed: false,
                        sighting: Sighting::new(d.color, scan, distance, pose.theta),
                    }));
                    associated.push(true);
                    Some(particle.map.len() - 1)
                }
                _ => None,
            };
            out[i] = landmark;
            let Some(l) = landmark else { continue };
            associated[l] = true;
            let lm = Rc::make_mut(&mut particle.map[l]);
            if lm.sighting.revisit(scan, distance, pose.theta) {
                particle.returned += 1;
            }
        }
        // Misses: confirmed landmarks in view that were not seen lower the
        // weight; tentative ones missed too often are dropped.
        let inverse = pose.inverse();
        let reach2 = (config.max_range + 1.0).powi(2);
        for (l, slot) in particle.map.iter_mut().enumerate() {
            if slot.removed {
                continue;
            }
            let near = (slot.mean - pose.t).norm_squared() < reach2;
            // Nor can a landmark be missed while the gates leave it out.
            let visible =
                near && in_view(config, &inverse, &slot.mean) && !awaits_closure(&slot.sighting);
            if visible && !associated[l] && slot.sighting.confirmed {
                log_weight += settings.missed_log_weight;
            }
            let mut sighting = slot.sighting.clone();
            let drop =
                sighting.after_scan(config, visible, associated[l], !localising, scan, distance);
            if drop || sighting != slot.sighting {
                let lm = Rc::make_mut(slot);
                lm.sighting = sighting;
                lm.removed = drop;
            }
        }
        particle.log_weight += log_weight;
        let choices_u32 = out.iter().map(|c| c.map(|l| l as u32)).collect();
        push_step(particle, scan, StampedPose { t, pose }, choices_u32);
        (out, nearest)
    }

    /// Low-variance resampling when the effective sample size is low.
    fn resample(&mut self) {
        let n = self.particles.len();
        let max = self
            .particles
            .iter()
            .map(|p| p.log_weight)
            .fold(f64::NEG_INFINITY, f64::max);
        if !max.is_finite() {
            for p in &mut self.particles {
                p.log_weight = 0.0;
            }
            return;
        }
        let weights: Vec<f64> = self
            .particles
            .iter()
            .map(|p| (p.log_weight - max).exp())
            .collect();
        let total: f64 = weights.iter().sum();
        let ess = total * total / weights.iter().map(|w| w * w).sum::<f64>();
        if ess >= self.settings.resample_below * n as f64 {
            // Keep the weights bounded.
            for p in &mut self.particles {
                p.log_weight -= max;
            }
            return;
        }
        let step = total / n as f64;
        let mut target = rand::Rng::random::<f64>(&mut self.rng) * step;
        let mut chosen = Vec::with_capacity(n);
        let (mut i, mut cumulative) = (0, weights[0]);
        for _ in 0..n {
            while cumulative < target && i + 1 < n {
                i += 1;
                cumulative += weights[i];
            }
            chosen.push(i);
            target += step;
        }
        let mut next: Vec<Particle> = chosen.iter().map(|&i| self.particles[i].clone()).collect();
        for p in &mut next {
            p.log_weight = 0.0;
        }
        self.particles = next;
        self.resamplings += 1;
    }
}
