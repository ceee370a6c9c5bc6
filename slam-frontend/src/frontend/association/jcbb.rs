//! Joint compatibility branch and bound (Neira & Tardós 2001). Each
//! hypothesis's joint distance is updated as a pair joins it: in constant
//! time when only the pose correlates the pairs ([`ThroughPose`]), by one
//! block row of the stacked covariance's factor otherwise ([`JointFactor`]).

use super::{Candidates, Correlation, Pair};
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};

/// Nodes the search visits at most; it then keeps the best hypothesis found,
/// so a dense scan cannot stall an update.
const NODE_BUDGET: usize = 200;

/// Branch and bound over the detections: the hypothesis with the most
/// pairings whose stacked innovation passes the joint χ² test (ties: the
/// smaller joint distance). `gate(m)` is the test's threshold for m pairs.
pub(super) fn jcbb(
    candidates: &Candidates,
    correlation: Correlation,
    gate: impl Fn(usize) -> f64,
) -> Vec<Option<usize>> {
    let n = candidates.len();
    match correlation {
        Correlation::ThroughPose(pose_cov) => {
            search(candidates, &gate, ThroughPose::new(n, *pose_cov))
        }
        Correlation::General(correlation) => {
            search(candidates, &gate, JointFactor::new(n, correlation))
        }
    }
}

fn search<'a, G: Fn(usize) -> f64, J: JointDistance<'a>>(
    candidates: &'a Candidates,
    gate: &G,
    joint: J,
) -> Vec<Option<usize>> {
    let n = candidates.len();
    let mut search = Search {
        candidates,
        gate,
        joint,
        current: vec![None; n],
        best: vec![None; n],
        best_pairs: 0,
        best_d2: f64::INFINITY,
        nodes: 0,
    };
    search.recurse(0);
    search.best
}

/// The joint Mahalanobis distance νᵀS⁻¹ν of the stacked innovations of a
/// hypothesis, kept as pairs join and leave it in stack order.
trait JointDistance<'a> {
    /// Adds `pair` and returns the joint distance, or `None` when the joint
    /// covariance stops being positive definite (the pair stays in for
    /// [`Self::pop`] to remove either way).
    fn push(&mut self, pair: &'a Pair) -> Option<f64>;
    /// Removes the pair added last.
    fn pop(&mut self);
    /// Pairs in the hypothesis.
    fn len(&self) -> usize;
    /// The joint distance of the hypothesis.
    fn d2(&self) -> f64;
}

struct Search<'a, 'g, G: Fn(usize) -> f64, J> {
    candidates: &'a Candidates,
    gate: &'g G,
    joint: J,
    current: Vec<Option<usize>>,
    best: Vec<Option<usize>>,
    best_pairs: usize,
    best_d2: f64,
    nodes: usize,
}

impl<'a, G: Fn(usize) -> f64, J: JointDistance<'a>> Search<'a, '_, G, J> {
    /// Tries every pairing of detection `i` (and none) under the pairs
    /// already in `joint`.
    fn recurse(&mut self, i: usize) {
        self.nodes += 1;
        let n = self.candidates.len();
        let pairs = self.joint.len();
        if i == n {
            let d2 = self.joint.d2();
            if pairs > self.best_pairs || (pairs == self.best_pairs && d2 < self.best_d2) {
                self.best.clone_from(&self.current);
                self.best_pairs = pairs;
                self.best_d2 = d2;
            }
            return;
        }
        if self.nodes > NODE_BUDGET {
            return;
        }
        let candidates = self.candidates;
        for pair in &candidates[i] {
            if self.current.contains(&Some(pair.landmark)) {
                continue;
            }
            match self.joint.push(pair) {
                Some(d2) if d2 < (self.gate)(pairs + 1) => {
                    self.current[i] = Some(pair.landmark);
                    self.recurse(i + 1);
                    self.current[i] = None;
                }
                _ => {}
            }
            self.joint.pop();
        }
        // Leaving detection i unpaired can only help if it can still beat the best.
        if pairs + (n - i - 1) >= self.best_pairs.max(1) {
            self.recurse(i + 1);
        }
    }
}

/// The Cholesky factor L of the stacked innovation covariance S of the pairs
/// in a hypothesis, and w = L⁻¹ν, grown and shrunk a pair at a time: with
/// m pairs, adding one costs O(m²) instead of refactoring S in O(m³), and
/// the joint distance νᵀS⁻¹ν is |w|².
struct JointFactor<'a> {
    correlation: &'a dyn Fn(&Pair, &Pair) -> Matrix2<f64>,
    pairs: Vec<&'a Pair>,
    /// Row stride of `l`: two rows per detection.
    stride: usize,
    /// L, row-major; row 2k and 2k+1 hold pair k's block row.
    l: Vec<f64>,
    w: Vec<f64>,
    /// `d2[k]`: the joint distance of the first k pairs.
    d2: Vec<f64>,
}

impl<'a> JointFactor<'a> {
    /// Room for `capacity` pairs (one per detection), allocated once.
    fn new(capacity: usize, correlation: &'a dyn Fn(&Pair, &Pair) -> Matrix2<f64>) -> Self {
        let stride = 2 * capacity;
        Self {
            correlation,
            pairs: Vec::with_capacity(capacity),
            stride,
            l: vec![0.0; stride * stride],
            w: vec![0.0; stride],
            d2: {
                let mut d2 = Vec::with_capacity(capacity + 1);
                d2.push(0.0);
                d2
            },
        }
    }
}

impl<'a> JointDistance<'a> for JointFactor<'a> {
    fn len(&self) -> usize {
        self.pairs.len()
    }

    fn d2(&self) -> f64 {
        self.d2[self.pairs.len()]
    }

    fn push(&mut self, pair: &'a Pair) -> Option<f64> {
        let m = self.pairs.len();
        let (rows, stride) = (2 * m, self.stride);
        // The new block row X solves X L₀₀ᵀ = [S(new, k)]ₖ: forward substitution.
        for (k, &other) in self.pairs.iter().enumerate() {
            let s = (self.correlation)(pair, other);
            for r in 0..2 {
                for c in 0..2 {
                    self.l[(rows + r) * stride + 2 * k + c] = s[(r, c)];
                }
            }
        }
        let (done, new) = self.l.split_at_mut(rows * stride);
        let (x0, x1) = new.split_at_mut(stride);
        for x in [&mut x0[..rows], &mut x1[..rows]] {
            for col in 0..rows {
                let lrow = &done[col * stride..col * stride + col];
                let dot: f64 = lrow.iter().zip(&x[..col]).map(|(a, b)| a * b).sum();
                x[col] = (x[col] - dot) / done[col * stride + col];
            }
        }
        // Its diagonal block: the 2×2 factor of S(new, new) − X Xᵀ.
        let dot = |a: &[f64], b: &[f64]| -> f64 { a.iter().zip(b).map(|(p, q)| p * q).sum() };
        let s = pair.s_pose + pair.s_local;
        let schur = Matrix2::new(
            s[(0, 0)] - dot(&x0[..rows], &x0[..rows]),
            s[(0, 1)] - dot(&x0[..rows], &x1[..rows]),
            s[(1, 0)] - dot(&x1[..rows], &x0[..rows]),
            s[(1, 1)] - dot(&x1[..rows], &x1[..rows]),
        );
        let rhs = pair.innovation
            - Vector2::new(
                dot(&x0[..rows], &self.w[..rows]),
                dot(&x1[..rows], &self.w[..rows]),
            );
        self.pairs.push(pair);
        let factor = schur.cholesky()?;
        let l = factor.l();
        x0[rows] = l[(0, 0)];
        x0[rows + 1] = 0.0;
        x1[rows] = l[(1, 0)];
        x1[rows + 1] = l[(1, 1)];
        let w = l.solve_lower_triangular(&rhs)?;
        self.w[rows] = w.x;
        self.w[rows + 1] = w.y;
        let d2 = self.d2[m] + w.norm_squared();
        self.d2.push(d2);
        (d2.is_finite()).then_some(d2)
    }

    fn pop(&mut self) {
        self.pairs.pop();
        self.d2.truncate(self.pairs.len() + 1);
    }
}

/// The joint distance when only the pose correlates the pairs: S = D + H P Hᵀ
/// with D block diagonal (each pair's own landmark and noise) and H the
/// stacked pose Jacobians. By the Woodbury identity
/// νᵀS⁻¹ν = a − bᵀ(P⁻¹ + C)⁻¹b with the sums a = Σ νᵀD⁻¹ν, b = Σ HᵀD⁻¹ν
/// and C = Σ HᵀD⁻¹H over the pairs, so a pair joins in constant time.
/// (P⁻¹ + C)⁻¹ = P(I + CP)⁻¹ also holds for a singular P.
struct ThroughPose {
    pose_cov: Matrix3<f64>,
    /// The sums over the first k pairs, for k = 0 ..= pairs.
    sums: Vec<Sums>,
    d2: Vec<f64>,
}

#[derive(Clone, Copy)]
struct Sums {
    a: f64,
    b: Vector3<f64>,
    c: Matrix3<f64>,
}

impl ThroughPose {
    fn new(capacity: usize, pose_cov: Matrix3<f64>) -> Self {
        let mut sums = Vec::with_capacity(capacity + 1);
        sums.push(Sums {
            a: 0.0,
            b: Vector3::zeros(),
            c: Matrix3::zeros(),
        });
        let mut d2 = Vec::with_capacity(capacity + 1);
        d2.push(0.0);
        Self { pose_cov, sums, d2 }
    }
}

impl JointDistance<'_> for ThroughPose {
    fn push(&mut self, pair: &Pair) -> Option<f64> {
        let last = self.sums[self.sums.len() - 1];
        let d_inv = pair.s_local.cholesky().map(|c| c.inverse());
        let (sums, d2) = match d_inv {
            Some(d_inv) => {
                let u = d_inv * pair.innovation;
                let ht = pair.h_pose.transpose();
                let sums = Sums {
                    a: last.a + pair.innovation.dot(&u),
                    b: last.b + ht * u,
                    c: last.c + ht * d_inv * pair.h_pose,
                };
                let p = &self.pose_cov;
                let y = (Matrix3::identity() + sums.c * p).lu().solve(&sums.b);
                let d2 = y.map_or(f64::NAN, |y| sums.a - (p * sums.b).dot(&y));
                (sums, d2)
            }
            None => (last, f64::NAN),
        };
        self.sums.push(sums);
        self.d2.push(d2);
        d2.is_finite().then_some(d2)
    }

    fn pop(&mut self) {
        self.sums.pop();
        self.d2.pop();
    }

    fn len(&self) -> usize {
        self.d2.len() - 1
    }

    fn d2(&self) -> f64 {
        self.d2[self.d2.len() - 1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector, Matrix3, SMatrix};
    use rand::{Rng, SeedableRng, rngs::StdRng};

    /// A pair with a random innovation, pose Jacobian and local covariance.
    fn random_pair(rng: &mut StdRng, landmark: usize, pose_cov: &Matrix3<f64>) -> Pair {
        let h_pose = SMatrix::<f64, 2, 3>::from_fn(|_, _| rng.random_range(-2.0..2.0));
        let a = Matrix2::from_fn(|_, _| rng.random_range(-0.3..0.3));
        let s_local = a * a.transpose() + Matrix2::identity() * 0.01;
        Pair {
            landmark,
            d2: 0.0,
            cost: 0.0,
            penalty: 0.0,
            innovation: Vector2::from_fn(|_, _| rng.random_range(-0.5..0.5)),
            h_pose,
            s_pose: h_pose * pose_cov * h_pose.transpose(),
            s_local,
            bhattacharyya: 0.0,
        }
    }

    /// The correlation through the pose alone, as a closure.
    fn through(pose_cov: &Matrix3<f64>) -> impl Fn(&Pair, &Pair) -> Matrix2<f64> + '_ {
        move |a, b| a.h_pose * pose_cov * b.h_pose.transpose()
    }

    /// νᵀS⁻¹ν with S formed whole and factored anew.
    fn dense_d2(pairs: &[&Pair], correlation: &dyn Fn(&Pair, &Pair) -> Matrix2<f64>) -> f64 {
        let m = pairs.len();
        let s = DMatrix::from_fn(2 * m, 2 * m, |r, c| {
            let (a, b) = (pairs[r / 2], pairs[c / 2]);
            let block = if r / 2 == c / 2 {
                a.s_pose + a.s_local
            } else {
                correlation(a, b)
            };
            block[(r % 2, c % 2)]
        });
        let nu = DVector::from_fn(2 * m, |r, _| pairs[r / 2].innovation[r % 2]);
        s.cholesky()
            .map_or(f64::INFINITY, |c| nu.dot(&c.solve(&nu)))
    }

    #[test]
    fn the_grown_factor_gives_the_joint_distance_of_a_fresh_factorisation() {
        for_random_hypotheses(|pairs, _, correlation, rng| {
            let joint = JointFactor::new(pairs.len(), correlation);
            check_against_dense(joint, pairs, correlation, rng);
        });
    }

    #[test]
    fn the_rank_three_update_gives_the_joint_distance_of_a_fresh_factorisation() {
        for_random_hypotheses(|pairs, pose_cov, correlation, rng| {
            let joint = ThroughPose::new(pairs.len(), *pose_cov);
            check_against_dense(joint, pairs, correlation, rng);
        });
    }

    /// Random pairs under random pose covariances, some singular.
    fn for_random_hypotheses(
        check: impl Fn(&[Pair], &Matrix3<f64>, &dyn Fn(&Pair, &Pair) -> Matrix2<f64>, &mut StdRng),
    ) {
        let mut rng = StdRng::seed_from_u64(11);
        for round in 0..60 {
            let b = Matrix3::from_fn(|_, _| rng.random_range(-0.2..0.2));
            let pose_cov = if round % 4 == 0 {
                // Rank one: a pose known exactly but along one direction.
                let v = b.column(0).into_owned();
                v * v.transpose()
            } else {
                b * b.transpose() + Matrix3::identity() * 1e-4
            };
            let n = rng.random_range(1..25);
            let pairs: Vec<Pair> = (0..n)
                .map(|l| random_pair(&mut rng, l, &pose_cov))
                .collect();
            check(&pairs, &pose_cov, &through(&pose_cov), &mut rng);
        }
    }

    /// Pushes and pops pairs at random, as the search does, and checks the
    /// joint distance of every hypothesis against the dense one.
    fn check_against_dense<'a>(
        mut joint: impl JointDistance<'a>,
        pairs: &'a [Pair],
        correlation: &dyn Fn(&Pair, &Pair) -> Matrix2<f64>,
        rng: &mut StdRng,
    ) {
        let n = pairs.len();
        let mut stack: Vec<&Pair> = Vec::new();
        for _ in 0..3 * n {
            if !stack.is_empty() && rng.random_bool(0.3) {
                stack.pop();
                joint.pop();
            } else if stack.len() < n {
                let pair = &pairs[rng.random_range(0..n)];
                stack.push(pair);
                let d2 = joint.push(pair);
                let dense = dense_d2(&stack, correlation);
                // A pair pushed twice makes S singular: either may then fail.
                if let Some(d2) = d2.filter(|_| dense < 1e9) {
                    assert!(
                        (d2 - dense).abs() <= 1e-7 * dense.max(1.0),
                        "{d2} against {dense} with {} pairs",
                        stack.len()
                    );
                } else if !stack[..stack.len() - 1]
                    .iter()
                    .any(|p| std::ptr::eq(*p, pair))
                {
                    panic!("refused a positive definite hypothesis ({dense})");
                }
            }
            assert_eq!(joint.len(), stack.len());
        }
    }

    #[test]
    fn a_singular_joint_covariance_is_refused_and_can_be_popped() {
        let pose_cov = Matrix3::identity() * 0.01;
        let pair = Pair {
            landmark: 0,
            d2: 0.0,
            cost: 0.0,
            penalty: 0.0,
            innovation: Vector2::new(0.1, 0.0),
            h_pose: SMatrix::zeros(),
            s_pose: Matrix2::zeros(),
            s_local: Matrix2::zeros(),
            bhattacharyya: 0.0,
        };
        let correlation = through(&pose_cov);
        let mut general = JointFactor::new(2, &correlation);
        assert_eq!(general.push(&pair), None);
        general.pop();
        assert_eq!((general.len(), general.d2()), (0, 0.0));
        let mut low_rank = ThroughPose::new(2, pose_cov);
        assert_eq!(low_rank.push(&pair), None);
        low_rank.pop();
        assert_eq!((low_rank.len(), low_rank.d2()), (0, 0.0));
    }

    /// Three cones in a row 1 m apart, seen shifted by one spacing except
    /// for the first: each detection alone is nearest a wrong cone, but the
    /// pose error is shared, so the joint test keeps the consistent reading.
    #[test]
    fn a_shared_pose_error_is_explained_jointly() {
        let pose_cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(0.5, 0.5, 1e-6));
        let r = Matrix2::identity() * 0.01;
        let landmarks = [0.0, 1.0, 2.0, 3.0].map(|y| Vector2::new(5.0, y));
        // The car is 0.6 m off in y: every detection sits 0.6 m short.
        let detections: Vec<Vector2<f64>> = landmarks[..3]
            .iter()
            .map(|l| l - Vector2::new(0.0, 0.6))
            .collect();
        let h_pose = SMatrix::<f64, 2, 3>::new(-1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
        let candidates: Candidates = detections
            .iter()
            .map(|d| {
                let mut pairs: Vec<Pair> = landmarks
                    .iter()
                    .enumerate()
                    .filter_map(|(l, m)| Pair::new(l, d - m, h_pose, &r, &r, &pose_cov, 0.0, 13.8))
                    .collect();
                pairs.sort_by(|a, b| a.d2.total_cmp(&b.d2));
                pairs
            })
            .collect();
        // Alone, the last two detections are nearest the cone 0.4 m below.
        let best_alone: Vec<usize> = candidates.iter().map(|c| c[0].landmark).collect();
        assert_eq!(best_alone, vec![0, 0, 1]);
        let gate = |m| crate::frontend::chi2_99(2 * m);
        let correlation = through(&pose_cov);
        for correlation in [
            Correlation::ThroughPose(&pose_cov),
            Correlation::General(&correlation),
        ] {
            assert_eq!(
                jcbb(&candidates, correlation, gate),
                vec![Some(0), Some(1), Some(2)]
            );
        }
    }
}
