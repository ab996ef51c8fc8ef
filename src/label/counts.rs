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

    /// Counts `ids` (each must be below `n`: a larger one panics).
    ///
    /// Four tables, taken in turn: a run of one class (a scan's points and a map's cells come
    /// in such runs) then adds to four counters in turn, not to one counter whose every
    /// increment waits for the last one's store (a third of a SemanticKITTI frame's
    /// conversion went to two counts, one value at a time).
    pub fn count<I: IntoIterator<Item = ClassId>>(n: usize, ids: I) -> ClassCounts {
        ClassCounts::tally(n, ids.into_iter().map(|id| (id, 1)))
    }

    /// Counts the ids of `ids` whose `keep` is not 0 (the labels of a map's valid cells), in
    /// one pass without a branch a value (an empty cell adds 0: a filter's branch was
    /// mispredicted at every one).
    pub fn count_kept(n: usize, ids: &[ClassId], keep: &[u8]) -> ClassCounts {
        assert_eq!(ids.len(), keep.len(), "one keep flag an id");
        let kept = ids
            .iter()
            .zip(keep)
            .map(|(&id, &k)| (id, u64::from(k != 0)));
        ClassCounts::tally(n, kept)
    }

    /// The sum of the weights of each id ([`ClassCounts::count`]'s four tables).
    fn tally(n: usize, ids: impl Iterator<Item = (ClassId, u64)>) -> ClassCounts {
        const IDS: usize = ClassId::MAX as usize + 1;
        let mut tables = [[0u64; IDS]; 4];
        let mut ids = ids.into_iter();
        'all: loop {
            for table in &mut tables {
                let Some((id, w)) = ids.next() else {
                    break 'all;
                };
                table[id as usize] += w;
            }
        }
        let total = |id: usize| tables.iter().map(|t| t[id]).sum::<u64>();
        if let Some(id) = (n..IDS).find(|&id| total(id) > 0) {
            panic!("class id {id} counted among {n} classes");
        }
        ClassCounts(
            (0..n)
                .map(|id| if id < IDS { total(id) } else { 0 })
                .collect(),
        )
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The counts of the four tables together equal one count a value, for runs of one class,
    /// mixed ids, every length modulo four, and more classes than ids.
    #[test]
    fn four_tables_count_as_one() {
        let mut ids: Vec<ClassId> = Vec::new();
        for run in 0..300u32 {
            let id = (run * 37 % 19) as ClassId;
            ids.extend(std::iter::repeat_n(id, (run % 11) as usize));
        }
        for len in [0, 1, 2, 3, 4, 5, 7, 1000, ids.len()] {
            let mut one = vec![0u64; 300];
            for &id in &ids[..len] {
                one[id as usize] += 1;
            }
            let got = ClassCounts::count(300, ids[..len].iter().copied());
            assert_eq!(got.0, one, "{len} ids");
            assert_eq!(got.total(), len as u64);
        }
    }

    /// Only the kept ids count, an id beyond the classes too where it is not kept.
    #[test]
    fn only_kept_ids_count() {
        let ids = [1, 1, 2, 9, 0, 1, 1];
        let keep = [1, 0, 1, 0, 255, 1, 1];
        assert_eq!(ClassCounts::count_kept(3, &ids, &keep).0, [1, 3, 1]);
    }

    #[test]
    #[should_panic(expected = "class id 4 counted among 4 classes")]
    fn an_id_beyond_the_classes_panics() {
        ClassCounts::count(4, [0, 1, 4, 2]);
    }
}
