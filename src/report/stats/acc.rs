//! STATS: the sums of one frame, added up in frame order.

use crate::error::{Error, Result};
use crate::format::label_file;
use crate::format::layout::OutputDir;
use crate::label::{ClassCounts, ClassMap};
use crate::report::truth::MapFrame;

/// Sums of one frame or of many.
#[derive(Debug, Clone)]
pub(super) struct Acc {
    pub frames: u64,
    pub cells: ClassCounts,
    pub points: ClassCounts,
    pub points_known: bool,
    pub frames_with: ClassCounts,
    pub row_filled: Vec<u64>,
    pub rgb_cells: u64,
    pub sum: Vec<f64>,
    pub sum_sq: Vec<f64>,
}

impl Acc {
    pub fn new(rows: usize, classes: usize, inputs: usize) -> Acc {
        Acc {
            frames: 0,
            cells: ClassCounts::zeros(classes),
            points: ClassCounts::zeros(classes),
            points_known: true,
            frames_with: ClassCounts::zeros(classes),
            row_filled: vec![0; rows],
            rgb_cells: 0,
            sum: vec![0.0; inputs],
            sum_sq: vec![0.0; inputs],
        }
    }

    pub fn add(&mut self, o: &Acc) {
        self.frames += o.frames;
        self.cells += &o.cells;
        self.points += &o.points;
        self.frames_with += &o.frames_with;
        self.points_known &= o.points_known;
        for (a, b) in self.row_filled.iter_mut().zip(&o.row_filled) {
            *a += b;
        }
        self.rgb_cells += o.rgb_cells;
        for i in 0..self.sum.len() {
            self.sum[i] += o.sum[i];
            self.sum_sq[i] += o.sum_sq[i];
        }
    }

    /// The sums of one frame; its points from the `.label` file in `dir`, when there is one.
    pub fn of_frame(f: &MapFrame, map: &ClassMap, dir: Option<&OutputDir>) -> Result<Acc> {
        let m = &f.map;
        let depth = m.channels.len();
        let inputs: Vec<usize> = m
            .channels
            .inputs()
            .0
            .iter()
            .map(|c| m.channels.index(*c).expect("an input of the frame"))
            .collect();
        let mut acc = Acc::new(m.rows, map.len(), inputs.len());
        acc.frames = 1;
        for i in 0..m.cells() {
            if m.mask[i] == 0 {
                continue;
            }
            acc.cells.0[m.label[i] as usize] += 1;
            acc.row_filled[i / m.cols] += 1;
            let cell = &m.data[i * depth..(i + 1) * depth];
            for (j, &c) in inputs.iter().enumerate() {
                let v = cell[c] as f64;
                if !v.is_finite() {
                    return Err(Error::NotFinite {
                        path: f.source.clone(),
                        what: format!(
                            "frame {}, cell ({}, {}): channel {}",
                            f.id,
                            i / m.cols,
                            i % m.cols,
                            m.channels.0[c],
                        ),
                        value: v,
                    });
                }
                acc.sum[j] += v;
                acc.sum_sq[j] += v * v;
            }
            if m.rgb_valid.as_ref().is_some_and(|v| v[i] != 0) {
                acc.rgb_cells += 1;
            }
        }
        for (w, c) in acc.frames_with.0.iter_mut().zip(&acc.cells.0) {
            *w = (*c > 0) as u64;
        }
        match dir.map(|d| d.label_path(&f.id)).filter(|p| p.is_file()) {
            Some(lp) => {
                let classes = label_file::read_classes(&lp, map)?;
                acc.points = ClassCounts::count(map.len(), classes);
            }
            None => acc.points_known = false,
        }
        Ok(acc)
    }
}
