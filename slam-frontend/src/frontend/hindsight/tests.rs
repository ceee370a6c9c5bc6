//! Matching in hindsight: chains, paths and scans.

use super::*;

const SWITCH: f64 = 11.6; // −2 ln ID_SWITCH

pub(super) fn link(scan: usize, landmarks: &[(usize, f64)]) -> Link {
    Link {
        slot: scan,
        scan,
        landmarks: landmarks.to_vec(),
        clutter: 8.0,
    }
}

#[test]
fn annealing_halves_the_variance_down_to_the_detectors() {
    let close = |a: Vec<f64>, b: &[f64]| {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9)
    };
    let h = std::f64::consts::SQRT_2;
    assert!(close(
        anneal(8.0).collect(),
        &[8.0, 4.0 * h, 4.0, 2.0 * h, 2.0, h]
    ));
    assert!(close(anneal(2.0).collect(), &[2.0, h]));
    assert!(close(anneal(1.2).collect(), &[1.2]));
    assert_eq!(anneal(1.0).count(), 0);
    // The largest allowed: 14 rounds, the last within √2 of 1.
    let widest: Vec<f64> = anneal(100.0).collect();
    assert_eq!(widest.len(), 14);
    assert!(widest[13] > 1.0 && widest[13] < h);
}

#[test]
fn near_sightings_decide_the_far_ones_of_their_chain() {
    // Far away landmark 2 fits a little better; close up only 1 fits.
    let chain: Vec<Link> = (0..3)
        .map(|s| link(s, &[(1, 1.0), (2, 0.5)]))
        .chain((3..6).map(|s| link(s, &[(1, -6.0)])))
        .collect();
    assert_eq!(best_path(&chain, SWITCH), vec![Some(1); 6]);
    // Alone, each far sighting would take landmark 2.
    assert_eq!(best_path(&chain[..1], SWITCH), vec![Some(2)]);
}

#[test]
fn a_chain_switches_landmark_when_the_evidence_outweighs_the_switch() {
    let chain: Vec<Link> = (0..4)
        .map(|s| link(s, &[(1, -6.0), (2, 6.0)]))
        .chain((4..8).map(|s| link(s, &[(1, 6.0), (2, -6.0)])))
        .collect();
    let path = best_path(&chain, SWITCH);
    assert_eq!(&path[..4], &[Some(1); 4]);
    assert_eq!(&path[4..], &[Some(2); 4]);
    // One odd sighting is not worth two switches.
    let mut chain: Vec<Link> = (0..7).map(|s| link(s, &[(1, -6.0), (2, 6.0)])).collect();
    chain[3] = link(3, &[(1, 6.0), (2, -6.0)]);
    assert_eq!(best_path(&chain, SWITCH), vec![Some(1); 7]);
}

/// A chain of 40 sightings, one scan each from `first`, whose cone
/// changes between landmarks 1 and 2 every 5 sightings; the true one
/// costs `-evidence`, the other `evidence`.
fn switching(first: usize, evidence: f64) -> Vec<Link> {
    (0..40)
        .map(|t| {
            let (truth, other) = if (t / 5) % 2 == 0 { (1, 2) } else { (2, 1) };
            link(first + t, &[(truth, -evidence), (other, evidence)])
        })
        .collect()
}

#[test]
fn a_tracker_that_switches_often_is_learnt_and_its_weak_switches_followed() {
    // Eight chains whose switches are plain, one whose are weak: five
    // sightings of 2 in χ² do not pay for two switches at the prior
    // rate, but do at the rate the eight show.
    let mut chains: Vec<Vec<Link>> = (0..8).map(|c| switching(40 * c, 4.0)).collect();
    chains.push(switching(320, 1.0));
    let truth: Vec<Option<usize>> = (0..40)
        .map(|t| Some(if (t / 5) % 2 == 0 { 1 } else { 2 }))
        .collect();
    let alone = settled_paths(&chains[8..], &links_by_scan(&chains[8..]), ID_SWITCH);
    assert_eq!(alone[0], vec![Some(1); 40]);
    let paths = chain_paths(&chains, &links_by_scan(&chains));
    assert!(paths.iter().all(|p| *p == truth), "{paths:?}");
    // 7 switches in each of 9 chains of 39 steps, and the prior's one.
    let rate = switch_rate(&paths);
    assert!(
        (rate - 64.0 / (351.0 + 1.0 / ID_SWITCH)).abs() < 1e-12,
        "{rate}"
    );
}

#[test]
fn a_tracker_that_never_switches_is_trusted_more() {
    let steady: Vec<Vec<Option<usize>>> = vec![vec![Some(3); 400]; 5];
    assert!(switch_rate(&steady) < 0.2 * ID_SWITCH);
    assert!((switch_rate(&[]) - ID_SWITCH).abs() < 1e-12);
}

#[test]
fn a_lone_poor_fit_is_clutter() {
    assert_eq!(best_path(&[link(0, &[(4, 9.0)])], SWITCH), vec![None]);
    assert_eq!(best_path(&[link(0, &[])], SWITCH), vec![None]);
    assert_eq!(best_path(&[link(0, &[(4, 7.0)])], SWITCH), vec![Some(4)]);
}

#[test]
fn two_detections_of_one_scan_do_not_share_a_landmark() {
    let mut chains = vec![
        vec![link(0, &[(7, -2.0), (8, 0.0)])],
        vec![link(0, &[(7, -3.0)])],
    ];
    let paths = vec![vec![Some(7)], vec![Some(7)]];
    let by_scan = vec![vec![(0, 0), (1, 0)]];
    // The likelier claim (chain 1) keeps landmark 7; chain 0 loses it.
    assert_eq!(settle_claims(&mut chains, &paths, &by_scan), vec![0]);
    assert_eq!(chains[0][0].landmarks, vec![(8, 0.0)]);
    assert_eq!(best_path(&chains[0], SWITCH), vec![Some(8)]);
    assert_eq!(chains[1][0].landmarks, vec![(7, -3.0)]);
}

#[test]
fn an_object_tracked_beside_a_cone_loses_its_landmark_while_the_cone_holds_it() {
    // Chain 0, a cone seen in scans 0–5, holds landmark 3; chain 1, a
    // clutter object beside it, fits 3 in scans 2–5 and once even
    // better than the cone's own detection (scan 2).
    let mut chains = vec![
        (0..6).map(|s| link(s, &[(3, -4.0)])).collect::<Vec<_>>(),
        (2..6)
            .map(|s| link(s, &[(3, if s == 2 { -5.0 } else { -1.0 })]))
            .collect(),
    ];
    let paths: Vec<Vec<Option<usize>>> = chains.iter().map(|c| best_path(c, SWITCH)).collect();
    assert_eq!(paths[1], vec![Some(3); 4]);
    let mut by_scan = vec![vec![(0, 0)], vec![(0, 1)]];
    by_scan.extend((2..6).map(|s| vec![(0, s), (1, s - 2)]));
    assert_eq!(settle_claims(&mut chains, &paths, &by_scan), vec![1]);
    assert!(chains[1].iter().all(|link| link.landmarks.is_empty()));
    assert_eq!(best_path(&chains[1], SWITCH), vec![None; 4]);
    assert!(chains[0].iter().all(|link| link.landmarks == [(3, -4.0)]));
}
