//! EKF-SLAM's joint state storage: slots of landmarks in the mean and the
//! covariance, added and removed, and the covariance's pending downdates.

use super::{EkfSlam, ROBOT};
use faer::linalg::matmul::matmul;
use faer::{Accum, MatMut, MatRef, Par};
use nalgebra::DMatrix;

/// Columns of downdates held before they are applied to the covariance.
/// Each landmark update downdates P by rank 2, and applied alone it streams
/// all of P through memory; a scan's updates (up to 32) applied as one
/// matrix product stream it once.
pub(super) const PENDING: usize = 64;

impl EkfSlam {
    /// Two zeroed state entries for landmark `l`, growing the storage by
    /// doubling. Returns the slot.
    pub(super) fn push_slot(&mut self, l: usize) -> usize {
        self.flush();
        let slot = self.dim;
        if slot + 2 > self.x.len() {
            let capacity = 2 * self.x.len();
            let mut p = DMatrix::zeros(capacity, capacity);
            p.view_mut((0, 0), (slot, slot))
                .copy_from(&self.p.view((0, 0), (slot, slot)));
            self.p = p;
            self.x.resize_vertically_mut(capacity, 0.0);
            self.pht = DMatrix::zeros(capacity, 2);
            self.pending = DMatrix::zeros(capacity, PENDING);
        }
        self.x.fixed_rows_mut::<2>(slot).fill(0.0);
        self.p.view_mut((slot, 0), (2, slot + 2)).fill(0.0);
        self.p.view_mut((0, slot), (slot + 2, 2)).fill(0.0);
        self.owners.push(l);
        self.dim += 2;
        slot
    }

    /// Drops landmark `l` from the state: the last slot moves into its place.
    pub(super) fn remove(&mut self, l: usize) {
        let Some(slot) = self.landmarks[l].slot.take() else {
            return;
        };
        self.flush();
        let last = self.dim - 2;
        if slot != last {
            for k in 0..2 {
                self.x.swap_rows(slot + k, last + k);
                self.p.swap_rows(slot + k, last + k);
                self.p.swap_columns(slot + k, last + k);
            }
            let moved = self.owners[(last - ROBOT) / 2];
            self.owners[(slot - ROBOT) / 2] = moved;
            self.landmarks[moved].slot = Some(slot);
        }
        self.owners.pop();
        self.dim -= 2;
    }

    /// Applies the pending downdates, P ← P − U Uᵀ, as one matrix product.
    /// Entries (i, j) and (j, i) sum the same products in the same order,
    /// so P stays exactly symmetric.
    pub(super) fn flush(&mut self) {
        if self.rank == 0 {
            return;
        }
        let (n, capacity) = (self.dim, self.x.len());
        let u = MatRef::from_column_major_slice_with_stride(
            self.pending.as_slice(),
            n,
            self.rank,
            capacity,
        );
        let p =
            MatMut::from_column_major_slice_with_stride_mut(self.p.as_mut_slice(), n, n, capacity);
        matmul(p, Accum::Add, u, u.transpose(), -1.0, Par::Seq);
        self.rank = 0;
    }
}
