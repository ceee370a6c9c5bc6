//! EKF-SLAM's joint state storage: slots of landmarks in the mean and the
//! covariance, added, removed and kept symmetric.

use super::{EkfSlam, ROBOT};
use nalgebra::DMatrix;

impl EkfSlam {
    /// Two zeroed state entries for landmark `l`, growing the storage by
    /// doubling. Returns the slot.
    pub(super) fn push_slot(&mut self, l: usize) -> usize {
        let slot = self.dim;
        if slot + 2 > self.x.len() {
            let capacity = 2 * self.x.len();
            let mut p = DMatrix::zeros(capacity, capacity);
            p.view_mut((0, 0), (slot, slot))
                .copy_from(&self.p.view((0, 0), (slot, slot)));
            self.p = p;
            self.x.resize_vertically_mut(capacity, 0.0);
            self.pht = DMatrix::zeros(capacity, 2);
            self.gain = DMatrix::zeros(capacity, 2);
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

    /// Keeps P symmetric against round-off from the one-sided downdates.
    pub(super) fn symmetrise(&mut self) {
        let n = self.dim;
        for i in 0..n {
            for j in 0..i {
                let v = 0.5 * (self.p[(i, j)] + self.p[(j, i)]);
                self.p[(i, j)] = v;
                self.p[(j, i)] = v;
            }
        }
    }
}
