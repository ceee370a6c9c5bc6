//! Where an edge's linearisation goes, shared by the factor groups (which
//! write it) and the solvers (which lay it out): its slot in the
//! linearisation buffer, summed into H afterwards when edges are linearised
//! in parallel, or its [`BlockTarget`]s in H itself when one thread adds
//! them there directly ([`Scatter`]).
//!
//! For an edge on vertices with tangent dimensions `dims`, the slot holds the
//! upper block triangle of JᵀΩJ — blocks (a, b) with a ≤ b in the edge's vertex
//! order, each `dims[a] × dims[b]` column-major — then JᵀΩe per vertex, then χ².

use nalgebra::{SMatrix, SVector};

/// Offset of block (a, b), a ≤ b, within an edge's slot.
pub fn block_offset(dims: &[usize], a: usize, b: usize) -> usize {
    debug_assert!(a <= b && b < dims.len());
    let mut off = 0;
    for i in 0..dims.len() {
        for j in i..dims.len() {
            if (i, j) == (a, b) {
                return off;
            }
            off += dims[i] * dims[j];
        }
    }
    unreachable!("block ({a}, {b}) outside an edge of arity {}", dims.len())
}

/// Offset of vertex `a`'s gradient segment JₐᵀΩe.
pub fn gradient_offset(dims: &[usize], a: usize) -> usize {
    let n = dims.len();
    let hess: usize = (0..n)
        .map(|i| (i..n).map(|j| dims[i] * dims[j]).sum::<usize>())
        .sum();
    hess + dims[..a].iter().sum::<usize>()
}

/// Offset of the edge's χ².
pub fn chi2_offset(dims: &[usize]) -> usize {
    gradient_offset(dims, dims.len())
}

/// Scalars in one edge's slot.
pub fn stride(dims: &[usize]) -> usize {
    chi2_offset(dims) + 1
}

/// Where one block of an edge's JᵀΩJ adds into H, whose upper triangle is
/// stored by compressed columns with each vertex's columns together: column
/// j of the target block starts at `first + j·above + j(j+1)/2`, because
/// every column of a block column holds the rows above its diagonal block
/// (`above` of them) and the diagonal block's upper triangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockTarget {
    /// Index in H's values of the target block's entry (0, 0).
    pub first: u32,
    /// Rows above the diagonal block in each column of the target block column.
    pub above: u32,
    /// Whether the edge's block lands transposed (its first vertex's columns
    /// come after its second's).
    pub transposed: bool,
}

impl BlockTarget {
    /// The target of a block on a fixed vertex: nothing is added.
    pub const NONE: Self = Self {
        first: u32::MAX,
        above: 0,
        transposed: false,
    };

    fn column(&self, j: usize) -> usize {
        self.first as usize + j * self.above as usize + j * (j + 1) / 2
    }

    /// Adds the off-diagonal block `b` (an edge's block (a, b), a < b).
    #[inline]
    pub fn add<const R: usize, const C: usize>(&self, hessian: &mut [f64], b: &SMatrix<f64, R, C>) {
        if self.first == u32::MAX {
            return;
        }
        if self.transposed {
            for j in 0..R {
                let col = &mut hessian[self.column(j)..][..C];
                for (i, h) in col.iter_mut().enumerate() {
                    *h += b[(j, i)];
                }
            }
        } else {
            for j in 0..C {
                let col = &mut hessian[self.column(j)..][..R];
                for (i, h) in col.iter_mut().enumerate() {
                    *h += b[(i, j)];
                }
            }
        }
    }

    /// Adds the upper triangle of the diagonal block `b` (an edge's block
    /// (a, a); square).
    #[inline]
    pub fn add_diagonal<const R: usize, const C: usize>(
        &self,
        hessian: &mut [f64],
        b: &SMatrix<f64, R, C>,
    ) {
        debug_assert_eq!(R, C);
        if self.first == u32::MAX {
            return;
        }
        for j in 0..C {
            let col = &mut hessian[self.column(j)..][..=j];
            for (i, h) in col.iter_mut().enumerate() {
                *h += b[(i, j)];
            }
        }
    }
}

/// Adds an edge's gradient segment at column `first` (`u32::MAX`: a fixed
/// vertex, nothing is added).
#[inline]
pub fn add_gradient<const D: usize>(gradient: &mut [f64], first: u32, g: &SVector<f64, D>) {
    if first != u32::MAX {
        for (o, x) in gradient[first as usize..][..D].iter_mut().zip(g.iter()) {
            *o += x;
        }
    }
}

/// Where a factor group's edges add into H and the gradient, for
/// [`crate::FactorGroup::linearize_into`]: per edge, one [`BlockTarget`] per
/// block (a, b), a ≤ b, in slot order, and the first column of each vertex.
pub struct Scatter<'a> {
    /// Block targets, `arity·(arity + 1)/2` per edge.
    pub blocks: &'a [BlockTarget],
    /// First column of each of an edge's vertices, `arity` per edge.
    pub columns: &'a [u32],
    /// H's values, added to.
    pub hessian: &'a mut [f64],
    /// The gradient, added to.
    pub gradient: &'a mut [f64],
    /// Each edge's objective contribution, written.
    pub chi2: &'a mut [f64],
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binary_layout_is_packed_in_order() {
        let d = [3, 2];
        assert_eq!(block_offset(&d, 0, 0), 0);
        assert_eq!(block_offset(&d, 0, 1), 9);
        assert_eq!(block_offset(&d, 1, 1), 15);
        assert_eq!(gradient_offset(&d, 0), 19);
        assert_eq!(gradient_offset(&d, 1), 22);
        assert_eq!(chi2_offset(&d), 24);
        assert_eq!(stride(&d), 25);
        assert_eq!(stride(&[6]), 36 + 6 + 1);
    }
}
