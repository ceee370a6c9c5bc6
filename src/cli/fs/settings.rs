//! What `fs-slam` assumes: the estimators' settings from `--config`, the
//! `--noise` preset and single options, and the warning when the detector
//! looks noisier than assumed.

use super::{CliError, SlamArgs, bad_input, read_text};
use cairn::fs_tools::configs::assumed_config;
use cairn::slam::estimator::EstimatorKind;
use cairn::slam::frontend::association::AssociationMethod;
use cairn::slam::frontend::{FrontEndConfig, MotionModel};
use cairn::slam::motion::DEFAULT_ALPHA;

/// The estimators' settings: the `--config` file's, or those of the
/// `--noise` preset, with the single values the options give.
pub(super) fn slam_config(a: &SlamArgs, kind: EstimatorKind) -> Result<FrontEndConfig, CliError> {
    let association =
        match &a.association {
            Some(name) => Some(AssociationMethod::by_name(name).ok_or_else(|| {
                CliError::usage("--association must be ml, scnn, jcbb or tracking")
            })?),
            None => None,
        };
    let mut config = match &a.config {
        Some(path) => {
            let text = read_text(path)?;
            let mut config =
                FrontEndConfig::from_toml_for(&text, kind).map_err(bad_input(path.display()))?;
            describe_detector(&mut config, a)?;
            // A gate the file leaves to the estimator follows the false
            // positives `--false-positives` may have changed.
            if !FrontEndConfig::gives_gate(&text) {
                config.gate = FrontEndConfig::gate_for(kind, config.false_positives);
            }
            config
        }
        None => {
            let preset = a.noise.as_deref().unwrap_or("standard");
            let mut config = assumed_config(preset, AssociationMethod::Tracking, kind)
                .map_err(|e| CliError::usage(format!("--noise: {e}")))?;
            describe_detector(&mut config, a)?;
            // The gate follows the false positives `--false-positives` may have changed.
            config.gate = FrontEndConfig::gate_for(kind, config.false_positives);
            config
        }
    };
    if let Some(method) = association {
        config.association = method;
    }
    config.motion = match (a.motion.as_deref(), config.motion) {
        (None, motion) => motion,
        (Some("unicycle"), _) => MotionModel::Unicycle,
        (Some("bicycle"), _) if a.wheelbase > 0.0 && a.wheelbase.is_finite() => {
            MotionModel::Bicycle {
                wheelbase: a.wheelbase,
            }
        }
        _ => {
            return Err(CliError::usage(
                "--motion must be unicycle or bicycle (with a positive --wheelbase)",
            ));
        }
    };
    if a.keep_mapping {
        config.localise_after_loop = false;
    }
    if a.no_hindsight {
        config.hindsight = false;
    }
    if a.learn_noise {
        config.learn_detector_noise = true;
    }
    let noise = a.odometry_noise.as_deref();
    if !matches!(noise, None | Some("velocity" | "rot-trans-rot")) {
        return Err(CliError::usage(
            "--odometry-noise must be velocity or rot-trans-rot",
        ));
    }
    let alpha = match &a.alpha {
        Some(v) if v.len() == 4 && v.iter().all(|x| x.is_finite() && *x >= 0.0) => {
            Some([v[0], v[1], v[2], v[3]])
        }
        Some(_) => {
            return Err(CliError::usage(
                "--alpha takes four values A1,A2,A3,A4, finite and ≥ 0",
            ));
        }
        None => None,
    };
    let rot_trans_rot =
        noise == Some("rot-trans-rot") || (noise.is_none() && config.rot_trans_rot.is_some());
    config.rot_trans_rot = match (rot_trans_rot, alpha) {
        (false, Some(_)) => {
            return Err(CliError::usage(
                "--alpha needs --odometry-noise rot-trans-rot",
            ));
        }
        (false, None) => None,
        (true, Some(alpha)) => Some(alpha),
        (true, None) => Some(config.rot_trans_rot.unwrap_or(DEFAULT_ALPHA)),
    };
    Ok(config)
}

/// Replaces the parts of the detector model that `a` gives.
fn describe_detector(sensor: &mut FrontEndConfig, a: &SlamArgs) -> Result<(), CliError> {
    let positive = |v: f64| v.is_finite() && v > 0.0;
    let non_negative = |v: f64| v.is_finite() && v >= 0.0;
    let probability = |v: f64| v > 0.0 && v <= 1.0;
    for (value, target, name, valid, rule) in [
        (
            a.range_sigma,
            &mut sensor.range_sigma,
            "--range-sigma",
            &positive as &dyn Fn(f64) -> bool,
            "finite and positive",
        ),
        (
            a.range_sigma_relative,
            &mut sensor.range_sigma_relative,
            "--range-sigma-relative",
            &non_negative,
            "finite and ≥ 0",
        ),
        (
            a.bearing_sigma_deg.map(f64::to_radians),
            &mut sensor.bearing_sigma,
            "--bearing-sigma-deg",
            &positive,
            "finite and positive",
        ),
        (
            a.detection_probability,
            &mut sensor.detection_probability,
            "--detection-probability",
            &probability,
            "in (0, 1]",
        ),
        (
            a.false_positives,
            &mut sensor.false_positives,
            "--false-positives",
            &non_negative,
            "finite and ≥ 0",
        ),
    ] {
        if let Some(v) = value {
            if !valid(v) {
                return Err(CliError::usage(format!("{name} must be {rule}")));
            }
            *target = v;
        }
    }
    Ok(())
}

/// How far the fraction of detections rejected as spurious may exceed the
/// false positives the detector is assumed to make before `fs-slam` warns.
/// A detector as noisy as assumed loses its false positives and 1–2% more
/// (far, ambiguous cones); a `hard` log read with the `standard` noise loses
/// about half of all detections.
const EXCESS_REJECTED_WARNING: f64 = 0.1;

/// The warning for a run that rejected far more detections than the
/// assumed detector's false positives (`config.false_positives` in each of
/// `scans`): the usual sign that the detector is noisier than assumed, so
/// that its detections fall outside the gates.
pub(super) fn rejection_warning(
    rejected: usize,
    detections: usize,
    scans: usize,
    config: &FrontEndConfig,
) -> Option<String> {
    let fraction = rejected as f64 / detections.max(1) as f64;
    let false_positives =
        (config.false_positives * scans as f64 / detections.max(1) as f64).min(1.0);
    (detections >= 100 && fraction > false_positives + EXCESS_REJECTED_WARNING).then(|| {
        format!(
            "{:.0}% of the detections were rejected as spurious, where the detector is assumed \
             to make {:.0}% false positives. If it is noisier than assumed (range σ {} m + {}·r, \
             bearing σ {:.2}°, detection probability {}, {} false positives per scan), say so \
             with --noise hard or --range-sigma, --range-sigma-relative, --bearing-sigma-deg, \
             --detection-probability and --false-positives",
            100.0 * fraction,
            100.0 * false_positives,
            config.range_sigma,
            config.range_sigma_relative,
            config.bearing_sigma.to_degrees(),
            config.detection_probability,
            config.false_positives,
        )
    })
}
