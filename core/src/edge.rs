//! Edge (factor) traits: an error function of one or two variables, with
//! numeric Jacobians by default and analytic ones where a type provides them.

use crate::variable::Variable;
use nalgebra::{SMatrix, SVector};

/// Step of the central differences used for numeric Jacobians.
pub const NUMERIC_STEP: f64 = 1e-6;

/// An edge on one variable (a prior).
///
/// The information matrix is not part of the edge: the graph stores it beside
/// the edge (as g2o's `BaseEdge` does), so it can be checked and repaired.
pub trait UnaryEdge<const E: usize, const D: usize>: Clone + Send + Sync + 'static {
    /// The variable type.
    type V: Variable<D>;
    /// Name for messages.
    const NAME: &'static str;

    /// The error vector e(x).
    fn error(&self, x: &Self::V) -> SVector<f64, E>;

    /// ∂e/∂δ at δ = 0, where x ⊞ δ is the variable's update.
    fn jacobian(&self, x: &Self::V) -> SMatrix<f64, E, D> {
        numeric_unary(self, x)
    }
}

/// A binary edge's error and its Jacobians with respect to each variable.
pub type Linearized<const E: usize, const D1: usize, const D2: usize> =
    (SVector<f64, E>, SMatrix<f64, E, D1>, SMatrix<f64, E, D2>);

/// A binary edge's share of the normal equations, for a weighted
/// information matrix W: the blocks (1, 1), (1, 2) and (2, 2) of JᵀWJ and
/// each variable's JᵀWe.
#[derive(Clone, Debug, PartialEq)]
pub struct NormalBlocks<const D1: usize, const D2: usize> {
    /// J₁ᵀWJ₁.
    pub h11: SMatrix<f64, D1, D1>,
    /// J₁ᵀWJ₂.
    pub h12: SMatrix<f64, D1, D2>,
    /// J₂ᵀWJ₂.
    pub h22: SMatrix<f64, D2, D2>,
    /// J₁ᵀWe.
    pub g1: SVector<f64, D1>,
    /// J₂ᵀWe.
    pub g2: SVector<f64, D2>,
}

/// An edge between two variables.
pub trait BinaryEdge<const E: usize, const D1: usize, const D2: usize>:
    Clone + Send + Sync + 'static
{
    /// The first variable's type.
    type V1: Variable<D1>;
    /// The second variable's type.
    type V2: Variable<D2>;
    /// Name for messages.
    const NAME: &'static str;

    /// The error vector e(x1, x2).
    fn error(&self, x1: &Self::V1, x2: &Self::V2) -> SVector<f64, E>;

    /// (∂e/∂δ1, ∂e/∂δ2) at δ = 0. Numeric central differences unless overridden.
    fn jacobians(
        &self,
        x1: &Self::V1,
        x2: &Self::V2,
    ) -> (SMatrix<f64, E, D1>, SMatrix<f64, E, D2>) {
        numeric_binary(self, x1, x2)
    }

    /// The error and both Jacobians, as each iteration needs them. Override
    /// when the two share work (EDGE_SE2 and EDGE_SE2_XY compute the pose's
    /// sine and cosine once); the result must equal `error` and `jacobians`.
    fn linearize(&self, x1: &Self::V1, x2: &Self::V2) -> Linearized<E, D1, D2> {
        let (j1, j2) = self.jacobians(x1, x2);
        (self.error(x1, x2), j1, j2)
    }

    /// The edge's share of the normal equations from its linearisation `lin`
    /// and the symmetric weighted information `w`. Override when the
    /// Jacobians have structure that saves most of the products (EDGE_SE2);
    /// the result must equal this one to rounding.
    fn normal_blocks(
        &self,
        lin: &Linearized<E, D1, D2>,
        w: &SMatrix<f64, E, E>,
    ) -> NormalBlocks<D1, D2> {
        let (e, j1, j2) = lin;
        let (wj1, wj2) = (w * j1, w * j2);
        NormalBlocks {
            h11: j1.transpose() * wj1,
            h12: j1.transpose() * wj2,
            h22: j2.transpose() * wj2,
            g1: wj1.transpose() * e,
            g2: wj2.transpose() * e,
        }
    }

    /// The second variable predicted from the first and the measurement, used by
    /// spanning-tree initialisation (g2o `initialEstimate`). `None` if unknown.
    fn predict_second(&self, _x1: &Self::V1) -> Option<Self::V2> {
        None
    }

    /// The first variable predicted from the second, if the edge can invert.
    fn predict_first(&self, _x2: &Self::V2) -> Option<Self::V1> {
        None
    }
}

/// An edge on one variable given by its error alone: its dimensions come
/// from the variable's type, and its Jacobian is numeric. Every such type
/// is a [`UnaryEdge`]; implement `UnaryEdge` instead for an analytic
/// Jacobian.
pub trait NumericUnaryEdge<const E: usize>: Clone + Send + Sync + 'static {
    /// The variable type.
    type V;
    /// Name for messages.
    const NAME: &'static str;

    /// The error vector e(x).
    fn error(&self, x: &Self::V) -> SVector<f64, E>;
}

impl<T, const E: usize, const D: usize> UnaryEdge<E, D> for T
where
    T: NumericUnaryEdge<E>,
    T::V: Variable<D>,
{
    type V = T::V;
    const NAME: &'static str = <T as NumericUnaryEdge<E>>::NAME;

    fn error(&self, x: &Self::V) -> SVector<f64, E> {
        NumericUnaryEdge::error(self, x)
    }
}

/// An edge between two variables given by its error alone: its dimensions
/// come from the variables' types (`impl NumericBinaryEdge<1> for Range {
/// type V1 = SE2; type V2 = Vector2<f64>; … }`), and its Jacobians are
/// numeric. Every such type is a [`BinaryEdge`]; implement `BinaryEdge`
/// instead for analytic Jacobians, whose sizes name the dimensions.
pub trait NumericBinaryEdge<const E: usize>: Clone + Send + Sync + 'static {
    /// The first variable's type.
    type V1;
    /// The second variable's type.
    type V2;
    /// Name for messages.
    const NAME: &'static str;

    /// The error vector e(x1, x2).
    fn error(&self, x1: &Self::V1, x2: &Self::V2) -> SVector<f64, E>;
}

impl<T, const E: usize, const D1: usize, const D2: usize> BinaryEdge<E, D1, D2> for T
where
    T: NumericBinaryEdge<E>,
    T::V1: Variable<D1>,
    T::V2: Variable<D2>,
{
    type V1 = T::V1;
    type V2 = T::V2;
    const NAME: &'static str = <T as NumericBinaryEdge<E>>::NAME;

    fn error(&self, x1: &Self::V1, x2: &Self::V2) -> SVector<f64, E> {
        NumericBinaryEdge::error(self, x1, x2)
    }
}

/// Central-difference Jacobian of a function of one variable.
pub fn numeric_jacobian<V, const E: usize, const D: usize>(
    x: &V,
    f: impl Fn(&V) -> SVector<f64, E>,
) -> SMatrix<f64, E, D>
where
    V: Variable<D>,
{
    let mut j = SMatrix::<f64, E, D>::zeros();
    let scale = 0.5 / NUMERIC_STEP;
    for k in 0..D {
        let mut d = SVector::<f64, D>::zeros();
        d[k] = NUMERIC_STEP;
        let plus = f(&x.oplus(&d));
        d[k] = -NUMERIC_STEP;
        let minus = f(&x.oplus(&d));
        j.set_column(k, &((plus - minus) * scale));
    }
    j
}

/// Numeric Jacobian of a unary edge.
pub fn numeric_unary<T, const E: usize, const D: usize>(edge: &T, x: &T::V) -> SMatrix<f64, E, D>
where
    T: UnaryEdge<E, D>,
{
    numeric_jacobian(x, |v| edge.error(v))
}

/// Numeric Jacobians of a binary edge.
pub fn numeric_binary<T, const E: usize, const D1: usize, const D2: usize>(
    edge: &T,
    x1: &T::V1,
    x2: &T::V2,
) -> (SMatrix<f64, E, D1>, SMatrix<f64, E, D2>)
where
    T: BinaryEdge<E, D1, D2>,
{
    (
        numeric_jacobian(x1, |v| edge.error(v, x2)),
        numeric_jacobian(x2, |v| edge.error(x1, v)),
    )
}
