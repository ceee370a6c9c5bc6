//! The shipped configuration files (`configs/`): they read, round-trip,
//! and the simulator presets' files describe the presets' sensors.

use cairn::fs_tools::configs::assumed_config;
use cairn::fs_tools::sim::Preset;
use cairn::slam::estimator::EstimatorKind;
use cairn::slam::frontend::association::AssociationMethod;
use cairn::slam::frontend::{ConfigError, FrontEndConfig};
use std::path::Path;

fn shipped_text(name: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("configs")
        .join(name);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn shipped(name: &str) -> FrontEndConfig {
    FrontEndConfig::from_toml(&shipped_text(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

const KINDS: [EstimatorKind; 4] = [
    EstimatorKind::Graph,
    EstimatorKind::Ekf,
    EstimatorKind::FastSlam1,
    EstimatorKind::FastSlam2,
];

#[test]
fn every_shipped_config_reads_and_round_trips() {
    for name in [
        "standard.toml",
        "hard.toml",
        "realistic.toml",
        "mrclam.toml",
    ] {
        let config = shipped(name);
        let again = FrontEndConfig::from_toml(&config.to_toml()).expect("reads back");
        assert_eq!(again, config, "{name}");
    }
    // A config that sets every optional part round-trips too.
    let config = FrontEndConfig {
        rot_trans_rot: Some([1e-3, 2e-5, 3e-3, 4e-4]),
        yaw_rate_bias_sigma: Some(0.004),
        motion: cairn::slam::frontend::MotionModel::Bicycle { wheelbase: 1.53 },
        association: AssociationMethod::Jcbb,
        ..FrontEndConfig::default()
    };
    let text = config.to_toml();
    assert_eq!(
        FrontEndConfig::from_toml(&text).expect("reads back"),
        config,
        "{text}"
    );
}

/// The preset files describe the simulator's sensor as a team would its
/// own car's: the detector's noise, view and clutter exactly, the odometry's
/// σ wide enough to cover its biases. Nothing hands the estimator the
/// preset itself; this test is what ties the two together.
#[test]
fn the_preset_files_describe_the_presets() {
    for (name, preset) in [
        ("standard.toml", Preset::standard()),
        ("hard.toml", Preset::hard()),
        ("realistic.toml", Preset::realistic()),
    ] {
        let config = shipped(name);
        let (s, o) = (&preset.sensor, &preset.odometry);
        // A bias that holds is the default's; one that wanders is given.
        let walk = if o.yaw_rate_bias_walk > 0.0 {
            o.yaw_rate_bias_walk
        } else {
            FrontEndConfig::default().yaw_rate_bias_walk
        };
        let pairs = [
            ("scan_latency", config.scan_latency, s.latency),
            ("yaw_rate_bias_walk", config.yaw_rate_bias_walk, walk),
            ("range_sigma", config.range_sigma, s.range_sigma),
            (
                "range_sigma_relative",
                config.range_sigma_relative,
                s.range_sigma_relative,
            ),
            ("bearing_sigma", config.bearing_sigma, s.bearing_sigma),
            ("fov", config.fov, s.fov),
            ("max_range", config.max_range, s.max_range),
            (
                "detection_probability",
                config.detection_probability,
                s.detection_probability,
            ),
            ("false_positives", config.false_positives, s.false_positives),
            ("color_wrong", config.color_wrong, s.wrong_color),
            ("color_unknown", config.color_unknown, s.unknown_color),
            (
                "speed_sigma_relative",
                config.speed_sigma_relative,
                2.0 * o.speed_scale_bias + 0.01,
            ),
            (
                "yaw_rate_sigma",
                config.yaw_rate_sigma,
                2.0 * o.yaw_rate_bias + 0.015,
            ),
            ("yaw_rate_noise", config.yaw_rate_noise, o.yaw_rate_sigma),
        ];
        for (key, file, preset) in pairs {
            assert!(
                (file - preset).abs() <= 1e-12 * preset.abs().max(1.0),
                "{name}: {key} {file} vs {preset}"
            );
        }
        // `--config configs/<preset>.toml` and `--noise <preset>` assume
        // the same, for every estimator.
        for kind in KINDS {
            let told = assumed_config(preset.name, AssociationMethod::Tracking, kind)
                .expect("the preset has a shipped config");
            let file = FrontEndConfig::from_toml_for(&shipped_text(name), kind)
                .expect("the shipped config reads");
            assert_eq!(told, file, "{name}, {kind:?}");
        }
    }
}

#[test]
fn a_gate_left_out_is_the_estimators_and_one_given_holds_for_every_estimator() {
    let rare = "false_positives = 0.3\n";
    let graph = FrontEndConfig::from_toml_for(rare, EstimatorKind::Graph).expect("reads");
    assert_eq!(graph.gate, 13.82);
    for kind in [
        EstimatorKind::Ekf,
        EstimatorKind::FastSlam1,
        EstimatorKind::FastSlam2,
    ] {
        let filter = FrontEndConfig::from_toml_for(rare, kind).expect("reads");
        assert_eq!(filter.gate, 9.21, "{kind:?}");
    }
    // Clutter in every other scan narrows the graph's gate too.
    let often = "false_positives = 1.0\n";
    let graph = FrontEndConfig::from_toml_for(often, EstimatorKind::Graph).expect("reads");
    assert_eq!(graph.gate, 9.21);
    let given = "false_positives = 0.3\ngate = 11.0\n";
    assert!(FrontEndConfig::gives_gate(given) && !FrontEndConfig::gives_gate(rare));
    for kind in KINDS {
        let config = FrontEndConfig::from_toml_for(given, kind).expect("reads");
        assert_eq!(config.gate, 11.0, "{kind:?}");
    }
    // The gate it sets is range-checked like one the file gives.
    let err = FrontEndConfig::from_toml_for("new_landmark_gate = 12.0", EstimatorKind::Graph)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("new_landmark_gate must be finite and above 13.82"),
        "{err}"
    );
}

#[test]
fn bad_files_name_the_key() {
    let err = FrontEndConfig::from_toml("range_sigma = 0.1\nrange_sigmaa = 0.2\n").unwrap_err();
    assert!(matches!(err, ConfigError::Toml(_)));
    assert!(err.to_string().contains("range_sigmaa"), "{err}");
    for (text, field) in [
        (
            "range_sigma = -0.1",
            "range_sigma must be finite and positive",
        ),
        (
            "bearing_sigma = 0.0",
            "bearing_sigma must be finite and positive",
        ),
        ("fov = 7.0", "fov must be in (0, 2π]"),
        ("scan_latency = 1.5", "scan_latency must be in [0, 1)"),
        (
            "sideslip_sigma = -0.01",
            "sideslip_sigma must be finite and ≥ 0",
        ),
        ("turn_sigma = -0.1", "turn_sigma must be finite and ≥ 0"),
        (
            "hindsight_rounds = 0",
            "hindsight_rounds must be from 1 to 20",
        ),
        (
            "hindsight_rounds = 21",
            "hindsight_rounds must be from 1 to 20",
        ),
        (
            "hindsight_anneal = 0.5",
            "hindsight_anneal must be from 1 to 100",
        ),
        (
            "hindsight_anneal = 101.0",
            "hindsight_anneal must be from 1 to 100",
        ),
        (
            "yaw_rate_bias_sigma = 0.0",
            "yaw_rate_bias_sigma must be finite and positive",
        ),
        (
            "detection_probability = 1.5",
            "detection_probability must be in (0, 1]",
        ),
        (
            "gate = 30.0",
            "new_landmark_gate must be finite and above 30",
        ),
        ("max_range = 1e400", "max_range"),
        (
            "motion = { bicycle = { wheelbase = 0.0 } }",
            "motion.bicycle.wheelbase must be finite and positive",
        ),
        (
            "rot_trans_rot = [0.1, 0.1, -0.1, 0.1]",
            "rot_trans_rot must be finite and ≥ 0",
        ),
        ("association = \"nearest\"", "nearest"),
        ("confirm_after = 0", "confirm_after"),
    ] {
        let err = FrontEndConfig::from_toml(text).unwrap_err().to_string();
        assert!(err.contains(field), "{text}: {err}");
    }
}

#[test]
fn the_yaw_rate_bias_prior_is_its_own_or_the_yaw_rate_sigma() {
    // A gyro's config leaves it out: the bias is as uncertain as the
    // yaw rate (the simulator presets). Commanded velocities carry little
    // bias: configs/mrclam.toml says so.
    let standard = shipped("standard.toml");
    assert_eq!(standard.yaw_rate_bias_sigma, None);
    assert_eq!(standard.yaw_rate_bias_prior(), standard.yaw_rate_sigma);
    let mrclam = shipped("mrclam.toml");
    assert_eq!(mrclam.yaw_rate_bias_prior(), 0.005);
    assert!(mrclam.yaw_rate_bias_prior() < mrclam.yaw_rate_sigma);
    assert!(mrclam.turn_sigma > 0.0 && standard.turn_sigma == 0.0);
}
