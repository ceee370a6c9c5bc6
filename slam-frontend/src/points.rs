//! The planetary-rover front end: landmarks from raw point clouds. Points on
//! the vehicle itself and beyond a far limit are removed, the rest are
//! grouped by Euclidean clustering (a distance threshold, plus an angular
//! one for sparse far objects), and each cone-sized cluster becomes a
//! detection at its centroid. Successive landmark sets are aligned with the
//! Arun–Huang–Blostein least-squares method to carry identities from scan
//! to scan, which the tracking-assisted association uses.

use crate::color::Color;
use crate::estimator::Estimator;
use crate::files::{Association, StampedPose};
use crate::frontend::{Mode, MotionModel, Timing};
use crate::log::{Detection, Record};
use crate::map::Cone;
use crate::motion::{Correction, MotionNoise, Odometry};
use cairn_core::{DisjointSets, SE2};
use nalgebra::{DMatrix, DVector, Matrix2, Matrix3, Vector2, Vector3};

/// Settings of the point-cloud front end.
#[derive(Clone, Debug, PartialEq)]
pub struct PointCloudConfig {
    /// Points inside this box around the sensor, (x_min, x_max, y_min,
    /// y_max) in the vehicle frame, lie on the vehicle itself (m).
    pub vehicle: [f64; 4],
    /// Points farther than this (horizontal range) are dropped (m).
    pub far: f64,
    /// Points closer than this join one cluster (m).
    pub cluster_distance: f64,
    /// Points whose bearings differ by less than this, with ranges within
    /// `cluster_distance`, also join (rad): far objects are sparse.
    pub angular_gap: f64,
    /// Clusters with fewer points are noise.
    pub min_points: usize,
    /// Clusters wider than this are not cones (walls, cars) (m).
    pub max_extent: f64,
    /// The centroid of a cone's visible surface lies this much nearer the
    /// sensor than its axis; detections are pushed back by it (m).
    pub surface_offset: f64,
    /// Centroids of successive scans closer than this after alignment are
    /// the same object (m).
    pub match_distance: f64,
}

impl Default for PointCloudConfig {
    fn default() -> Self {
        Self {
            vehicle: [-2.0, 0.5, -0.8, 0.8],
            far: 20.0,
            cluster_distance: 0.3,
            angular_gap: 0.5f64.to_radians(),
            min_points: 2,
            max_extent: 0.6,
            surface_offset: CONE_SURFACE_OFFSET,
            match_distance: 0.5,
        }
    }
}

/// Base radius and height of a small Formula Student cone (m).
pub const CONE_RADIUS: f64 = 0.114;
/// See [`CONE_RADIUS`].
pub const CONE_HEIGHT: f64 = 0.325;
/// A scanner sweeping at even bearing steps samples the visible half of a
/// circle of radius ρ at an offset uniform in ρ·sin φ, whose mean depth is
/// ρ·π/4 nearer than the centre; ρ averages 0.6 of the base radius over the
/// heights a scanner sees.
pub const CONE_SURFACE_OFFSET: f64 = std::f64::consts::FRAC_PI_4 * 0.6 * CONE_RADIUS;

/// A cluster of points: the indices into the cloud and the centroid.
#[derive(Clone, Debug, PartialEq)]
pub struct Cluster {
    /// Indices of the points (into the cloud passed to [`extract`]).
    pub points: Vec<usize>,
    /// Mean of the points.
    pub centroid: Vector3<f64>,
}

/// The cone-sized clusters of a cloud (vehicle frame), in bearing order.
pub fn extract(cloud: &[[f64; 3]], config: &PointCloudConfig) -> Vec<Cluster> {
    let [x0, x1, y0, y1] = config.vehicle;
    let kept: Vec<usize> = (0..cloud.len())
        .filter(|&i| {
            let [x, y, z] = cloud[i];
            let on_vehicle = (x0..=x1).contains(&x) && (y0..=y1).contains(&y);
            x.is_finite()
                && y.is_finite()
                && z.is_finite()
                && !on_vehicle
                && x.hypot(y) <= config.far
        })
        .collect();
    let mut sets = DisjointSets::new(kept.len());
    let polar: Vec<(f64, f64)> = kept
        .iter()
        .map(|&i| {
            (
                cloud[i][0].hypot(cloud[i][1]),
                cloud[i][1].atan2(cloud[i][0]),
            )
        })
        .collect();
    let d2 = config.cluster_distance.powi(2);
    for a in 0..kept.len() {
        for b in a + 1..kept.len() {
            let (p, q) = (cloud[kept[a]], cloud[kept[b]]);
            let near = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2) < d2;
            let beside = (polar[a].1 - polar[b].1).abs() < config.angular_gap
                && (polar[a].0 - polar[b].0).abs() < config.cluster_distance;
            if near || beside {
                sets.union(a, b);
            }
        }
    }
    let mut clusters: Vec<Cluster> = sets
        .groups()
        .into_iter()
        .map(|members| members.into_iter().map(|a| kept[a]).collect::<Vec<usize>>())
        .filter(|g| g.len() >= config.min_points)
        .filter_map(|points| {
            let n = points.len() as f64;
            let centroid = points
                .iter()
                .map(|&i| Vector3::from(cloud[i]))
                .sum::<Vector3<f64>>()
                / n;
            let extent = points
                .iter()
                .map(|&i| (Vector3::from(cloud[i]) - centroid).xy().norm())
                .fold(0.0, f64::max);
            (2.0 * extent <= config.max_extent).then_some(Cluster { points, centroid })
        })
        .collect();
    clusters.sort_by(|a, b| {
        let bearing = |c: &Cluster| c.centroid.y.atan2(c.centroid.x);
        bearing(a).total_cmp(&bearing(b))
    });
    clusters
}

/// A cluster as a detection: its centroid pushed back along the line of
/// sight by the surface offset, colour unknown.
pub fn detection(cluster: &Cluster, config: &PointCloudConfig, id: Option<u64>) -> Detection {
    let c = cluster.centroid.xy();
    let range = c.norm();
    let position = if range > 1e-9 {
        c * ((range + config.surface_offset) / range)
    } else {
        c
    };
    Detection {
        position,
        range_bearing: None,
        color: Color::Unknown,
        id,
        covariance: None,
    }
}

/// The rotation R and translation t minimising Σ‖R aᵢ + t − bᵢ‖² over
/// paired 2D points (Arun, Huang and Blostein 1987): the SVD of the
/// cross-covariance, with the last singular direction flipped when the best
/// orthogonal fit is a reflection. `None` with fewer than two pairs.
pub fn arun(a: &[Vector2<f64>], b: &[Vector2<f64>]) -> Option<(Matrix2<f64>, Vector2<f64>)> {
    let columns = |s: &[Vector2<f64>]| DMatrix::from_fn(2, s.len(), |i, j| s[j][i]);
    let (r, t) = arun_columns(&columns(a), &columns(b))?;
    Some((
        r.fixed_view::<2, 2>(0, 0).into_owned(),
        t.fixed_rows::<2>(0).into_owned(),
    ))
}

/// [`arun`]'s fit as a rigid motion: the `SE2` that maps `a` onto `b` best.
pub fn rigid_motion(a: &[Vector2<f64>], b: &[Vector2<f64>]) -> Option<SE2> {
    let (r, t) = arun(a, b)?;
    Some(SE2::new(t.x, t.y, r[(1, 0)].atan2(r[(0, 0)])))
}

/// The rigid motion that takes `a` to `ma` and `b` to `mb` (exactly in
/// direction, midpoints matched); `None` when either pair is one point.
pub fn two_point(
    a: &Vector2<f64>,
    b: &Vector2<f64>,
    ma: &Vector2<f64>,
    mb: &Vector2<f64>,
) -> Option<SE2> {
    let (d, e) = (b - a, mb - ma);
    if d.norm() < 1e-9 || e.norm() < 1e-9 {
        return None;
    }
    let theta = e.y.atan2(e.x) - d.y.atan2(d.x);
    let t = 0.5 * (ma + mb) - nalgebra::Rotation2::new(theta) * (0.5 * (a + b));
    Some(SE2::new(t.x, t.y, theta))
}

/// [`arun`] for 3D points.
pub fn arun3(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> Option<(Matrix3<f64>, Vector3<f64>)> {
    let columns = |s: &[Vector3<f64>]| DMatrix::from_fn(3, s.len(), |i, j| s[j][i]);
    let (r, t) = arun_columns(&columns(a), &columns(b))?;
    Some((
        r.fixed_view::<3, 3>(0, 0).into_owned(),
        t.fixed_rows::<3>(0).into_owned(),
    ))
}

/// Arun's method on points as the columns of `a` and `b`.
fn arun_columns(a: &DMatrix<f64>, b: &DMatrix<f64>) -> Option<(DMatrix<f64>, DVector<f64>)> {
    let n = a.ncols().min(b.ncols());
    if n < 2 {
        return None;
    }
    let (a, b) = (a.columns(0, n), b.columns(0, n));
    let ca = a.column_mean();
    let cb = b.column_mean();
    let mut h = DMatrix::zeros(a.nrows(), a.nrows());
    for j in 0..n {
        h += (a.column(j) - &ca) * (b.column(j) - &cb).transpose();
    }
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut v = v_t.transpose();
    let mut r = &v * u.transpose();
    if r.determinant() < 0.0 {
        // nalgebra orders singular values decreasingly: flip the weakest.
        let last = v.ncols() - 1;
        v.column_mut(last).neg_mut();
        r = &v * u.transpose();
    }
    let t = cb - &r * ca;
    Some((r, t))
}

/// Carries identities from scan to scan: the new centroids are moved by the
/// odometry guess onto the previous ones, the pairs found within
/// [`PointCloudConfig::match_distance`] refine the motion by [`arun`], and
/// matching repeats; matched centroids keep their identity, the rest get
/// new ones.
#[derive(Clone, Debug, Default)]
pub struct SetTracker {
    previous: Vec<(Vector2<f64>, u64)>,
    next_id: u64,
}

impl SetTracker {
    /// Identities of `centroids` (vehicle frame) given `motion`, the pose of
    /// this scan in the previous scan's frame. Also returns the refined motion.
    pub fn track(
        &mut self,
        centroids: &[Vector2<f64>],
        motion: &SE2,
        match_distance: f64,
    ) -> (Vec<u64>, SE2) {
        let mut motion = *motion;
        let mut pairs: Vec<Option<usize>> = vec![None; centroids.len()];
        for _ in 0..3 {
            pairs = mutual_nearest(&self.previous, centroids, &motion, match_distance);
            let (a, b): (Vec<Vector2<f64>>, Vec<Vector2<f64>>) = pairs
                .iter()
                .enumerate()
                .filter_map(|(i, p)| p.map(|j| (centroids[i], self.previous[j].0)))
                .unzip();
            if a.len() < 3 {
                break;
            }
            let Some(fit) = rigid_motion(&a, &b) else {
                break;
            };
            motion = fit;
        }
        let ids: Vec<u64> = pairs
            .iter()
            .map(|p| match p {
                Some(j) => self.previous[*j].1,
                None => {
                    self.next_id += 1;
                    self.next_id
                }
            })
            .collect();
        self.previous = centroids.iter().copied().zip(ids.iter().copied()).collect();
        (ids, motion)
    }
}

/// For each centroid moved by `motion`, the previous centroid that is its
/// nearest within `gate` and has it as its own nearest.
fn mutual_nearest(
    previous: &[(Vector2<f64>, u64)],
    centroids: &[Vector2<f64>],
    motion: &SE2,
    gate: f64,
) -> Vec<Option<usize>> {
    let moved: Vec<Vector2<f64>> = centroids
        .iter()
        .map(|c| motion.transform_point(c))
        .collect();
    let nearest = |p: &Vector2<f64>, set: &mut dyn Iterator<Item = Vector2<f64>>| {
        set.enumerate()
            .map(|(j, q)| (j, (q - p).norm()))
            .min_by(|x, y| x.1.total_cmp(&y.1))
    };
    moved
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let (j, d) = nearest(m, &mut previous.iter().map(|p| p.0))?;
            let (back, _) = nearest(&previous[j].0, &mut moved.iter().copied())?;
            (d < gate && back == i).then_some(j)
        })
        .collect()
}

/// Any estimator fed from point clouds: each `points` record becomes a
/// `cones` record of cluster detections with tracked identities; other
/// records pass through.
pub struct Clustered {
    inner: Box<dyn Estimator>,
    config: PointCloudConfig,
    tracker: SetTracker,
    motion: Odometry,
}

impl Clustered {
    /// Wraps `inner`.
    pub fn new(inner: Box<dyn Estimator>, config: PointCloudConfig) -> Self {
        // The odometry only seeds the alignment; its noise is not used.
        let noise = MotionNoise::Velocity {
            speed_sigma: 0.0,
            speed_sigma_relative: 0.0,
            yaw_rate_sigma: 0.0,
            turn_sigma: 0.0,
            sideslip_sigma: 0.0,
        };
        Self {
            inner,
            config,
            tracker: SetTracker::default(),
            motion: Odometry::new(MotionModel::Unicycle, noise),
        }
    }

    /// The detections a cloud gives, with identities carried from the
    /// previous cloud.
    pub fn detections(&mut self, t: f64, cloud: &[[f64; 3]]) -> Vec<Detection> {
        self.motion.advance(t, Correction::NONE);
        let (delta, _) = self.motion.take();
        let clusters = extract(cloud, &self.config);
        let centroids: Vec<Vector2<f64>> = clusters
            .iter()
            .map(|c| detection(c, &self.config, None).position)
            .collect();
        let (ids, _) = self
            .tracker
            .track(&centroids, &delta, self.config.match_distance);
        clusters
            .iter()
            .zip(ids)
            .map(|(c, id)| detection(c, &self.config, Some(id)))
            .collect()
    }
}

impl Estimator for Clustered {
    fn process(&mut self, record: &Record) {
        match record {
            Record::Points { t, points } => {
                let cones = self.detections(*t, points);
                self.inner.process(&Record::Cones { t: *t, cones });
            }
            Record::Odom {
                t, v, yaw_rate, vy, ..
            } => {
                self.motion
                    .record(*t, (*v, *vy), *yaw_rate, None, Correction::NONE);
                self.inner.process(record);
            }
            _ => self.inner.process(record),
        }
    }
    fn finish(&mut self) -> Result<(), crate::frontend::OptimiseError> {
        self.inner.finish()
    }
    fn warnings(&self) -> &[String] {
        self.inner.warnings()
    }
    fn map(&self) -> Vec<Cone> {
        self.inner.map()
    }
    fn trajectory(&self) -> Vec<StampedPose> {
        self.inner.trajectory()
    }
    fn associations(&self) -> Vec<Association> {
        self.inner.associations()
    }
    fn timing(&self) -> &Timing {
        self.inner.timing()
    }
    fn loop_closures(&self) -> usize {
        self.inner.loop_closures()
    }
    fn detector_noise(&self) -> Option<crate::frontend::DetectorNoise> {
        self.inner.detector_noise()
    }
    fn calibration(&self) -> Option<crate::frontend::Calibration> {
        self.inner.calibration()
    }
    fn mode(&self) -> Mode {
        self.inner.mode()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Unit};
    use proptest::prelude::*;

    #[test]
    fn two_points_give_the_motion_that_maps_them() {
        let truth = SE2::new(1.5, -2.0, 0.7);
        let (a, b) = (Vector2::new(0.3, 1.0), Vector2::new(-2.0, 4.0));
        let fit = two_point(
            &a,
            &b,
            &truth.transform_point(&a),
            &truth.transform_point(&b),
        )
        .expect("distinct points");
        assert!((fit.t - truth.t).norm() < 1e-12 && (fit.theta - truth.theta).abs() < 1e-12);
        assert!(two_point(&a, &a, &a, &b).is_none());
    }

    proptest! {
        #[test]
        fn arun_recovers_a_2d_motion(
            th in -3.1..3.1f64, tx in -10.0..10.0f64, ty in -10.0..10.0f64,
            pts in prop::collection::vec((-20.0..20.0f64, -20.0..20.0f64), 3..12),
        ) {
            let a: Vec<Vector2<f64>> = pts.iter().map(|&(x, y)| Vector2::new(x, y)).collect();
            let spread = a.iter().map(|p| (p - a[0]).norm()).fold(0.0, f64::max);
            prop_assume!(spread > 1.0);
            let pose = SE2::new(tx, ty, th);
            let b: Vec<Vector2<f64>> = a.iter().map(|p| pose.transform_point(p)).collect();
            let (r, t) = arun(&a, &b).unwrap();
            prop_assert!((r - pose.rotation()).abs().max() < 1e-6);
            prop_assert!((t - pose.t).norm() < 1e-6);
        }

        #[test]
        fn arun_recovers_a_3d_motion(
            axis in prop::array::uniform3(-1.0..1.0f64), angle in -3.0..3.0f64,
            shift in prop::array::uniform3(-5.0..5.0f64),
            pts in prop::collection::vec(prop::array::uniform3(-10.0..10.0f64), 4..12),
        ) {
            let axis = Vector3::from(axis);
            prop_assume!(axis.norm() > 0.1);
            let rot = Rotation3::from_axis_angle(&Unit::new_normalize(axis), angle).into_inner();
            let a: Vec<Vector3<f64>> = pts.iter().map(|p| Vector3::from(*p)).collect();
            // Not all on one line.
            let c = a.iter().sum::<Vector3<f64>>() / a.len() as f64;
            let m = a.iter().map(|p| (p - c) * (p - c).transpose()).sum::<Matrix3<f64>>();
            prop_assume!(m.symmetric_eigenvalues().min() > 1.0);
            let b: Vec<Vector3<f64>> = a.iter().map(|p| rot * p + Vector3::from(shift)).collect();
            let (r, t) = arun3(&a, &b).unwrap();
            prop_assert!((r - rot).abs().max() < 1e-6);
            prop_assert!((t - Vector3::from(shift)).norm() < 1e-6);
        }
    }

    #[test]
    fn arun_returns_a_rotation_for_mirrored_points() {
        let a = [
            Vector2::new(0.0, 0.0),
            Vector2::new(1.0, 0.0),
            Vector2::new(0.0, 2.0),
        ];
        let mirrored: Vec<Vector2<f64>> = a.iter().map(|p| Vector2::new(p.x, -p.y)).collect();
        let (r, _) = arun(&a, &mirrored).unwrap();
        assert!((r.determinant() - 1.0).abs() < 1e-9, "{r}");
        assert!(arun(&a[..1], &mirrored[..1]).is_none());
    }

    #[test]
    fn clustering_drops_the_vehicle_and_far_points_and_finds_each_cone() {
        let config = PointCloudConfig::default();
        let mut cloud = Vec::new();
        // Two cones at 5 m (0.5 m apart) and one at 12 m.
        for (cx, cy) in [(5.0, 0.25), (5.0, -0.25), (12.0, 3.0)] {
            for k in 0..6 {
                let a = k as f64 * 0.3;
                cloud.push([cx - 0.08 * a.cos(), cy + 0.08 * a.sin() - 0.04, 0.1]);
            }
        }
        // On the vehicle and beyond the far limit.
        cloud.extend([
            [0.2, 0.1, 0.3],
            [-1.0, -0.3, 0.2],
            [25.0, 0.0, 0.5],
            [25.1, 0.0, 0.5],
        ]);
        // A wall: wider than a cone.
        for k in 0..20 {
            cloud.push([8.0, -4.0 + 0.1 * k as f64 - 1.0, 0.3]);
        }
        let clusters = extract(&cloud, &config);
        assert_eq!(clusters.len(), 3, "{clusters:?}");
        // Bearing order: the right-hand cone at 5 m first.
        assert!(clusters[0].centroid.y < 0.0 && clusters[1].centroid.y > 0.0);
        assert!((clusters[2].centroid.xy() - Vector2::new(12.0, 3.0)).norm() < 0.2);
        assert!(clusters.iter().all(|c| c.points.len() == 6));
        let d = detection(&clusters[2], &config, Some(4));
        assert!(d.position.norm() > clusters[2].centroid.xy().norm());
        assert_eq!((d.color, d.id), (Color::Unknown, Some(4)));
    }

    #[test]
    fn the_set_tracker_keeps_identities_through_motion() {
        let world = [
            Vector2::new(5.0, 2.0),
            Vector2::new(6.0, -2.0),
            Vector2::new(10.0, 2.5),
            Vector2::new(11.0, -1.5),
        ];
        let mut tracker = SetTracker::default();
        let first = tracker.track(&world, &SE2::identity(), 0.5).0;
        // The car moved 1 m ahead and turned a little; odometry says 0.8 m.
        let moved = SE2::new(1.0, 0.05, 0.03);
        let seen: Vec<Vector2<f64>> = world
            .iter()
            .map(|p| moved.inverse().transform_point(p))
            .collect();
        let (second, motion) = tracker.track(&seen, &SE2::new(0.8, 0.0, 0.0), 0.5);
        assert_eq!(first, second);
        assert!((motion.t - moved.t).norm() < 1e-6 && (motion.theta - moved.theta).abs() < 1e-9);
        // A new object gets a new identity.
        let mut more = seen.clone();
        more.push(Vector2::new(3.0, 8.0));
        let third = tracker.track(&more, &SE2::identity(), 0.5).0;
        assert_eq!(&third[..4], &first[..]);
        assert!(!first.contains(&third[4]));
    }
}
