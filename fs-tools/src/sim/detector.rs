//! One scan of the simulated cone detector: which objects it sees, with
//! what noise, colour and tracker id.

use super::effects::{Noise, behind};
use super::tracker::Tracker;
use super::{SensorModel, Source};
use crate::track::Track;
use cairn_core::SE2;
use cairn_slam::Color;
use cairn_slam::log::Detection;
use nalgebra::Vector2;
use rand::Rng;
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand_distr::{Distribution, Poisson};

/// One scan from `pose`. A cone `hidden` by an overlapping one draws its
/// noise like any other (so that hiding it leaves every other detection's
/// draws as they were) but is not reported. The tracker gets the motion the
/// odometry measured since the last scan.
pub(super) fn detect(
    track: &Track,
    hidden: &[bool],
    pose: &SE2,
    sensor: &SensorModel,
    (tracker, motion): (&mut Tracker, &SE2),
    rng: &mut StdRng,
) -> (Vec<Detection>, Vec<Source>) {
    let inverse = pose.inverse();
    let bearing_noise = Noise::new(sensor.bearing_sigma, sensor.noise_dof);
    let objects = track
        .cones
        .iter()
        .enumerate()
        .map(|(i, c)| (Source::Cone(i), c.position, c.color))
        .chain(
            track
                .clutter
                .iter()
                .enumerate()
                .map(|(i, p)| (Source::Clutter(i), *p, Color::Unknown)),
        );
    let in_view: Vec<(Source, Vector2<f64>, Color)> = objects
        .map(|(source, world, color)| (source, inverse.transform_point(&world), color))
        .filter(|(_, local, _)| {
            let (r, b) = (local.norm(), local.y.atan2(local.x));
            r <= sensor.max_range && r >= 0.5 && b.abs() <= sensor.fov / 2.0
        })
        .collect();
    let blocked = if sensor.occlusion {
        // A cone listed twice stands once: its hidden copy blocks nothing.
        let standing: Vec<Vector2<f64>> = in_view
            .iter()
            .filter(|(s, _, _)| !matches!(s, Source::Cone(i) if hidden[*i]))
            .map(|o| o.1)
            .collect();
        in_view
            .iter()
            .map(|(_, p, _)| behind(p, &standing))
            .collect()
    } else {
        vec![false; in_view.len()]
    };
    let mut found: Vec<(Source, Vector2<f64>, Color)> = Vec::new();
    for ((source, local, color), blocked) in in_view.into_iter().zip(blocked) {
        let (probability, color) = match source {
            Source::Clutter(_) => (
                sensor.clutter_detection_probability,
                [Color::Blue, Color::Yellow, Color::Unknown][rng.random_range(0..3)],
            ),
            _ => (detection_probability(sensor, local.norm()), color),
        };
        if rng.random::<f64>() < probability && !blocked {
            found.push((source, local, color));
        }
    }
    let fp = Poisson::new(sensor.false_positives.max(1e-12))
        .map(|p| p.sample(rng) as usize)
        .unwrap_or(0);
    for _ in 0..fp {
        let r = rng.random_range(1.0..sensor.max_range);
        let b = rng.random_range(-sensor.fov / 2.0..sensor.fov / 2.0);
        let color = [Color::Blue, Color::Yellow, Color::Unknown][rng.random_range(0..3)];
        found.push((
            Source::FalsePositive,
            Vector2::new(r * b.cos(), r * b.sin()),
            color,
        ));
    }
    found.shuffle(rng);
    let oracle_ids = match tracker {
        Tracker::Oracle(oracle) => Some(oracle.ids(&found, sensor.id_swap, rng)),
        Tracker::Nearest(_) => None,
    };
    let mut detections = Vec::with_capacity(found.len());
    let mut sources = Vec::with_capacity(found.len());
    for (k, (source, local, color)) in found.into_iter().enumerate() {
        let r = local.norm();
        let range_noise = Noise::new(
            sensor.range_sigma + sensor.range_sigma_relative * r,
            sensor.noise_dof,
        );
        let r = (r + range_noise.sample(rng)).max(0.0);
        let b = local.y.atan2(local.x) + bearing_noise.sample(rng);
        let color = misread(color, sensor, rng.random());
        if matches!(source, Source::Cone(i) if hidden[i]) {
            continue;
        }
        detections.push(Detection {
            position: Vector2::new(r * b.cos(), r * b.sin()),
            range_bearing: Some((r, b)),
            color,
            id: oracle_ids.as_ref().map(|ids| ids[k]),
            covariance: None,
        });
        sources.push(source);
    }
    if let Tracker::Nearest(nearest) = tracker {
        let positions: Vec<Vector2<f64>> = detections.iter().map(|d| d.position).collect();
        for (d, id) in detections.iter_mut().zip(nearest.ids(&positions, motion)) {
            d.id = Some(id);
        }
    }
    (detections, sources)
}

/// The probability of detecting a cone at range `r`.
fn detection_probability(sensor: &SensorModel, r: f64) -> f64 {
    match sensor.far_detection_probability {
        None => sensor.detection_probability,
        Some(far) => {
            let u = (r / sensor.max_range).clamp(0.0, 1.0);
            sensor.detection_probability + (far - sensor.detection_probability) * u
        }
    }
}

/// The colour a detector reports for a cone of `color`, `u` uniform in [0, 1).
fn misread(color: Color, sensor: &SensorModel, u: f64) -> Color {
    if u < sensor.unknown_color {
        Color::Unknown
    } else if u < sensor.unknown_color + sensor.wrong_color {
        mistaken_for(color)
    } else {
        color
    }
}

/// The colour a cone of `color` is misread as, when it is not read unknown.
fn mistaken_for(color: Color) -> Color {
    match color {
        Color::Blue => Color::Yellow,
        Color::Yellow => Color::Blue,
        Color::Orange => Color::BigOrange,
        Color::BigOrange => Color::Orange,
        Color::Unknown => Color::Unknown,
    }
}

/// The probability that the detector reports a cone of `color` as
/// `reported` ([`misread`]'s law).
pub(crate) fn read_probability(color: Color, reported: Color, sensor: &SensorModel) -> f64 {
    let (unknown, wrong) = (sensor.unknown_color, sensor.wrong_color);
    if color == Color::Unknown {
        return if reported == Color::Unknown { 1.0 } else { 0.0 };
    }
    if reported == Color::Unknown {
        unknown
    } else if reported == color {
        1.0 - unknown - wrong
    } else if reported == mistaken_for(color) {
        wrong
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::Preset;

    #[test]
    fn the_read_probabilities_are_the_misreading_frequencies() {
        let sensor = Preset::hard().sensor;
        let colors = [
            Color::Blue,
            Color::Yellow,
            Color::Orange,
            Color::BigOrange,
            Color::Unknown,
        ];
        let draws = 10_000;
        for color in colors {
            let mut total = 0.0;
            for reported in colors {
                let p = read_probability(color, reported, &sensor);
                // u on an even grid over [0, 1) reads each colour that often.
                let seen = (0..draws)
                    .filter(|k| {
                        misread(color, &sensor, (*k as f64 + 0.5) / draws as f64) == reported
                    })
                    .count();
                assert!(
                    (seen as f64 / draws as f64 - p).abs() < 1e-3,
                    "{color:?} as {reported:?}"
                );
                total += p;
            }
            assert!((total - 1.0).abs() < 1e-12, "{color:?}: {total}");
        }
    }
}
