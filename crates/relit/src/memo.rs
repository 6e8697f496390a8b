//! Bounded memories of pure functions' values.
//!
//! The basis choice builds every size of a data-driven family on each validation
//! fold's lights, in each space, and several of a build's steps depend on the fold
//! alone (the RBF kernels' gradient Gram matrix, the samples' principal directions), so
//! the same values were computed again for every size; the analytic candidates'
//! penalties are the same in every fold. A [`Memo`] keeps the last few values with
//! their arguments, compared exactly, so a remembered value is the one that would be
//! computed: results do not depend on what was asked before.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

/// The last values of a function, with their arguments `K`, up to a byte budget
/// (the oldest forgotten first). A value of more than a quarter of the budget is
/// returned and not kept: a memory is for the small values asked for again and again
/// (a fit's final basis, built once from its whole pixel subsample, would only raise
/// the fit's peak memory).
pub(crate) struct Memo<K, V> {
    kept: Mutex<VecDeque<(K, Arc<V>, usize)>>,
    budget: usize,
}

impl<K, V> Memo<K, V> {
    /// A memory of at most `budget` bytes (as the callers count them).
    pub(crate) const fn new(budget: usize) -> Self {
        Self {
            kept: Mutex::new(VecDeque::new()),
            budget,
        }
    }

    /// The value remembered for the arguments that `same` recognises, or else
    /// `compute()`'s, then remembered with the arguments `key()` and `bytes` of memory.
    /// Computed outside the lock, so that other threads are not held up; two threads
    /// computing the same value at once keep one of the (equal) results.
    pub(crate) fn get_or(
        &self,
        same: impl Fn(&K) -> bool,
        key: impl FnOnce() -> K,
        compute: impl FnOnce() -> V,
        bytes: impl FnOnce(&V) -> usize,
    ) -> Arc<V> {
        let find = |list: &VecDeque<(K, Arc<V>, usize)>| {
            list.iter().find(|e| same(&e.0)).map(|e| e.1.clone())
        };
        if let Some(v) = find(&self.lock()) {
            return v;
        }
        let value = Arc::new(compute());
        let size = bytes(&value);
        if size > self.budget / 4 {
            return value;
        }
        let mut list = self.lock();
        if let Some(v) = find(&list) {
            return v;
        }
        list.push_back((key(), value.clone(), size));
        while list.iter().map(|e| e.2).sum::<usize>() > self.budget {
            list.pop_front();
        }
        value
    }

    /// Forget every value.
    pub(crate) fn clear(&self) {
        self.lock().clear();
    }

    /// How many values are remembered.
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.lock().len()
    }

    /// A poisoned lock only means another thread panicked while holding it; the list is
    /// whole between any two of its statements.
    fn lock(&self) -> std::sync::MutexGuard<'_, VecDeque<(K, Arc<V>, usize)>> {
        self.kept.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// Whether two slices of floats hold the same bits (`==` would call `-0.0` and `0.0`
/// the same and `NaN` different from itself).
pub(crate) fn same_bits_f32(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn remembers_within_its_budget_and_forgets_the_oldest_first() {
        let memo: Memo<u32, Vec<u8>> = Memo::new(32);
        let calls = std::cell::Cell::new(0);
        let get = |k: u32| {
            memo.get_or(
                |&x| x == k,
                || k,
                || {
                    calls.set(calls.get() + 1);
                    vec![k as u8; 8]
                },
                |v| v.len(),
            )
        };
        assert_eq!(*get(1), vec![1; 8]);
        assert_eq!(*get(2), vec![2; 8]);
        assert_eq!(*get(1), vec![1; 8]);
        assert_eq!(calls.get(), 2, "1 was remembered");
        assert_eq!(*get(3), vec![3; 8]);
        assert_eq!(*get(4), vec![4; 8]);
        assert_eq!(memo.len(), 4);
        assert_eq!(*get(5), vec![5; 8]); // 40 bytes: 1 is forgotten
        assert_eq!(memo.len(), 4);
        assert_eq!(*get(2), vec![2; 8]);
        assert_eq!(calls.get(), 5);
        assert_eq!(*get(1), vec![1; 8]);
        assert_eq!(calls.get(), 6, "1 was forgotten");
        // A value of more than a quarter of the budget is returned and not kept.
        let big = memo.get_or(|&x| x == 9, || 9, || vec![9; 9], |v| v.len());
        assert_eq!(*big, vec![9; 9]);
        assert_eq!(memo.len(), 4);
        assert!(memo.get_or(|&x| x == 9, || 9, || vec![7; 9], |v| v.len())[0] == 7);
    }

    #[test]
    fn compares_floats_by_their_bits() {
        assert!(same_bits_f32(&[1.0, 0.0], &[1.0, 0.0]));
        assert!(!same_bits_f32(&[0.0], &[-0.0]));
        assert!(same_bits_f32(&[f32::NAN], &[f32::NAN]));
        assert!(!same_bits_f32(&[1.0], &[1.0, 1.0]));
    }
}
