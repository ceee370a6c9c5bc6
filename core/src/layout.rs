//! Layout of one edge's slot in the linearisation buffer, shared by the factor
//! groups (which write it) and the solvers (which gather from it).
//!
//! For an edge on vertices with tangent dimensions `dims`, the slot holds the
//! upper block triangle of JᵀΩJ — blocks (a, b) with a ≤ b in the edge's vertex
//! order, each `dims[a] × dims[b]` column-major — then JᵀΩe per vertex, then χ².

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
