//! Cairn's supernodal Cholesky: its structure, found on the vertex blocks
//! (the `symbolic` module: faer's supernodes and layout, without faer's
//! scalar analysis), and its numeric factorisation and solves, with faer's
//! dense kernels for each supernode.
//!
//! The factorisation is right-looking: each supernode, once its columns
//! hold all their updates, is factorised (dense Cholesky of its diagonal
//! block, a triangular solve for the rows below), then forms its whole update
//! L₂₁L₂₁ᵀ in one dense product and subtracts it from the later supernodes'
//! columns. faer's own numeric factorisation is left-looking: each supernode
//! gathers the updates of its descendants one product at a time. On pose
//! graphs, whose supernodes are narrow, one product per supernode is 15–25%
//! faster (BENCHMARKS.md) and gives the same values. The forward
//! substitution of a solve can run inside the factorisation, each supernode
//! right after it is factorised, while its values are still in cache.

use crate::hessian_layout::HessianLayout;
use crate::linear::NotPositiveDefinite;
use crate::structure::group_by_key;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{
    LltError, LltRegularization, cholesky_in_place, cholesky_in_place_scratch,
};
use faer::linalg::matmul::triangular::{BlockStructure, matmul};
use faer::linalg::triangular_solve::solve_lower_triangular_in_place;
use faer::reborrow::*;
use faer::{Accum, MatMut, MatRef, Par};
use std::ops::Range;

mod symbolic;
pub(crate) use symbolic::SupernodalSymbolic;

/// Where the entries of H go in L, and where each supernode's update goes.
pub(crate) struct SupernodalNumeric {
    /// For each entry of H's upper triangle, its position among L's values
    /// (`u32`: half the memory to read in each factorisation).
    h_to_l: Vec<u32>,
    /// Per supernode, the runs of its rows below the diagonal block that
    /// fall in one later supernode: `(first row, end row, rel start)`.
    groups: Vec<(u32, u32, usize)>,
    group_start: Vec<usize>,
    /// For each group, the positions within that later supernode's columns
    /// of the rows from the group's first on.
    rel: Vec<u32>,
    /// Per row below a supernode's diagonal block (in the structure's row
    /// order), the position among L's values where its column starts.
    column_start: Vec<u32>,
    /// One supernode's update, L₂₁L₂₁ᵀ (lower triangle, column-major).
    update: Vec<f64>,
    scratch: MemBuffer,
    par: Par,
}

/// Position of row `r` within the rows of the supernode starting at column
/// `start` with `width` columns and rows `below` under its diagonal block.
fn position(r: usize, start: usize, width: usize, below: &[usize]) -> Option<usize> {
    if r < start + width {
        r.checked_sub(start)
    } else {
        below.binary_search(&r).ok().map(|p| width + p)
    }
}

/// For each entry of H's upper triangle (laid out by `layout`), its
/// position among L's values. H's entry (i, j), i ≤ j, is L's (j, i):
/// column i, row j. A block of H, rows of block r and columns of block c,
/// lies in the columns of r's supernode s (supernodes are runs of whole
/// blocks), where c's rows are consecutive: its entry (a, b) is at
/// base + a·height + b, base being c's first row in r's first column. One
/// search per block; `None` if a block's rows are not where the structure
/// puts them.
fn h_positions(
    symbolic: &SupernodalSymbolic,
    layout: &HessianLayout,
    supernode_of: &[usize],
) -> Option<Vec<u32>> {
    let val_ptr = symbolic.val_ptr();
    let (block_ptr, block_rows) = (layout.blocks().col_ptr(), layout.blocks().row_idx());
    let (first, dims) = (layout.block_column(), layout.dims());
    let mut h_to_l = Vec::with_capacity(layout.nnz());
    // The current block column's blocks: (base, height, rows).
    let mut bases: Vec<(usize, usize, usize)> = Vec::new();
    for c in 0..dims.len() {
        let (cc, dc) = (first[c], dims[c]);
        bases.clear();
        for &r in &block_rows[block_ptr[c]..block_ptr[c + 1]] {
            let s = *supernode_of.get(first[r])?;
            let (start, width, height, below) = symbolic.supernode(s);
            let p = position(cc, start, width, below)?;
            if position(cc + dc - 1, start, width, below)? != p + dc - 1 {
                return None;
            }
            bases.push((
                val_ptr[s] + (first[r] - start) * height + p,
                height,
                dims[r],
            ));
        }
        for b in 0..dc {
            let last = bases.len() - 1;
            for (k, &(base, height, rows)) in bases.iter().enumerate() {
                // The diagonal block, last, down to the diagonal.
                let rows = if k == last { b + 1 } else { rows };
                h_to_l.extend((0..rows).map(|a| (base + a * height + b) as u32));
            }
        }
    }
    Some(h_to_l)
}

/// The positions `rel` of the groups' rows (each group's source supernode's
/// rows from the group's first on) in the group's target supernode: target
/// by target, through a map from row to position there.
fn update_positions(
    symbolic: &SupernodalSymbolic,
    groups: &[(u32, u32, usize)],
    targets: &[(u32, u32)],
    len: usize,
) -> Option<Vec<u32>> {
    let n_supernodes = symbolic.n_supernodes();
    let by_target: Vec<(u32, u32)> = (0..groups.len() as u32)
        .map(|g| (targets[g as usize].0, g))
        .collect();
    let (start_of, order) = group_by_key(n_supernodes, &by_target);
    // Each row's supernode (the last one mapped that holds it) and position there.
    let mut position = vec![(u32::MAX, 0u32); symbolic.dim()];
    let mut rel = vec![0u32; len];
    for s in 0..n_supernodes {
        let (start, width, _, below) = symbolic.supernode(s);
        let rows = (start..start + width).chain(below.iter().copied());
        for (p, r) in rows.enumerate() {
            position[r] = (s as u32, p as u32);
        }
        for &g in &order[start_of[s]..start_of[s + 1]] {
            let (first, _, rel_start) = groups[g as usize];
            let (_, _, _, pattern) = symbolic.supernode(targets[g as usize].1 as usize);
            let pattern = &pattern[first as usize..];
            for (out, &r) in rel[rel_start..][..pattern.len()].iter_mut().zip(pattern) {
                let (owner, p) = position[r];
                // The structure puts every row there.
                if owner != s as u32 {
                    return None;
                }
                *out = p;
            }
        }
    }
    Some(rel)
}

impl SupernodalNumeric {
    /// The plan for H (laid out by `layout`) on `symbolic` (the
    /// structure of its factor). `None` if the pattern does not fit the
    /// structure (which the analysis rules out), the plan would outgrow the
    /// factor, or the factor has more values than its `u32` positions reach
    /// (32 GB of them).
    pub(crate) fn new(
        symbolic: &SupernodalSymbolic,
        layout: &HessianLayout,
        par: Par,
    ) -> Option<Self> {
        u32::try_from(symbolic.len_val()).ok()?;
        let n_supernodes = symbolic.n_supernodes();
        let val_ptr = symbolic.val_ptr();
        let mut supernode_of = vec![0; symbolic.dim()];
        for s in 0..n_supernodes {
            let (start, width, _, _) = symbolic.supernode(s);
            supernode_of[start..start + width].fill(s);
        }
        let h_to_l = h_positions(symbolic, layout, &supernode_of)?;
        // Each supernode d's rows below, in runs that fall in one later
        // supernode s (a group); column j of d's update goes to s's column
        // of the row j, its rows from j on to their positions there (rel).
        let (mut groups, mut group_start, mut targets) = (Vec::new(), vec![0], Vec::new());
        let mut column_start = Vec::new();
        let (mut widest, mut tallest, mut rel_len) = (0, 0, 0);
        for d in 0..n_supernodes {
            let (_, width, _, pattern) = symbolic.supernode(d);
            (widest, tallest) = (widest.max(width), tallest.max(pattern.len()));
            let mut j = 0;
            while j < pattern.len() {
                let s = supernode_of[pattern[j]];
                let (start, width, rows, _) = symbolic.supernode(s);
                let end = j + pattern[j..].partition_point(|&r| r < start + width);
                groups.push((j as u32, end as u32, rel_len));
                targets.push((s as u32, d as u32));
                rel_len += pattern.len() - j;
                column_start.extend(
                    pattern[j..end]
                        .iter()
                        .map(|&c| (val_ptr[s] + (c - start) * rows) as u32),
                );
                j = end;
            }
            group_start.push(groups.len());
        }
        if rel_len > symbolic.len_val() {
            return None;
        }
        let rel = update_positions(symbolic, &groups, &targets, rel_len)?;
        let req = cholesky_in_place_scratch::<f64>(widest, par, Default::default());
        Some(Self {
            h_to_l,
            groups,
            group_start,
            rel,
            column_start,
            update: vec![0.0; tallest * tallest],
            scratch: MemBuffer::try_new(req).ok()?,
            par,
        })
    }

    /// Factorises H, given by the values of its upper triangle, into
    /// `values` (faer's supernodal layout).
    ///
    /// With `forward` (the right-hand side, and room for the rows below any
    /// one supernode's diagonal block, as the solves take), also runs the
    /// forward substitution L y = b in place, each supernode right after it
    /// is factorised (while its values are in cache); [`backward_solve`]
    /// then finishes the solve.
    pub(crate) fn factorize(
        &mut self,
        symbolic: &SupernodalSymbolic,
        h: &[f64],
        values: &mut [f64],
        mut forward: Option<(&mut [f64], &mut [f64])>,
    ) -> Result<(), NotPositiveDefinite> {
        values.fill(0.0);
        for (&p, &x) in self.h_to_l.iter().zip(h) {
            values[p as usize] = x;
        }
        let val_ptr = symbolic.val_ptr();
        let mut first_row = 0;
        for d in 0..symbolic.n_supernodes() {
            let (start, width, rows, rows_below) = symbolic.supernode(d);
            let below = rows - width;
            let (done, later) = values.split_at_mut(val_ptr[d + 1]);
            let l = MatMut::from_column_major_slice_mut(&mut done[val_ptr[d]..], rows, width);
            let (mut diagonal, mut l21) = l.split_at_row_mut(width);
            let stack = MemStack::new(&mut self.scratch);
            cholesky_in_place(
                diagonal.rb_mut(),
                LltRegularization::default(),
                self.par,
                stack,
                Default::default(),
            )
            .map_err(|LltError::NonPositivePivot { index }| NotPositiveDefinite {
                pivot: index + start,
            })?;
            solve_lower_triangular_in_place(diagonal.rb(), l21.rb_mut().transpose_mut(), self.par);
            if below > 0 {
                let groups = self.group_start[d]..self.group_start[d + 1];
                let column_start = first_row..first_row + below;
                self.subtract_update(l21.rb(), groups, column_start, later, val_ptr[d + 1]);
                first_row += below;
            }
            if let Some((x, work)) = forward.as_mut() {
                let l = &done[val_ptr[d]..];
                forward_step(start, width, l, rows_below, x, &mut work[..below]);
            }
        }
        Ok(())
    }

    /// Subtracts a supernode's update L₂₁L₂₁ᵀ from the later supernodes'
    /// columns, `later` (L's values from `offset` on), through its `groups`
    /// and the `column_start` entries of its rows below.
    fn subtract_update(
        &mut self,
        l21: MatRef<'_, f64>,
        groups: Range<usize>,
        column_start: Range<usize>,
        later: &mut [f64],
        offset: usize,
    ) {
        let below = l21.nrows();
        let mut update =
            MatMut::from_column_major_slice_mut(&mut self.update[..below * below], below, below);
        matmul(
            update.rb_mut(),
            BlockStructure::TriangularLower,
            Accum::Replace,
            l21,
            BlockStructure::Rectangular,
            l21.transpose(),
            BlockStructure::Rectangular,
            1.0,
            self.par,
        );
        // Column j of the update goes to the column of row j of the
        // pattern, in the supernode holding it; row i ≥ j to position
        // rel[i] there.
        let column_start = &self.column_start[column_start];
        for &(first, end, rel_start) in &self.groups[groups] {
            let (first, end) = (first as usize, end as usize);
            let rel = &self.rel[rel_start..rel_start + below - first];
            for j in first..end {
                let rel = &rel[j - first..];
                let last = rel[rel.len() - 1] as usize;
                let target = &mut later[column_start[j] as usize - offset..][..=last];
                for (&r, &u) in rel.iter().zip(&self.update[j * below + j..(j + 1) * below]) {
                    target[r as usize] -= u;
                }
            }
        }
    }
}

/// A supernodal factor: Cairn's structure (from the block analysis), its
/// factorisation plan, the values and the solves' work space.
pub(crate) struct SupernodalCholesky {
    symbolic: SupernodalSymbolic,
    numeric: SupernodalNumeric,
    values: Vec<f64>,
    /// Rows below one supernode's diagonal block, for the solves (the
    /// forward substitution in the factorisation too).
    work: Vec<f64>,
}

impl std::fmt::Debug for SupernodalCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SupernodalCholesky")
            .field("supernodes", &self.symbolic.n_supernodes())
            .field("values", &self.values.len())
            .finish()
    }
}

impl SupernodalCholesky {
    /// The factor of H (laid out by `layout`) with the structure
    /// `symbolic`; `None` if its plan would outgrow the factor.
    pub(crate) fn new(
        symbolic: SupernodalSymbolic,
        layout: &HessianLayout,
        par: Par,
    ) -> Option<Self> {
        let numeric = SupernodalNumeric::new(&symbolic, layout, par)?;
        Some(Self {
            numeric,
            values: vec![0.0; symbolic.len_val()],
            work: vec![0.0; symbolic.most_below()],
            symbolic,
        })
    }

    /// Stored values of L.
    pub(crate) fn len_val(&self) -> usize {
        self.values.len()
    }

    /// Factorises H, given by the values of its upper triangle; with
    /// `forward`, also runs the forward substitution on it in place.
    pub(crate) fn factorize(
        &mut self,
        h: &[f64],
        forward: Option<&mut [f64]>,
    ) -> Result<(), NotPositiveDefinite> {
        let forward = forward.map(|x| (x, &mut self.work[..]));
        self.numeric
            .factorize(&self.symbolic, h, &mut self.values, forward)
    }

    /// Solves L Lᵀ x = b in place.
    pub(crate) fn solve_in_place(&mut self, x: &mut [f64]) {
        supernodal_solve(&self.symbolic, &self.values, x, &mut self.work);
    }

    /// Solves Lᵀ x = y in place, after a factorisation that ran the forward
    /// substitution.
    pub(crate) fn backward_solve(&mut self, x: &mut [f64]) {
        backward_solve(&self.symbolic, &self.values, x, &mut self.work);
    }

    /// The structure and values as the selected inverse takes them.
    pub(crate) fn supernodes(&self) -> crate::selected_inverse::Supernodes {
        self.symbolic.supernodes(self.values.clone())
    }
}

/// `a · b` summed in eight independent lanes, which the compiler keeps in
/// SIMD registers (a single running sum waits on each addition in turn).
pub(crate) fn dot_in_lanes(a: &[f64], b: &[f64]) -> f64 {
    let mut lanes = [0.0; 8];
    let (a_chunks, b_chunks) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f64 = a_chunks
        .remainder()
        .iter()
        .zip(b_chunks.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in a_chunks.zip(b_chunks) {
        for k in 0..8 {
            lanes[k] += x[k] * y[k];
        }
    }
    lanes.iter().sum::<f64>() + tail
}

/// Supernode `s`'s first column, width, values (column-major, the
/// diagonal block's rows first) and the rows below its diagonal block.
fn supernode_values<'a>(
    symbolic: &'a SupernodalSymbolic,
    values: &'a [f64],
    s: usize,
) -> (usize, usize, &'a [f64], &'a [usize]) {
    let (start, width, _, below) = symbolic.supernode(s);
    let val_ptr = symbolic.val_ptr();
    (start, width, &values[val_ptr[s]..val_ptr[s + 1]], below)
}

/// The forward substitution's step for one supernode (first column
/// `start`, `width` columns, `values`, rows `below` under its diagonal
/// block): solves its diagonal block, then subtracts its rows below from
/// `x` (summed in `tmp` first, so that they are read contiguously).
fn forward_step(
    start: usize,
    width: usize,
    values: &[f64],
    below: &[usize],
    x: &mut [f64],
    tmp: &mut [f64],
) {
    let rows = width + below.len();
    tmp.fill(0.0);
    for (j, column) in values[..rows * width].chunks_exact(rows).enumerate() {
        let xj = x[start + j] / column[j];
        x[start + j] = xj;
        for (xi, &l) in x[start + j + 1..start + width]
            .iter_mut()
            .zip(&column[j + 1..width])
        {
            *xi -= l * xj;
        }
        for (t, &l) in tmp.iter_mut().zip(&column[width..]) {
            *t += l * xj;
        }
    }
    for (&r, &t) in below.iter().zip(tmp.iter()) {
        x[r] -= t;
    }
}

/// Solves L Lᵀ x = b in place for a supernodal factor L (unpermuted; faer's
/// layout). faer's own solve multiplies each supernode through its general
/// dense kernels, which on the small supernodes of pose graphs (3 to a few
/// dozen columns) costs more than these loops.
fn supernodal_solve(
    symbolic: &SupernodalSymbolic,
    values: &[f64],
    x: &mut [f64],
    work: &mut [f64],
) {
    for s in 0..symbolic.n_supernodes() {
        let (start, width, values, below) = supernode_values(symbolic, values, s);
        forward_step(start, width, values, below, x, &mut work[..below.len()]);
    }
    backward_solve(symbolic, values, x, work);
}

/// Solves Lᵀ x = y in place (the second half of [`supernodal_solve`]).
fn backward_solve(symbolic: &SupernodalSymbolic, values: &[f64], x: &mut [f64], work: &mut [f64]) {
    for s in (0..symbolic.n_supernodes()).rev() {
        let (start, size, values, below) = supernode_values(symbolic, values, s);
        let rows = size + below.len();
        let tmp = &mut work[..below.len()];
        for (t, &r) in tmp.iter_mut().zip(below) {
            *t = x[r];
        }
        for (j, column) in values.chunks_exact(rows).enumerate().rev() {
            // Two dot products in independent lanes: a running sum would
            // wait on each addition, and the diagonal blocks of the large
            // supernodes near the root hold a good part of the factor.
            let diagonal = dot_in_lanes(&column[j + 1..size], &x[start + j + 1..start + size]);
            let xj = x[start + j] - diagonal - dot_in_lanes(&column[size..], tmp);
            x[start + j] = xj / column[j];
        }
    }
}

#[cfg(test)]
mod tests;
