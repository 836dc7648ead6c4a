//! Per-particle landmark maps implementing quarry-core's [`LandmarkStore`].
//!
//! [`PersistentStore`] is FastSLAM's log-time map (Montemerlo et al. 2002; spec 000 §2.11, A9):
//! a persistent radix tree of `Arc`-shared nodes with branching factor
//! [`PersistentStore::BRANCHING`] = 16. Cloning a store (what resampling does when it copies a
//! particle) is O(1): one reference-count increment. Writing a landmark copies only the nodes on
//! its root-to-leaf path that are shared with another store (path copying via
//! `Arc::make_mut`): at most `⌈log₁₆ M⌉ + 1` nodes. Reads are O(log₁₆ M).
//!
//! [`VecStore`] is the flat alternative (copying a particle is O(M)); faster for small maps.
//! Both behave exactly like a `Vec` indexed by dense [`LandmarkId`]s `0..len`.
//!
//! ```
//! use quarry_core::{LandmarkId, LandmarkStore};
//! use quarry_filter::store::PersistentStore;
//! let mut a = PersistentStore::new();
//! for i in 0..1000 {
//!     a.push(i as f64);
//! }
//! let mut b = a.clone();                        // O(1), shares every node
//! b.set(LandmarkId(7), -1.0)?;                  // copies one path (3 nodes here)
//! assert_eq!(a.get(LandmarkId(7)), Some(&7.0)); // the original is unchanged
//! assert_eq!(b.get(LandmarkId(7)), Some(&-1.0));
//! assert_eq!(b.unshared_nodes(&a), 3);
//! # Ok::<(), quarry_core::CoreError>(())
//! ```

use quarry_core::{CoreError, LandmarkId, LandmarkStore};
use std::sync::Arc;

const BITS: u32 = 4;
const B: usize = 1 << BITS;
const MASK: usize = B - 1;

#[derive(Debug, Clone)]
enum Node<T> {
    Leaf(Vec<T>),
    Branch(Vec<Arc<Node<T>>>),
}

/// A persistent, structure-sharing landmark map (see the [module docs](self)).
#[derive(Debug, Clone)]
pub struct PersistentStore<T> {
    root: Option<Arc<Node<T>>>,
    len: usize,
    /// `BITS` × (height of the tree); 0 when the root is a leaf.
    shift: u32,
}

impl<T> Default for PersistentStore<T> {
    fn default() -> Self {
        Self {
            root: None,
            len: 0,
            shift: 0,
        }
    }
}

fn out_of_range(id: usize, len: usize) -> CoreError {
    CoreError::invalid(
        "landmark id",
        format!("{id} is out of range (the store holds {len})"),
    )
}

impl<T: Clone> PersistentStore<T> {
    /// The branching factor of the tree.
    pub const BRANCHING: usize = B;

    /// An empty store.
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of landmarks.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The value at index `i`.
    pub fn get_index(&self, i: usize) -> Option<&T> {
        if i >= self.len {
            return None;
        }
        let mut node = self.root.as_deref()?;
        let mut s = self.shift;
        loop {
            match node {
                Node::Branch(ch) => {
                    node = ch.get((i >> s) & MASK)?;
                    s = s.saturating_sub(BITS);
                }
                Node::Leaf(v) => return v.get(i & MASK),
            }
        }
    }

    /// Replaces the value at index `i` (path copying).
    pub fn set_index(&mut self, i: usize, value: T) -> Result<(), CoreError> {
        if i >= self.len {
            return Err(out_of_range(i, self.len));
        }
        let Some(root) = self.root.as_mut() else {
            return Err(out_of_range(i, self.len));
        };
        let mut node = Arc::make_mut(root);
        let mut s = self.shift;
        loop {
            match node {
                Node::Branch(ch) => {
                    let c = ch
                        .get_mut((i >> s) & MASK)
                        .ok_or_else(|| out_of_range(i, self.len))?;
                    node = Arc::make_mut(c);
                    s = s.saturating_sub(BITS);
                }
                Node::Leaf(v) => {
                    let slot = v
                        .get_mut(i & MASK)
                        .ok_or_else(|| out_of_range(i, self.len))?;
                    *slot = value;
                    return Ok(());
                }
            }
        }
    }

    /// Appends a value; returns its index.
    pub fn push_value(&mut self, value: T) -> usize {
        let i = self.len;
        match self.root.take() {
            None => {
                let mut v = Vec::with_capacity(B);
                v.push(value);
                self.root = Some(Arc::new(Node::Leaf(v)));
                self.shift = 0;
            }
            Some(root) => {
                // Grow a level when the tree is full.
                let mut root = if i == 1usize << (self.shift + BITS) {
                    self.shift += BITS;
                    let mut ch = Vec::with_capacity(B);
                    ch.push(root);
                    Arc::new(Node::Branch(ch))
                } else {
                    root
                };
                let mut node = Arc::make_mut(&mut root);
                let mut s = self.shift;
                loop {
                    match node {
                        Node::Branch(ch) => {
                            let idx = (i >> s) & MASK;
                            if idx == ch.len() {
                                let fresh = if s == BITS {
                                    Node::Leaf(Vec::with_capacity(B))
                                } else {
                                    Node::Branch(Vec::with_capacity(B))
                                };
                                ch.push(Arc::new(fresh));
                            }
                            node = Arc::make_mut(&mut ch[idx]);
                            s = s.saturating_sub(BITS);
                        }
                        Node::Leaf(v) => {
                            v.push(value);
                            break;
                        }
                    }
                }
                self.root = Some(root);
            }
        }
        self.len += 1;
        i
    }

    /// Iterates over the values in index order.
    pub fn iter(&self) -> impl Iterator<Item = &T> + '_ {
        let mut stack: Vec<&Node<T>> = self.root.as_deref().into_iter().collect();
        let mut leaf: std::slice::Iter<'_, T> = [].iter();
        std::iter::from_fn(move || {
            loop {
                if let Some(v) = leaf.next() {
                    return Some(v);
                }
                match stack.pop()? {
                    Node::Leaf(v) => leaf = v.iter(),
                    Node::Branch(ch) => stack.extend(ch.iter().rev().map(|c| &**c)),
                }
            }
        })
    }

    /// The values as a `Vec`, in index order.
    pub fn to_vec(&self) -> Vec<T> {
        self.iter().cloned().collect()
    }

    /// Number of tree nodes.
    pub fn node_count(&self) -> usize {
        fn count<T>(n: &Node<T>) -> usize {
            match n {
                Node::Leaf(_) => 1,
                Node::Branch(ch) => 1 + ch.iter().map(|c| count(c)).sum::<usize>(),
            }
        }
        self.root.as_deref().map_or(0, count)
    }

    /// Number of this store's nodes that are not shared (pointer-equal, at the same position)
    /// with `other`: 0 right after a clone; at most `⌈log₁₆ M⌉ + 1` after writing one landmark.
    pub fn unshared_nodes(&self, other: &Self) -> usize {
        fn walk<T>(a: &Arc<Node<T>>, b: Option<&Arc<Node<T>>>) -> usize {
            if b.is_some_and(|b| Arc::ptr_eq(a, b)) {
                return 0;
            }
            match &**a {
                Node::Leaf(_) => 1,
                Node::Branch(ch) => {
                    let other: Option<&Vec<Arc<Node<T>>>> = match b.map(|b| &**b) {
                        Some(Node::Branch(o)) => Some(o),
                        _ => None,
                    };
                    1 + ch
                        .iter()
                        .enumerate()
                        .map(|(k, c)| walk(c, other.and_then(|o| o.get(k))))
                        .sum::<usize>()
                }
            }
        }
        match &self.root {
            None => 0,
            Some(r) => {
                // Compare at equal heights only.
                let o = if self.shift == other.shift {
                    other.root.as_ref()
                } else {
                    None
                };
                walk(r, o)
            }
        }
    }
}

impl<T: Clone> FromIterator<T> for PersistentStore<T> {
    fn from_iter<I: IntoIterator<Item = T>>(iter: I) -> Self {
        let mut s = Self::new();
        for v in iter {
            s.push_value(v);
        }
        s
    }
}

impl<T: Clone + PartialEq> PartialEq for PersistentStore<T> {
    fn eq(&self, other: &Self) -> bool {
        self.len == other.len && self.iter().eq(other.iter())
    }
}

fn to_id(i: usize) -> LandmarkId {
    // More than 2³² landmarks cannot be addressed by a LandmarkId; saturate (never reached in
    // practice: that is hundreds of gigabytes of Gaussians).
    LandmarkId(u32::try_from(i).unwrap_or(u32::MAX))
}

impl<T: Clone> LandmarkStore<T> for PersistentStore<T> {
    fn get(&self, id: LandmarkId) -> Option<&T> {
        self.get_index(id.0 as usize)
    }
    fn set(&mut self, id: LandmarkId, value: T) -> Result<(), CoreError> {
        self.set_index(id.0 as usize, value)
    }
    fn push(&mut self, value: T) -> LandmarkId {
        to_id(self.push_value(value))
    }
    fn len(&self) -> usize {
        self.len
    }
}

/// A flat landmark map: a `Vec`. Cloning copies every landmark (O(M)).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct VecStore<T> {
    /// The landmarks, indexed by `LandmarkId`.
    pub items: Vec<T>,
}

impl<T> VecStore<T> {
    /// An empty store.
    pub fn new() -> Self {
        Self { items: Vec::new() }
    }
}

impl<T> FromIterator<T> for VecStore<T> {
    fn from_iter<I: IntoIterator<Item = T>>(iter: I) -> Self {
        Self {
            items: iter.into_iter().collect(),
        }
    }
}

impl<T: Clone> LandmarkStore<T> for VecStore<T> {
    fn get(&self, id: LandmarkId) -> Option<&T> {
        self.items.get(id.0 as usize)
    }
    fn set(&mut self, id: LandmarkId, value: T) -> Result<(), CoreError> {
        let len = self.items.len();
        let slot = self
            .items
            .get_mut(id.0 as usize)
            .ok_or_else(|| out_of_range(id.0 as usize, len))?;
        *slot = value;
        Ok(())
    }
    fn push(&mut self, value: T) -> LandmarkId {
        self.items.push(value);
        to_id(self.items.len() - 1)
    }
    fn len(&self) -> usize {
        self.items.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[derive(Debug, Clone)]
    enum Op {
        Push(i64),
        Set(usize, i64),
        /// Clone store `k` (mod count) into a new slot.
        Clone(usize),
        /// Switch the store subsequent operations act on.
        Select(usize),
    }

    fn op() -> impl Strategy<Value = Op> {
        prop_oneof![
            4 => any::<i64>().prop_map(Op::Push),
            4 => (any::<usize>(), any::<i64>()).prop_map(|(i, v)| Op::Set(i, v)),
            1 => any::<usize>().prop_map(Op::Clone),
            1 => any::<usize>().prop_map(Op::Select),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// Spec 000 §6.1 test 18: after any random sequence of pushes, updates and clones every
        /// persistent store reads back exactly like its `Vec` twin.
        #[test]
        fn persistent_equals_vec(ops in proptest::collection::vec(op(), 0..600), prefill in 0usize..300) {
            let mut ps: Vec<PersistentStore<i64>> = vec![(0..prefill as i64).collect()];
            let mut vs: Vec<VecStore<i64>> = vec![(0..prefill as i64).collect()];
            let mut cur = 0;
            for o in ops {
                match o {
                    Op::Push(v) => {
                        let a = ps[cur].push(v);
                        let b = vs[cur].push(v);
                        prop_assert_eq!(a, b);
                    }
                    Op::Set(i, v) => {
                        let len = vs[cur].len();
                        let id = LandmarkId((if len > 0 && i % 8 != 0 { i % len } else { i % (len + 3) }) as u32);
                        let a = ps[cur].set(id, v);
                        let b = vs[cur].set(id, v);
                        prop_assert_eq!(a.is_ok(), b.is_ok());
                    }
                    Op::Clone(k) => {
                        let k = k % ps.len();
                        let p = ps[k].clone();
                        prop_assert_eq!(p.unshared_nodes(&ps[k]), 0);
                        ps.push(p);
                        vs.push(vs[k].clone());
                    }
                    Op::Select(k) => cur = k % ps.len(),
                }
            }
            for (p, v) in ps.iter().zip(&vs) {
                prop_assert_eq!(p.len(), v.len());
                prop_assert_eq!(p.to_vec(), v.items.clone());
                for i in 0..v.len() + 2 {
                    prop_assert_eq!(p.get(LandmarkId(i as u32)), v.get(LandmarkId(i as u32)));
                }
            }
        }
    }

    #[test]
    fn path_copying_bounds() {
        for m in [1usize, 15, 16, 17, 255, 256, 257, 5000, 70_000] {
            let a: PersistentStore<u64> = (0..m as u64).collect();
            let height = (m as f64).log(16.0).ceil() as usize;
            for id in [0, m / 2, m - 1] {
                let mut b = a.clone();
                assert_eq!(b.unshared_nodes(&a), 0);
                b.set(LandmarkId(id as u32), 999).unwrap();
                let copied = b.unshared_nodes(&a);
                assert!(
                    copied <= height.max(1) + 1,
                    "m {m}: copied {copied} > {}",
                    height + 1
                );
                assert_eq!(a.get(LandmarkId(id as u32)), Some(&(id as u64)));
                assert_eq!(b.get(LandmarkId(id as u32)), Some(&999));
                // writing it again copies nothing more
                b.set(LandmarkId(id as u32), 1000).unwrap();
                assert_eq!(b.unshared_nodes(&a), copied);
            }
            assert!(a.clone().set(LandmarkId(m as u32), 0).is_err());
        }
    }
}
