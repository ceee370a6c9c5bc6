//! The scan latency learnt at the end of the run. The last optimisation
//! solves for it beside the poses ([`PoseBias`](super::bias::PoseBias));
//! where the log pins it and it differs from the config's, every sighting
//! is moved to what the pose its scan is stamped with would have seen, so
//! that poses, sightings and landmarks agree without the odometry between
//! the poses changing. Elsewhere the optimisation is made again without it.

use super::GraphSlam;
use crate::motion::integrate;
use cairn_core::SE2;

/// The largest scan latency learnt, either way (s): a clock offset between
/// the detector and the odometry can stamp scans early too.
const MAX_SCAN_LATENCY: f64 = 0.5;

/// The σ (s) within which a log must pin the latency for it to be learnt,
/// a third of a typical detector pipeline's 50 ms. At a steady speed the
/// latency trades against the map's turn about the start, which a log pins
/// loosely: on random tracks 0–9 (seeds 100–104) σ came out 8–19 ms on
/// `standard` logs, 25–50 ms on `hard` ones, 3–20 ms where the car slows
/// for corners. Set with the significance below on those logs: 0.01 s
/// learnt 29 of the 48 latencies of 50 ms there, 0.015 s 43, and neither
/// took one from a log without latency (`standard`, `hard`, detector noise
/// 2×, a drifting gyro bias), while 5 of 150 logs with sideslip, no start
/// line or no big orange cones gave one of 15–37 ms either way.
const LATENCY_PRECISION: f64 = 0.015;

/// How many σ the latency found must lie from the one assumed: on logs
/// without latency the estimate leans 1–2 σ one way on some tracks (the
/// map's turn), so fewer would take that for a latency.
const LATENCY_SIGNIFICANCE: f64 = 3.0;

impl GraphSlam {
    /// The car's speed (m/s) and yaw rate (rad/s) as it came to scan `k`:
    /// the odometry's between the scan before and this one. Before the first
    /// scan the log says nothing, and the car is taken to have stood at its
    /// start.
    pub(super) fn motion_at(&self, k: usize) -> (f64, f64) {
        match k.checked_sub(1).and_then(|i| self.odometry.get(i)) {
            Some(o) if o.dt > 0.0 => (o.delta.t.x / o.dt, o.delta.theta / o.dt),
            _ => (0.0, 0.0),
        }
    }

    /// Where the car was `late` seconds before scan `k`, in that scan's
    /// pose frame.
    fn earlier(&self, k: usize, late: f64) -> SE2 {
        let (speed, yaw_rate) = self.motion_at(k);
        integrate(&SE2::identity(), -speed, -yaw_rate, late)
    }

    /// Takes the latency a solve found, `late` seconds beyond the one
    /// assumed, with σ `sigma`, if the log shows it: σ within
    /// [`LATENCY_PRECISION`] and `late` beyond [`LATENCY_SIGNIFICANCE`] σ.
    /// Returns whether the solve stands (false: the log does not show the
    /// latency, and the solve is to be made again without it).
    pub(super) fn judge_latency(&mut self, late: f64, sigma: f64) -> bool {
        self.calibration.scan_latency_sigma = Some(sigma);
        let shown = sigma <= LATENCY_PRECISION && late.abs() > LATENCY_SIGNIFICANCE * sigma;
        if shown {
            self.take_latency(late);
        }
        shown || late == 0.0
    }

    /// Takes scans `late` seconds older than assumed so far (the total held
    /// to ±[`MAX_SCAN_LATENCY`]): each sighting becomes what its pose would
    /// have seen.
    fn take_latency(&mut self, late: f64) {
        let before = self.calibration.scan_latency;
        let late = (before + late).clamp(-MAX_SCAN_LATENCY, MAX_SCAN_LATENCY) - before;
        if !late.is_finite() || late == 0.0 {
            return;
        }
        for i in 0..self.observations.len() {
            let back = self.earlier(self.observations[i].pose, late);
            let o = &mut self.observations[i];
            let turn = back.rotation();
            o.z = back.transform_point(&o.z);
            o.information = turn * o.information * turn.transpose();
        }
        self.calibration.scan_latency += late;
    }
}
