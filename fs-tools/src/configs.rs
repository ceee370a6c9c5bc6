//! The estimators' assumptions for the simulator's logs: the shipped
//! `configs/<preset>.toml` files. The simulator never hands its parameters
//! to an estimator; a run that should assume the preset's sensor reads the
//! file that describes it, as a team would read its own car's config.

use cairn_slam::estimator::EstimatorKind;
use cairn_slam::frontend::association::AssociationMethod;
use cairn_slam::frontend::{ConfigError, FrontEndConfig};

/// The shipped configuration files of the simulator presets, by preset name.
pub const PRESET_CONFIGS: [(&str, &str); 3] = [
    ("standard", include_str!("../../configs/standard.toml")),
    ("hard", include_str!("../../configs/hard.toml")),
    ("realistic", include_str!("../../configs/realistic.toml")),
];

/// Why a preset's assumed settings are not there.
#[derive(Debug, thiserror::Error)]
pub enum PresetConfigError {
    /// No shipped file for this preset.
    #[error("no shipped config for the preset {0:?} (standard, hard and realistic have one)")]
    Unknown(String),
    /// The shipped file does not read (a broken build).
    #[error("configs/{0}.toml: {1}")]
    Config(String, ConfigError),
}

/// The settings `configs/<preset>.toml` gives for an estimator of `kind`
/// ([`FrontEndConfig::from_toml_for`]: the files leave the χ² gate to the
/// estimator), with `association`.
pub fn assumed_config(
    preset: &str,
    association: AssociationMethod,
    kind: EstimatorKind,
) -> Result<FrontEndConfig, PresetConfigError> {
    let (_, text) = PRESET_CONFIGS
        .iter()
        .find(|(name, _)| *name == preset)
        .ok_or_else(|| PresetConfigError::Unknown(preset.to_string()))?;
    let mut config = FrontEndConfig::from_toml_for(text, kind)
        .map_err(|e| PresetConfigError::Config(preset.to_string(), e))?;
    config.association = association;
    Ok(config)
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
        assert!(matches!(
            assumed_config("nope", AssociationMethod::Jcbb, EstimatorKind::Graph),
            Err(PresetConfigError::Unknown(_))
        ));
    }
}
