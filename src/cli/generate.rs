//! `cairn generate`: synthetic benchmark graphs.

use cairn::generate::{ManhattanOptions, SphereOptions, manhattan, sphere};
use clap::{Args, ValueEnum};
use std::path::PathBuf;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum World {
    /// 2D grid of 1 m streets with loop closures where the path crosses itself.
    Manhattan,
    /// 3D rings of poses on a sphere, each ring closing loops with the one below.
    Sphere,
}

/// Options of `cairn generate`.
#[derive(Debug, Args)]
pub struct GenerateArgs {
    /// Kind of world.
    #[arg(value_enum)]
    world: World,
    /// Output g2o file (`-` for stdout).
    #[arg(short, long, default_value = "-")]
    output: PathBuf,
    /// Number of poses, 2 to 10⁷ (sphere: rounded to whole rings of √N poses).
    #[arg(short = 'n', long, default_value_t = 3500,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(2..=10_000_000))]
    poses: usize,
    /// Translation noise σ in metres.
    #[arg(long, default_value_t = 0.05)]
    sigma_translation: f64,
    /// Rotation noise σ in radians.
    #[arg(long, default_value_t = 0.01)]
    sigma_rotation: f64,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

pub fn run(a: GenerateArgs) -> Result<(), super::CliError> {
    if a.sigma_translation.is_nan()
        || a.sigma_rotation.is_nan()
        || a.sigma_translation <= 0.0
        || a.sigma_rotation <= 0.0
    {
        return Err(super::CliError::usage("noise σ must be positive"));
    }
    let graph = match a.world {
        World::Manhattan => manhattan(&ManhattanOptions {
            poses: a.poses,
            size: ((a.poses as f64).sqrt() as i64).max(4),
            sigma_translation: a.sigma_translation,
            sigma_rotation: a.sigma_rotation,
            seed: a.seed,
            ..Default::default()
        }),
        World::Sphere => {
            let side = ((a.poses as f64).sqrt().round() as usize).max(2);
            sphere(&SphereOptions {
                rings: side,
                poses_per_ring: side,
                sigma_translation: a.sigma_translation,
                sigma_rotation: a.sigma_rotation,
                seed: a.seed,
                ..Default::default()
            })
        }
    }
    .map_err(|e| e.to_string())?;
    let text = cairn::g2o::to_string(&graph).map_err(|e| e.to_string())?;
    super::write_output(&a.output, text.as_bytes())?;
    if a.output.as_os_str() != "-" {
        eprintln!(
            "wrote {}: {} vertices, {} edges",
            a.output.display(),
            graph.num_vertices(),
            graph.num_edges()
        );
    }
    Ok(())
}
