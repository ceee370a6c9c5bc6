//! Each effect of the simulator's `realistic` preset happens at the rate
//! asked, measured from the log against the truth.

use cairn_core::SE2;
use cairn_fs_tools::sim::{Preset, SimConfig, Simulation, SpeedProfile, TrackerModel, simulate};
use cairn_fs_tools::trackgen::{TrackRules, random_track};
use cairn_slam::log::{Detection, Record};
use nalgebra::Vector2;
use std::collections::{HashMap, HashSet};

/// `standard` without false positives or clutter, changed by `change`, on
/// random track 1 at 5 m/s.
fn run(laps: f64, change: impl FnOnce(&mut Preset)) -> Simulation {
    run_at(5.0, laps, change)
}

/// [`run`] at `speed` (m/s).
fn run_at(speed: f64, laps: f64, change: impl FnOnce(&mut Preset)) -> Simulation {
    let (track, course) = random_track(1, &TrackRules::default());
    let mut preset = Preset::standard();
    preset.sensor.false_positives = 0.0;
    preset.sensor.clutter_detection_probability = 0.0;
    change(&mut preset);
    simulate(
        &track,
        &course,
        &SimConfig {
            preset,
            laps,
            speed,
            seed: 7,
            ..SimConfig::default()
        },
    )
}

/// A scan: its time, the true pose then, and its detections with the true
/// cone each came from.
type Scan = (f64, SE2, Vec<(Detection, Option<usize>)>);

/// Every scan of the run.
fn scans(sim: &Simulation) -> Vec<Scan> {
    let truth: HashMap<u64, SE2> = sim.truth.iter().map(|p| (p.t.to_bits(), p.pose)).collect();
    let mut sources = sim.truth_associations.iter();
    sim.log
        .iter()
        .filter_map(|r| match r {
            Record::Cones { t, cones } => Some((*t, cones)),
            _ => None,
        })
        .map(|(t, cones)| {
            let with = cones
                .iter()
                .map(|d| (d.clone(), sources.next().and_then(|a| a.landmark)))
                .collect();
            (t, truth[&t.to_bits()], with)
        })
        .collect()
}

/// The true pose at time `t` (the nearest odometry time).
fn pose_at(sim: &Simulation, t: f64) -> SE2 {
    let i = sim
        .truth
        .partition_point(|p| p.t < t)
        .clamp(1, sim.truth.len() - 1);
    let (a, b) = (&sim.truth[i - 1], &sim.truth[i]);
    let f = ((t - a.t) / (b.t - a.t)).clamp(0.0, 1.0);
    let turn = cairn_core::se2::normalize_angle(b.pose.theta - a.pose.theta);
    SE2::new(
        a.pose.t.x + f * (b.pose.t.x - a.pose.t.x),
        a.pose.t.y + f * (b.pose.t.y - a.pose.t.y),
        a.pose.theta + f * turn,
    )
}

#[test]
fn student_t_noise_has_heavy_tails_at_the_same_sigma() {
    let tails = |dof: Option<f64>| {
        let sim = run(1.0, |p| p.sensor.noise_dof = dof);
        let s = &Preset::standard().sensor;
        let mut z = Vec::new();
        for (_, pose, detections) in scans(&sim) {
            for (d, cone) in detections {
                let cone = sim.truth_map[cone.expect("no false positives")].position;
                let r = pose.inverse().transform_point(&cone).norm();
                let (range, _) = d.range_bearing.expect("range and bearing");
                z.push((range - r) / (s.range_sigma + s.range_sigma_relative * r));
            }
        }
        let n = z.len() as f64;
        let beyond = z.iter().filter(|x| x.abs() > 3.0).count() as f64 / n;
        let mut abs: Vec<f64> = z.iter().map(|x| x.abs()).collect();
        abs.sort_by(f64::total_cmp);
        (beyond, abs[abs.len() / 2], z.len())
    };
    let (gauss_tail, gauss_median, n) = tails(None);
    let (t_tail, t_median, _) = tails(Some(3.0));
    println!("{n} ranges: Gaussian {gauss_tail} {gauss_median}, t3 {t_tail} {t_median}");
    // Gaussian: 0.27% beyond 3σ, median |z| 0.674; Student-t(3) at the same
    // σ: 1.39% and 0.442.
    assert!(gauss_tail < 0.006, "{gauss_tail}");
    assert!((gauss_median - 0.674).abs() < 0.03, "{gauss_median}");
    assert!((t_tail - 0.0139).abs() < 0.005, "{t_tail}");
    assert!((t_median - 0.442).abs() < 0.03, "{t_median}");
}

/// The fraction of cones within the field of view at ranges in `band` that
/// were detected, from the true poses.
fn detected_fraction(sim: &Simulation, band: (f64, f64)) -> f64 {
    let s = &Preset::standard().sensor;
    let (mut seen, mut detected) = (0usize, 0usize);
    for (_, pose, detections) in scans(sim) {
        let found: HashSet<usize> = detections.iter().filter_map(|d| d.1).collect();
        for (i, cone) in sim.truth_map.iter().enumerate() {
            let local = pose.inverse().transform_point(&cone.position);
            let (r, b) = (local.norm(), local.y.atan2(local.x));
            if r >= band.0 && r < band.1 && b.abs() <= s.fov / 2.0 - 0.01 {
                seen += 1;
                detected += usize::from(found.contains(&i));
            }
        }
    }
    detected as f64 / seen as f64
}

#[test]
fn detection_falls_with_range_as_asked() {
    let sim = run(1.0, |p| p.sensor.far_detection_probability = Some(0.3));
    // p(r) = 0.9 − 0.6·r/15: 0.84 at 1.5 m (band 1–2), 0.36 at 13.5 m.
    let near = detected_fraction(&sim, (1.0, 2.0));
    let far = detected_fraction(&sim, (13.0, 14.0));
    println!("near {near}, far {far}");
    assert!((near - 0.84).abs() < 0.04, "{near}");
    assert!((far - 0.36).abs() < 0.04, "{far}");
    let flat = run(1.0, |_| {});
    let far_flat = detected_fraction(&flat, (13.0, 14.0));
    assert!((far_flat - 0.9).abs() < 0.03, "{far_flat}");
}

#[test]
fn occlusion_hides_cones_behind_nearer_ones() {
    let blocked_detections = |sim: &Simulation| {
        let (mut behind, mut detected) = (0usize, 0usize);
        for (_, pose, detections) in scans(sim) {
            let found: HashSet<usize> = detections.iter().filter_map(|d| d.1).collect();
            let local: Vec<Vector2<f64>> = sim
                .truth_map
                .iter()
                .map(|c| pose.inverse().transform_point(&c.position))
                .collect();
            for (i, p) in local.iter().enumerate() {
                if p.norm() > 15.0 || p.x <= 0.5 {
                    continue;
                }
                let hidden = local.iter().any(|q| {
                    let d = (q.y.atan2(q.x) - p.y.atan2(p.x)).abs();
                    q.norm() < p.norm() && q.x > 0.5 && d < (0.114 / q.norm()).atan()
                });
                if hidden {
                    behind += 1;
                    detected += usize::from(found.contains(&i));
                }
            }
        }
        (behind, detected)
    };
    let (behind, detected) = blocked_detections(&run(1.0, |p| p.sensor.occlusion = true));
    println!("{behind} sightings behind a nearer cone, {detected} detected");
    assert!(behind > 50, "the track has cones in line: {behind}");
    assert_eq!(detected, 0);
    let (behind, detected) = blocked_detections(&run(1.0, |_| {}));
    assert!(
        detected as f64 > 0.8 * behind as f64,
        "{detected} of {behind}"
    );
}

#[test]
fn scans_are_measured_from_where_the_car_was_before_their_stamp() {
    // 0.05 s is two and a half odometry steps: measured between them.
    let sim = run(1.0, |p| p.sensor.latency = 0.05);
    let mut error = [0.0; 4];
    let ages = [0.0, 0.04, 0.05, 0.06];
    for (t, pose, detections) in scans(&sim) {
        let earlier = ages.map(|age| {
            if age == 0.0 {
                pose
            } else {
                pose_at(&sim, t - age)
            }
        });
        for (d, cone) in detections {
            let cone = sim.truth_map[cone.expect("no false positives")].position;
            for (e, from) in error.iter_mut().zip(&earlier) {
                *e += (from.transform_point(&d.position) - cone).norm();
            }
        }
    }
    // At 5 m/s the stamp's pose is 0.25 m off, a step either side 0.05 m;
    // the pose 0.05 s before only by the detector's noise.
    println!("summed error from the pose this long before the stamp {ages:?}: {error:?}");
    assert!(error[2] < 0.5 * error[0], "{error:?}");
    assert!(error[2] < error[1] && error[2] < error[3], "{error:?}");
}

#[test]
fn the_gyro_bias_random_walks_at_the_rate_asked() {
    let walk = 5e-4;
    let mut squares = Vec::new();
    for seed in 0..16 {
        let (track, course) = random_track(1, &TrackRules::default());
        let mut preset = Preset::standard();
        preset.odometry.yaw_rate_bias_walk = walk;
        let sim = simulate(
            &track,
            &course,
            &SimConfig {
                preset,
                laps: 3.0,
                seed,
                ..SimConfig::default()
            },
        );
        // The measured yaw rate less the true one: the bias plus white noise.
        let measured: Vec<f64> = sim
            .log
            .iter()
            .filter_map(|r| match r {
                Record::Odom { yaw_rate, .. } => Some(*yaw_rate),
                _ => None,
            })
            .collect();
        let residual: Vec<f64> = sim
            .truth
            .windows(2)
            .zip(&measured)
            .map(|(w, m)| m - (w[1].pose.theta - w[0].pose.theta).sin().asin() / (w[1].t - w[0].t))
            .collect();
        // Means over 2 s windows 20 s apart, in disjoint pairs: their
        // difference has variance walk²·20 s plus the white noise's
        // 2·σ²/100, which is taken off.
        let (window, lag) = (100, 1000);
        let mean = |i: usize| residual[i..i + window].iter().sum::<f64>() / window as f64;
        let mut i = 0;
        while i + lag + window <= residual.len() {
            squares
                .push((mean(i + lag) - mean(i)).powi(2) - 2.0 * 0.005f64.powi(2) / window as f64);
            i += lag + window;
        }
    }
    let estimated = (squares.iter().sum::<f64>() / squares.len() as f64 / 20.0).sqrt();
    println!("{} differences: walk {estimated:.2e}", squares.len());
    assert!((estimated - walk).abs() < 0.2 * walk, "{estimated}");
}

#[test]
fn the_car_slides_off_its_heading_in_proportion_to_lateral_acceleration() {
    let k = 0.02;
    // At 8 m/s the random track's corners reach 2.6 m/s².
    let sim = run_at(8.0, 1.0, |p| p.odometry.sideslip = k);
    let mut ratios = Vec::new();
    for w in sim.truth.windows(2) {
        let dt = w[1].t - w[0].t;
        let step = w[0].pose.inverse().compose(&w[1].pose);
        let (v, omega) = (step.t.norm() / dt, step.theta / dt);
        // On an arc the chord leaves at half the turn: the rest is sideslip.
        let sideslip = step.t.y.atan2(step.t.x) - step.theta / 2.0;
        if (v * omega).abs() > 0.5 {
            ratios.push(sideslip / (v * omega));
        }
    }
    let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
    println!(
        "{} turning steps: sideslip per lateral acceleration {mean}",
        ratios.len()
    );
    assert!(ratios.len() > 100);
    assert!((mean - k).abs() < 0.02 * k, "{mean}");
}

#[test]
fn the_corner_profile_slows_for_corners_within_its_accelerations() {
    // 12 m/s on the straights; the random track's sharpest corners allow
    // about 9 m/s at 3 m/s².
    let sim = run_at(12.0, 1.0, |p| {
        p.speed = SpeedProfile::Corners {
            lateral_acceleration: 3.0,
            longitudinal_acceleration: 2.0,
        }
    });
    let speeds: Vec<(f64, f64, f64)> = sim
        .truth
        .windows(2)
        .map(|w| {
            let dt = w[1].t - w[0].t;
            let step = w[0].pose.inverse().compose(&w[1].pose);
            (w[0].t, step.t.norm() / dt, step.theta / dt)
        })
        .collect();
    let slowest = speeds.iter().map(|s| s.1).fold(f64::MAX, f64::min);
    let fastest = speeds.iter().map(|s| s.1).fold(0.0, f64::max);
    println!("speed {slowest:.2}–{fastest:.2} m/s");
    assert!(fastest > 11.9 && fastest < 12.01, "{fastest}");
    assert!(slowest < 9.5, "the track's corners slow it: {slowest}");
    for w in speeds.windows(2) {
        let accel = (w[1].1 - w[0].1) / (w[1].0 - w[0].0);
        // Speeds from chords of arcs: within 1% of the limit.
        assert!(accel.abs() < 2.02, "{accel} m/s² at {}", w[0].0);
    }
    // Lateral acceleration v·ω, once settled, within 10% of the limit on
    // all but the sharpest 1% of steps.
    let mut lateral: Vec<f64> = speeds.iter().map(|s| (s.1 * s.2).abs()).collect();
    lateral.sort_by(f64::total_cmp);
    let p99 = lateral[lateral.len() * 99 / 100];
    assert!(p99 < 3.3, "{p99}");
}

#[test]
fn nearest_neighbour_ids_fragment_switch_and_return() {
    let sim = run(2.0, |p| {
        p.sensor.tracker = TrackerModel::NearestNeighbour {
            gate: 0.5,
            max_misses: 2,
        };
    });
    let scans = scans(&sim);
    // Per id, the cones it was given to; per cone, its scans and ids.
    let mut cones_of_id: HashMap<u64, HashSet<usize>> = HashMap::new();
    let mut history: HashMap<usize, Vec<(usize, u64, f64)>> = HashMap::new();
    for (k, (_, _, detections)) in scans.iter().enumerate() {
        for (d, cone) in detections {
            let (id, cone) = (d.id.expect("an id"), cone.expect("no false positives"));
            cones_of_id.entry(id).or_default().insert(cone);
            history
                .entry(cone)
                .or_default()
                .push((k, id, d.position.norm()));
        }
    }
    let reused = cones_of_id.values().filter(|c| c.len() > 1).count();
    // Consecutive sightings of a cone within 8 m (where the detector's
    // noise is well inside the gate): seen in the next scan, the id is kept
    // but for switches. Farther, the noise fragments tracks. After more
    // than two scans unseen, the track has ended and the id is one freed or
    // new.
    let (mut next, mut kept, mut far, mut far_kept) = (0, 0, 0, 0);
    let (mut returns, mut renamed) = (0, 0);
    for sightings in history.values() {
        for w in sightings.windows(2) {
            let ((a, id_a, r), (b, id_b, _)) = (w[0], w[1]);
            if b == a + 1 && r < 8.0 {
                next += 1;
                kept += usize::from(id_a == id_b);
            } else if b == a + 1 && r > 12.0 {
                far += 1;
                far_kept += usize::from(id_a == id_b);
            } else if b > a + 3 {
                returns += 1;
                renamed += usize::from(id_a != id_b);
            }
        }
    }
    println!(
        "{} ids, {reused} reused; kept {kept} of {next} near, {far_kept} of {far} far; \
         renamed {renamed} of {returns} returns",
        cones_of_id.len()
    );
    assert!(reused > 10, "ids return on other cones: {reused}");
    assert!(kept as f64 > 0.99 * next as f64, "{kept} of {next}");
    assert!(
        (far_kept as f64) < 0.95 * far as f64,
        "far tracks fragment: {far_kept} of {far}"
    );
    assert!(
        returns > 100 && renamed as f64 > 0.8 * returns as f64,
        "{renamed} of {returns}"
    );
}

#[test]
fn the_realistic_preset_has_every_effect_and_checks_its_settings() {
    let p = Preset::realistic();
    assert_eq!(p.sensor.noise_dof, Some(3.0));
    assert!(p.sensor.occlusion && p.sensor.latency > 0.0);
    assert!(p.sensor.far_detection_probability.is_some());
    assert!(matches!(
        p.sensor.tracker,
        TrackerModel::NearestNeighbour { .. }
    ));
    assert!(p.odometry.yaw_rate_bias_walk > 0.0 && p.odometry.sideslip > 0.0);
    assert!(matches!(p.speed, SpeedProfile::Corners { .. }));
    assert!(p.check().is_ok());
    for change in [
        (|p: &mut Preset| p.sensor.noise_dof = Some(2.0)) as fn(&mut Preset),
        |p| p.sensor.latency = f64::NAN,
        |p| p.odometry.sideslip = 2.0,
        |p| p.sensor.far_detection_probability = Some(1.5),
        |p| p.odometry.yaw_rate_bias_walk = -1.0,
    ] {
        let mut bad = Preset::realistic();
        change(&mut bad);
        assert!(bad.check().is_err());
    }
}
