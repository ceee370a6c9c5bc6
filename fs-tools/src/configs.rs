//! The estimators' assumptions for the simulator's logs: the shipped
//! `configs/<preset>.toml` files. The simulator never hands its parameters
//! to an estimator; a run that should assume the preset's sensor reads the
//! file that describes it, as a team would read its own car's config.

use cairn_slam::estimator::EstimatorKind;
use cairn_slam::frontend::FrontEndConfig;
use cairn_slam::frontend::association::AssociationMethod;

/// The shipped configuration files of the simulator presets, by preset name.
pub const PRESET_CONFIGS: [(&str, &str); 2] = [
    ("standard", include_str!("../../configs/standard.toml")),
    ("hard", include_str!("../../configs/hard.toml")),
];

/// The settings `configs/<preset>.toml` gives, with `association` and the
/// χ² gate for `kind` ([`FrontEndConfig::gate_for`]); `None` for a preset
/// without a shipped file.
pub fn assumed_config(
    preset: &str,
    association: AssociationMethod,
    kind: EstimatorKind,
) -> Option<FrontEndConfig> {
    let (_, text) = PRESET_CONFIGS.iter().find(|(name, _)| *name == preset)?;
    let mut config = FrontEndConfig::from_toml(text).ok()?;
    config.association = association;
    config.gate = FrontEndConfig::gate_for(kind, config.false_positives);
    Some(config)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_preset_file_reads() {
        for (name, _) in PRESET_CONFIGS {
            let graph = assumed_config(name, AssociationMethod::Jcbb, EstimatorKind::Graph)
                .expect("the shipped file reads");
            assert_eq!(graph.association, AssociationMethod::Jcbb);
            let ekf = assumed_config(name, AssociationMethod::Jcbb, EstimatorKind::Ekf)
                .expect("the shipped file reads");
            assert_eq!(ekf.gate, 9.21, "{name}");
        }
        assert!(assumed_config("nope", AssociationMethod::Jcbb, EstimatorKind::Graph).is_none());
    }
}
