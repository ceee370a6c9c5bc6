//! Disjoint sets (union-find) over `0..n`: a graph's connected components,
//! clusters of points or of landmarks.

/// A partition of `0..n` into sets, merged by [`DisjointSets::union`].
/// Each set's root is its least member, so the result does not depend on
/// the order of the unions.
#[derive(Clone, Debug)]
pub struct DisjointSets {
    parent: Vec<usize>,
}

impl DisjointSets {
    /// `n` sets of one element each.
    pub fn new(n: usize) -> Self {
        Self {
            parent: (0..n).collect(),
        }
    }

    /// The least member of `i`'s set.
    pub fn find(&mut self, mut i: usize) -> usize {
        while self.parent[i] != i {
            // Path halving: every other node on the way points past its parent.
            self.parent[i] = self.parent[self.parent[i]];
            i = self.parent[i];
        }
        i
    }

    /// Merges the sets of `a` and `b`.
    pub fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        self.parent[ra.max(rb)] = ra.min(rb);
    }

    /// The sets, each in ascending order, in the order of their least members.
    pub fn groups(&mut self) -> Vec<Vec<usize>> {
        let mut index = vec![usize::MAX; self.parent.len()];
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for i in 0..self.parent.len() {
            let r = self.find(i);
            if index[r] == usize::MAX {
                index[r] = groups.len();
                groups.push(Vec::new());
            }
            groups[index[r]].push(i);
        }
        groups
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unions_in_any_order_give_the_same_sets_rooted_at_their_least_member() {
        let pairs = [(4, 2), (7, 4), (0, 5), (5, 3), (8, 8)];
        let mut forward = DisjointSets::new(9);
        let mut backward = DisjointSets::new(9);
        for &(a, b) in &pairs {
            forward.union(a, b);
        }
        for &(a, b) in pairs.iter().rev() {
            backward.union(b, a);
        }
        let expected = vec![vec![0, 3, 5], vec![1], vec![2, 4, 7], vec![6], vec![8]];
        assert_eq!(forward.groups(), expected);
        assert_eq!(backward.groups(), expected);
        assert_eq!(forward.find(7), 2);
        assert_eq!(DisjointSets::new(0).groups(), Vec::<Vec<usize>>::new());
    }
}
