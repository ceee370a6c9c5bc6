//! The supernodal structure of L, found on the vertex blocks.
//!
//! Every column of a vertex block has the pattern of the block's first
//! column below the block, so a supernode is a run of whole blocks and the
//! block analysis (the `simplicial` module's elimination tree and pattern)
//! already holds everything a scalar analysis would find, at a ninth of the
//! entries for 2D poses. The supernodes are those faer's analysis finds:
//! the same fundamental supernodes, relaxed by the same rule and limits, so
//! that the factor and its layout are the same (tested).

use crate::SolveError;
use crate::simplicial::SimplicialSymbolic;

/// faer's default relaxation: a child supernode merges into its parent when
/// the merged width is at most `.0` and at most a fraction `.1` of the
/// merged supernode's entries are then explicit zeros.
const RELAX: [(usize, f64); 4] = [(4, 1.0), (16, 0.8), (48, 0.1), (usize::MAX, 0.05)];

/// Supernodes of L: runs of columns stored together as one dense panel,
/// column-major, the diagonal block's rows first, then the rows below it
/// (faer's supernodal layout).
#[derive(Debug)]
pub(crate) struct SupernodalSymbolic {
    /// First column of each supernode, and the dimension at the end.
    begin: Vec<usize>,
    /// Where each supernode's values start, and their number at the end.
    val_ptr: Vec<usize>,
    /// Where each supernode's rows below its diagonal block start in `row_idx`.
    row_ptr: Vec<usize>,
    /// The rows below each supernode's diagonal block, ascending.
    row_idx: Vec<usize>,
}

/// A run of fundamental supernodes merged into one: its first block, its
/// width and the explicit zeros the merges added.
struct Run {
    first_block: usize,
    width: usize,
    zeros: usize,
}

/// Whether a child supernode (`child` columns, `child_degree` rows below)
/// with `zeros` explicit zeros merges into its parent (`parent` columns,
/// `degree` rows below); the merged supernode's zeros if it does.
fn relaxed_merge(
    (child, child_degree, zeros): (usize, usize, usize),
    (parent, degree): (usize, usize),
) -> Option<usize> {
    // The child's rows below are among the parent's columns and rows below:
    // the rest of those become zeros in the child's columns.
    let new_zeros = (parent + degree - child_degree) * child;
    if new_zeros == 0 {
        return Some(zeros);
    }
    let total = zeros + new_zeros;
    let width = child + parent;
    let entries = (width * (width + 1) / 2 + degree * width) as f64;
    RELAX
        .iter()
        .any(|&(widest, fraction)| widest >= width && entries * fraction >= total as f64)
        .then_some(total)
}

impl SupernodalSymbolic {
    /// The supernodes of the factor the block analysis `blocks` describes.
    pub(crate) fn from_blocks(blocks: &SimplicialSymbolic) -> Result<Self, SolveError> {
        let first = blocks.block_column();
        let nb = first.len() - 1;
        let width = |b: usize| first[b + 1] - first[b];
        let degree = |b: usize| blocks.degree(b);
        let parent = |b: usize| blocks.parent(b);
        let mut children = vec![0u32; nb];
        for b in 0..nb {
            if let Some(p) = parent(b) {
                children[p] += 1;
            }
        }
        // Fundamental supernodes: a block joins the one before when it is
        // that block's parent, has no other child, and the rows below
        // continue that block's (the same pattern).
        let mut fundamental = vec![0];
        for (b, &children) in children.iter().enumerate().skip(1) {
            let joins =
                parent(b - 1) == Some(b) && children == 1 && degree(b - 1) == width(b) + degree(b);
            if !joins {
                fundamental.push(b);
            }
        }
        fundamental.push(nb);
        // Relaxation: each fundamental supernode may take in the run just
        // before it when that run's last supernode is its child.
        let mut runs: Vec<Run> = Vec::new();
        for f in fundamental.windows(2).filter(|w| w[0] < w[1]) {
            let (start, end) = (f[0], f[1]);
            let own = (first[end] - first[start], degree(end - 1));
            let merged = runs.last().and_then(|run| {
                let child_last = start - 1;
                parent(child_last).filter(|p| (start..end).contains(p))?;
                relaxed_merge((run.width, degree(child_last), run.zeros), own)
            });
            match (merged, runs.last_mut()) {
                (Some(zeros), Some(run)) => {
                    run.width += own.0;
                    run.zeros = zeros;
                }
                _ => runs.push(Run {
                    first_block: start,
                    width: own.0,
                    zeros: 0,
                }),
            }
        }
        let too_large = SolveError::TooLarge {
            entries: usize::MAX,
        };
        let n_supernodes = runs.len();
        let mut supernode_of = vec![0usize; nb];
        let (mut begin, mut val_ptr, mut row_ptr) = (vec![0], vec![0], vec![0]);
        for (s, run) in runs.iter().enumerate() {
            let end_block = runs.get(s + 1).map_or(nb, |r| r.first_block);
            supernode_of[run.first_block..end_block].fill(s);
            let below = degree(end_block - 1);
            let values = (run.width + below)
                .checked_mul(run.width)
                .and_then(|v| v.checked_add(val_ptr[s]))
                .ok_or(too_large.clone())?;
            begin.push(first[end_block]);
            val_ptr.push(values);
            row_ptr.push(row_ptr[s] + below);
        }
        // Supernode s's rows below: every block row k reaching one of its
        // columns, in ascending k, so each list comes out sorted.
        let mut row_idx = vec![0usize; row_ptr[n_supernodes]];
        let mut next = row_ptr.clone();
        let mut last_row = vec![usize::MAX; n_supernodes];
        for k in 0..nb {
            for &j in blocks.row(k) {
                let s = supernode_of[j as usize];
                if s != supernode_of[k] && last_row[s] != k {
                    last_row[s] = k;
                    row_idx[next[s]..][..width(k)]
                        .iter_mut()
                        .zip(first[k]..)
                        .for_each(|(r, c)| *r = c);
                    next[s] += width(k);
                }
            }
        }
        debug_assert_eq!(next[..n_supernodes], row_ptr[1..]);
        Ok(Self {
            begin,
            val_ptr,
            row_ptr,
            row_idx,
        })
    }

    /// Number of supernodes.
    pub(crate) fn n_supernodes(&self) -> usize {
        self.begin.len() - 1
    }

    /// Dimension of H.
    pub(crate) fn dim(&self) -> usize {
        self.begin[self.n_supernodes()]
    }

    /// Stored values of L.
    pub(crate) fn len_val(&self) -> usize {
        self.val_ptr[self.n_supernodes()]
    }

    /// Where each supernode's values start, and their number at the end.
    pub(crate) fn val_ptr(&self) -> &[usize] {
        &self.val_ptr
    }

    /// Supernode `s`'s first column, width, number of rows (the diagonal
    /// block's and those below) and the rows below.
    pub(crate) fn supernode(&self, s: usize) -> (usize, usize, usize, &[usize]) {
        let (start, end) = (self.begin[s], self.begin[s + 1]);
        let below = &self.row_idx[self.row_ptr[s]..self.row_ptr[s + 1]];
        (start, end - start, end - start + below.len(), below)
    }

    /// The most rows below any supernode's diagonal block.
    pub(crate) fn most_below(&self) -> usize {
        self.row_ptr
            .windows(2)
            .map(|w| w[1] - w[0])
            .max()
            .unwrap_or(0)
    }

    /// The structure as the selected inverse takes it, with the factor's `values`.
    pub(crate) fn supernodes(&self, values: Vec<f64>) -> crate::selected_inverse::Supernodes {
        let n = self.n_supernodes();
        crate::selected_inverse::Supernodes {
            begin: self.begin[..n].to_vec(),
            end: self.begin[1..].to_vec(),
            val_ptr: self.val_ptr.clone(),
            row_ptr: self.row_ptr.clone(),
            row_idx: self.row_idx.clone(),
            values,
        }
    }
}
