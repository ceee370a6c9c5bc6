//! The shipped configuration files (`configs/`): they read, round-trip,
//! and the simulator presets' files say what `FrontEndConfig::for_preset`
//! says.

use cairn::slam::estimator::EstimatorKind;
use cairn::slam::frontend::association::AssociationMethod;
use cairn::slam::frontend::{ConfigError, FrontEndConfig};
use cairn::slam::sim::Preset;
use std::path::Path;

fn shipped(name: &str) -> FrontEndConfig {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("configs")
        .join(name);
    let text = std::fs::read_to_string(&path).expect("the shipped config reads");
    FrontEndConfig::from_toml(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn every_shipped_config_reads_and_round_trips() {
    for name in ["standard.toml", "hard.toml", "mrclam.toml"] {
        let config = shipped(name);
        let again = FrontEndConfig::from_toml(&config.to_toml()).expect("reads back");
        assert_eq!(again, config, "{name}");
    }
    // A config that sets every optional part round-trips too.
    let config = FrontEndConfig {
        rot_trans_rot: Some([1e-3, 2e-5, 3e-3, 4e-4]),
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

/// Every number of two configs, by key, to 1e-12 relative.
fn assert_same(a: &FrontEndConfig, b: &FrontEndConfig, what: &str) {
    let table = |c: &FrontEndConfig| -> toml::Table { toml::from_str(&c.to_toml()).expect("TOML") };
    let (a, b) = (table(a), table(b));
    assert_eq!(
        a.keys().collect::<Vec<_>>(),
        b.keys().collect::<Vec<_>>(),
        "{what}"
    );
    for (key, x) in &a {
        let y = &b[key];
        match (x.as_float(), y.as_float()) {
            (Some(x), Some(y)) => assert!(
                (x - y).abs() <= 1e-12 * x.abs().max(1.0),
                "{what}: {key} {x} vs {y}"
            ),
            _ => assert_eq!(x, y, "{what}: {key}"),
        }
    }
}

#[test]
fn the_preset_files_are_the_presets() {
    for (name, preset) in [
        ("standard.toml", Preset::standard()),
        ("hard.toml", Preset::hard()),
    ] {
        let preset =
            FrontEndConfig::for_preset(&preset, AssociationMethod::Tracking, EstimatorKind::Graph);
        assert_same(&shipped(name), &preset, name);
    }
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
