//! Per-class counts ([`ClassCounts`]), summed over frames.

use std::ops::AddAssign;

use serde::{Deserialize, Serialize};

use super::ClassId;

/// A count per class id, `counts[id]`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct ClassCounts(pub Vec<u64>);

impl ClassCounts {
    /// Zero for each of `n` classes.
    pub fn zeros(n: usize) -> ClassCounts {
        ClassCounts(vec![0; n])
    }

    /// Counts `ids` (each must be below the length).
    pub fn count<I: IntoIterator<Item = ClassId>>(n: usize, ids: I) -> ClassCounts {
        let mut c = ClassCounts::zeros(n);
        for id in ids {
            c.0[id as usize] += 1;
        }
        c
    }

    /// The count of class `id` (0 beyond the length).
    pub fn get(&self, id: ClassId) -> u64 {
        self.0.get(id as usize).copied().unwrap_or(0)
    }

    /// All counts added.
    pub fn total(&self) -> u64 {
        self.0.iter().sum()
    }
}

impl AddAssign<&ClassCounts> for ClassCounts {
    fn add_assign(&mut self, o: &ClassCounts) {
        if self.0.len() < o.0.len() {
            self.0.resize(o.0.len(), 0);
        }
        for (a, b) in self.0.iter_mut().zip(&o.0) {
            *a += b;
        }
    }
}
