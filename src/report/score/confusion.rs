//! SCORE: the confusion matrix and the figures computed from it.

use serde::Serialize;

use crate::label::classes::AbsentInMiou;
use crate::label::{ClassId, ClassMap};

/// A confusion matrix over `k` classes, `m[ground truth][prediction]`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct Confusion {
    /// Counts, ground truth by row, prediction by column.
    pub m: Vec<Vec<u64>>,
}

impl Confusion {
    /// An empty matrix over `k` classes.
    pub fn new(k: usize) -> Confusion {
        Confusion {
            m: vec![vec![0; k]; k],
        }
    }

    /// Number of classes.
    pub fn k(&self) -> usize {
        self.m.len()
    }

    /// Counts one element.
    #[inline]
    pub fn count(&mut self, truth: ClassId, pred: ClassId) {
        self.m[truth as usize][pred as usize] += 1;
    }

    /// Adds another matrix of the same size.
    pub fn add(&mut self, o: &Confusion) {
        for (a, b) in self.m.iter_mut().zip(&o.m) {
            for (x, y) in a.iter_mut().zip(b) {
                *x += y;
            }
        }
    }

    /// True positives of class `c`.
    pub fn tp(&self, c: usize) -> u64 {
        self.m[c][c]
    }

    /// False positives of class `c` (predicted c, truth other).
    pub fn fp(&self, c: usize) -> u64 {
        (0..self.k())
            .filter(|&g| g != c)
            .map(|g| self.m[g][c])
            .sum()
    }

    /// False negatives of class `c` (truth c, predicted other).
    pub fn fn_(&self, c: usize) -> u64 {
        (0..self.k())
            .filter(|&p| p != c)
            .map(|p| self.m[c][p])
            .sum()
    }

    /// Overall accuracy: the diagonal over every counted element (`None` when none was counted).
    pub fn accuracy(&self) -> Option<f64> {
        let total = self.total();
        (total > 0).then(|| (0..self.k()).map(|c| self.tp(c)).sum::<u64>() as f64 / total as f64)
    }

    /// IoU of class `c`: TP / (TP + FP + FN); `None` when the class is absent from truth and
    /// prediction.
    pub fn iou(&self, c: usize) -> Option<f64> {
        let d = self.tp(c) + self.fp(c) + self.fn_(c);
        (d > 0).then(|| self.tp(c) as f64 / d as f64)
    }

    /// `TP / (TP + FP)`, or `None` when nothing was predicted as the class.
    pub fn precision(&self, c: usize) -> Option<f64> {
        let d = self.tp(c) + self.fp(c);
        (d > 0).then(|| self.tp(c) as f64 / d as f64)
    }

    /// `TP / (TP + FN)`, or `None` when the class is absent from the truth.
    pub fn recall(&self, c: usize) -> Option<f64> {
        let d = self.tp(c) + self.fn_(c);
        (d > 0).then(|| self.tp(c) as f64 / d as f64)
    }

    /// Mean IoU over the classes `over` (the class map's `miou` list: car, pedestrian and
    /// cyclist for the paper's map). A class absent from both truth and prediction has no IoU and
    /// is left out of the mean (so a perfect prediction scores 1 on a set without cyclists); 0
    /// when none is present. On SqueezeSeg's val set every class is present and this is its
    /// plain three-class mean.
    pub fn miou(&self, over: &[ClassId]) -> f64 {
        self.miou_present(over).unwrap_or(0.0)
    }

    /// The mean IoU of a class map's `miou` classes, with its rule for absent classes: left out
    /// ([`Confusion::miou`]) or counted as 0 (SemanticKITTI's benchmark).
    pub fn miou_for(&self, map: &ClassMap) -> f64 {
        match map.absent_in_miou {
            AbsentInMiou::LeftOut => self.miou(&map.miou),
            AbsentInMiou::Zero => {
                let v: Vec<f64> = map
                    .miou
                    .iter()
                    .map(|&c| self.iou(c as usize).unwrap_or(0.0))
                    .collect();
                if v.is_empty() {
                    0.0
                } else {
                    v.iter().sum::<f64>() / v.len() as f64
                }
            }
        }
    }

    /// Mean IoU over the classes of `over` present in truth or prediction, `None` if none is.
    pub fn miou_present(&self, over: &[ClassId]) -> Option<f64> {
        let v: Vec<f64> = over.iter().filter_map(|&c| self.iou(c as usize)).collect();
        (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
    }

    /// Counted elements.
    pub fn total(&self) -> u64 {
        self.m.iter().flatten().sum()
    }
}
