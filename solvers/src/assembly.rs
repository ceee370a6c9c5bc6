//! Assembly of H from a buffer that the edges linearise into in parallel
//! (see [`cairn_core::layout`]): every entry of H sums its sources in edge
//! order, the same order in which one thread adds the edges' blocks straight
//! into H ([`HessianStructure::linearize_into`]), so the bits do not depend
//! on the number of threads. Built on first use: one thread never needs it.

use crate::structure::{HessianStructure, group_by_key};
use cairn_core::Graph;
use cairn_core::layout;

/// Entries of H summed per parallel work item, at least.
const CHUNK_VALUES: usize = 4096;

/// One edge's contribution to a block of H: where its block starts in the
/// linearisation buffer, and whether it lands transposed (its first vertex's
/// columns come after its second's).
#[derive(Clone, Copy, Debug, Default)]
struct BlockSource {
    offset: u32,
    transposed: bool,
}

/// For every block of H and every gradient segment, the edges' blocks in
/// the buffer that sum into it.
#[derive(Debug)]
pub struct Assembly {
    /// Start of each factor group's region in the linearisation buffer.
    pub group_offset: Vec<usize>,
    /// Length of the linearisation buffer.
    pub buffer_len: usize,
    /// The edges' blocks summed into each block of H, in edge order.
    hessian_start: Vec<u32>,
    hessian_sources: Vec<BlockSource>,
    /// The edges' gradient segments summed into each vertex's, in edge order.
    gradient_start: Vec<u32>,
    gradient_sources: Vec<u32>,
    /// First block column of each parallel work item, and the end.
    pub(crate) chunks: Vec<usize>,
    chi2_slots: Vec<u32>,
}

impl Assembly {
    /// The sources of every entry of `structure`'s H, for `graph` (the graph
    /// the structure was built for; its buffer fits u32 offsets).
    pub fn new(structure: &HessianStructure, graph: &Graph) -> Self {
        let s = structure;
        let layout = &s.layout;
        let (block_col_ptr, block_row_idx) = (layout.blocks().col_ptr(), layout.blocks().row_idx());
        let block_index = |r: u32, c: u32| -> usize {
            let range = block_col_ptr[c as usize]..block_col_ptr[c as usize + 1];
            let r = r as usize;
            range.start + block_row_idx[range].binary_search(&r).unwrap_or(0)
        };
        let mut group_offset = Vec::new();
        let mut buffer_len = 0usize;
        let mut h_sources: Vec<(u32, BlockSource)> = Vec::new();
        let mut g_sources: Vec<(u32, u32)> = Vec::new();
        let mut chi2_slots = Vec::new();
        for g in graph.factor_groups() {
            group_offset.push(buffer_len);
            let dims = g.vertex_dims();
            let stride = layout::stride(dims);
            for i in 0..g.len() {
                let slot = buffer_len + i * stride;
                let vs = g.vertices(i);
                for p in 0..vs.len() {
                    let bp = s.block_of[vs[p]];
                    if bp == u32::MAX {
                        continue;
                    }
                    for (q, &vq) in vs.iter().enumerate().skip(p) {
                        let bq = s.block_of[vq];
                        if bq == u32::MAX {
                            continue;
                        }
                        let source = BlockSource {
                            offset: (slot + layout::block_offset(dims, p, q)) as u32,
                            transposed: bp > bq,
                        };
                        h_sources.push((block_index(bp.min(bq), bp.max(bq)) as u32, source));
                    }
                    g_sources.push((bp, (slot + layout::gradient_offset(dims, p)) as u32));
                }
                chi2_slots.push((slot + stride - 1) as u32);
            }
            buffer_len += g.len() * stride;
        }
        let as_u32 = |v: Vec<usize>| v.into_iter().map(|x| x as u32).collect::<Vec<u32>>();
        let (h_start, h_sources) = group_by_key(block_row_idx.len(), &h_sources);
        let blocks = layout.dims().len();
        let (g_start, g_sources) = group_by_key(blocks, &g_sources);

        // Work items of at least CHUNK_VALUES entries, whole block columns.
        let (col_ptr, block_column) = (layout.col_ptr(), layout.block_column());
        let mut chunks = vec![0];
        for c in 0..blocks {
            let chunk_begin = col_ptr[block_column[*chunks.last().unwrap_or(&0)]];
            if col_ptr[block_column[c + 1]] - chunk_begin >= CHUNK_VALUES {
                chunks.push(c + 1);
            }
        }
        if chunks.last() != Some(&blocks) {
            chunks.push(blocks);
        }
        Self {
            group_offset,
            buffer_len,
            hessian_start: as_u32(h_start),
            hessian_sources: h_sources,
            gradient_start: as_u32(g_start),
            gradient_sources: g_sources,
            chunks,
            chi2_slots,
        }
    }

    /// Sums the edges' blocks into the values of H and their gradient
    /// segments into the gradient. Block columns are split among threads;
    /// each entry adds its sources in edge order, whatever the thread count.
    pub fn assemble(
        &self,
        structure: &HessianStructure,
        buffer: &[f64],
        values: &mut [f64],
        gradient: &mut [f64],
    ) {
        self.assemble_chunks(structure, &self.chunks, buffer, values, gradient);
    }

    /// Assembles the block columns `chunks[0]..chunks[last]`, whose values
    /// and gradient entries are `values` and `gradient`.
    fn assemble_chunks(
        &self,
        s: &HessianStructure,
        chunks: &[usize],
        buffer: &[f64],
        values: &mut [f64],
        gradient: &mut [f64],
    ) {
        if chunks.len() > 2 {
            let mid = chunks.len() / 2;
            let (col_ptr, block_column) = (s.layout.col_ptr(), s.layout.block_column());
            let (first, split) = (block_column[chunks[0]], block_column[chunks[mid]]);
            let (v1, v2) = values.split_at_mut(col_ptr[split] - col_ptr[first]);
            let (g1, g2) = gradient.split_at_mut(split - first);
            rayon::join(
                || self.assemble_chunks(s, &chunks[..=mid], buffer, v1, g1),
                || self.assemble_chunks(s, &chunks[mid..], buffer, v2, g2),
            );
        } else if let [begin, end] = *chunks {
            self.assemble_columns(s, begin..end, buffer, values, gradient);
        }
    }

    /// Assembles the block columns `range` (see [`Self::assemble_chunks`]).
    fn assemble_columns(
        &self,
        s: &HessianStructure,
        range: std::ops::Range<usize>,
        buffer: &[f64],
        values: &mut [f64],
        gradient: &mut [f64],
    ) {
        let layout = &s.layout;
        let (col_ptr, block_column, dims) =
            (layout.col_ptr(), layout.block_column(), layout.dims());
        let (block_col_ptr, block_row_idx) = (layout.blocks().col_ptr(), layout.blocks().row_idx());
        let first = block_column[range.start];
        let base = col_ptr[first];
        // Entry by entry, each summing its sources in a register: the
        // sources' blocks are read from memory once and then from cache.
        for c in range {
            let (cc, dc) = (block_column[c], dims[c]);
            let blocks = block_col_ptr[c]..block_col_ptr[c + 1];
            for (k, &r) in blocks.clone().zip(&block_row_idx[blocks]) {
                let dr = dims[r];
                let sources = &self.hessian_sources
                    [self.hessian_start[k] as usize..self.hessian_start[k + 1] as usize];
                for j in 0..dc {
                    let height = if r == c { j + 1 } else { dr };
                    let at = col_ptr[cc + j] - base + layout.row_offset()[k] as usize;
                    for (i, v) in values[at..at + height].iter_mut().enumerate() {
                        // A transposed block is stored dc × dr: entry (i, j) is its (j, i).
                        let (straight, transposed) = (i + j * dr, j + i * dc);
                        *v = sources
                            .iter()
                            .map(|s| {
                                let within = if s.transposed { transposed } else { straight };
                                buffer[s.offset as usize + within]
                            })
                            .sum();
                    }
                }
            }
            let sources = &self.gradient_sources
                [self.gradient_start[c] as usize..self.gradient_start[c + 1] as usize];
            for (i, g) in gradient[cc - first..cc - first + dc].iter_mut().enumerate() {
                *g = sources.iter().map(|&o| buffer[o as usize + i]).sum();
            }
        }
    }

    /// Total χ² stored in the buffer by the last linearisation (deterministic order).
    pub fn chi2(&self, buffer: &[f64]) -> f64 {
        cairn_core::factor::deterministic_sum(self.chi2_slots.len(), |k| {
            buffer[self.chi2_slots[k] as usize]
        })
    }
}
