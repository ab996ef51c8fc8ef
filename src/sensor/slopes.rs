//! SENSOR: a beam table's angles as slopes (z / horizontal distance, monotonic in the
//! elevation), and the row of a slope found with a lookup grid instead of a count or a search.

/// A table's angles as slopes: the boundaries between rows, and each beam's tolerance band.
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct Slopes {
    /// The slopes of the boundaries between rows k and k + 1, descending.
    mid: Vec<f64>,
    /// The slopes of each beam's lowest and highest fitting elevations.
    bands: Vec<(f64, f64)>,
    /// The row of a slope in two lookups; `None` when the boundaries are too close together for
    /// a grid of at most [`Grid::MAX_CELLS`] cells (the row is then counted).
    grid: Option<Grid>,
}

/// A uniform grid over the boundaries' slopes: the cell of a slope says how many boundaries lie
/// surely above it and which one (at most one) is near enough to need a comparison.
///
/// Cells are a quarter of the smallest gap between boundaries wide; cell `k` covers `[a, a + w)`
/// with `a = t0 + k w`, and its window `[a - w, a + 2w)` (three quarters of the smallest gap)
/// holds at most one boundary: `probe`, or minus infinity. `above` counts the boundaries at or
/// above the window's top. A slope placed one cell off by rounding still lies in the window,
/// so the row is always the count's, exactly.
#[derive(Debug, Clone, PartialEq)]
struct Grid {
    t0: f64,
    inv_w: f64,
    last: f64,
    /// `(probe, above)` of every cell.
    cells: Vec<(f64, u32)>,
}

impl Grid {
    /// The most cells a grid may have (beyond it the row is counted).
    const MAX_CELLS: f64 = 65_536.0;

    /// The grid of descending boundaries `mid`, if it has at most [`Grid::MAX_CELLS`] cells.
    fn new(mid: &[f64]) -> Option<Grid> {
        let (&hi, &lo) = (mid.first()?, mid.last()?);
        let gap = mid
            .windows(2)
            .map(|w| w[0] - w[1])
            .fold(f64::INFINITY, f64::min);
        // One boundary: any width will do.
        let w = if gap.is_finite() { gap / 4.0 } else { 1.0 };
        let t0 = lo - 2.0 * w;
        let count = ((hi - lo) / w).ceil() + 5.0;
        if !(w > 0.0 && count.is_finite() && count <= Grid::MAX_CELLS) {
            return None;
        }
        let cells = (0..count as usize)
            .map(|k| {
                let a = t0 + k as f64 * w;
                let (bottom, top) = (a - w, a + 2.0 * w);
                let above = mid.iter().filter(|&&m| m >= top).count() as u32;
                let probe = mid
                    .iter()
                    .copied()
                    .find(|&m| bottom <= m && m < top)
                    .unwrap_or(f64::NEG_INFINITY);
                (probe, above)
            })
            .collect();
        Some(Grid {
            t0,
            inv_w: 1.0 / w,
            last: count - 1.0,
            cells,
        })
    }

    /// The number of boundaries above the finite slope `t`.
    #[inline(always)]
    fn above(&self, t: f64) -> usize {
        let k = ((t - self.t0) * self.inv_w).clamp(0.0, self.last) as usize;
        let (probe, above) = self.cells[k];
        above as usize + usize::from(probe > t)
    }
}

impl Slopes {
    /// The slopes of beams at `elevations` (radians, descending) with half-gaps `tolerance`.
    pub(super) fn new(elevations: &[f64], tolerance: &[f64]) -> Slopes {
        let half_pi = std::f64::consts::FRAC_PI_2;
        let tan = |a: f64| match a {
            a if a >= half_pi => f64::INFINITY,
            a if a <= -half_pi => f64::NEG_INFINITY,
            a => a.tan(),
        };
        let mid: Vec<f64> = elevations
            .windows(2)
            .map(|w| tan((w[0] + w[1]) / 2.0))
            .collect();
        Slopes {
            grid: Grid::new(&mid),
            mid,
            bands: elevations
                .iter()
                .zip(tolerance)
                .map(|(e, t)| (tan(e - t), tan(e + t)))
                .collect(),
        }
    }

    /// The row of the finite slope `t` (the number of boundaries above it: a point on a
    /// boundary takes the upper row) and whether it fits that row's beam.
    #[inline(always)]
    pub(super) fn row(&self, t: f64) -> (u8, bool) {
        let row = match &self.grid {
            Some(g) => g.above(t),
            None => self.count_above(t),
        };
        let (low, high) = self.bands[row];
        (row as u8, (low <= t) & (t <= high))
    }

    /// The number of boundaries above `t`, counted without a branch (the compiler vectorises
    /// it; a binary search mispredicted about half of its steps).
    #[inline]
    fn count_above(&self, t: f64) -> usize {
        self.mid.iter().map(|&m| usize::from(m > t)).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_counts_as_the_boundaries_do() {
        // Uneven gaps (Pandar40P-like: dense at the centre), one boundary, and slopes on,
        // beside and far beyond every boundary.
        let tables: [&[f64]; 3] = [
            &[0.27, 0.1, 0.02, 0.0147, 0.0089, 0.003, -0.0028, -0.2, -0.47],
            &[0.05],
            &[1e-3, 0.0, -1e-3],
        ];
        for mid in tables {
            let s = Slopes {
                grid: Grid::new(mid),
                mid: mid.to_vec(),
                ..Default::default()
            };
            let g = s.grid.as_ref().expect("a grid");
            let mut ts: Vec<f64> = vec![-1e300, -5.0, 5.0, 1e300, 0.0, -0.0];
            for &m in mid {
                ts.extend([m, m.next_up(), m.next_down(), m + 1e-7, m - 1e-7]);
            }
            ts.extend((-6000..6000).map(|k| k as f64 * 1e-4));
            for t in ts {
                assert_eq!(g.above(t), s.count_above(t), "{mid:?} at {t}");
            }
        }
    }

    #[test]
    fn boundaries_too_close_for_a_grid_are_counted() {
        // Beams near the zenith: the boundaries' slopes span thousands of the smallest gap.
        let e: Vec<f64> = [89.99f64, 89.9, 10.0, 9.9998, 9.9996]
            .iter()
            .map(|d| d.to_radians())
            .collect();
        let s = Slopes::new(&e, &[1e-6; 5]);
        assert!(s.grid.is_none());
        assert_eq!(s.row(0.0).0, 4);
        assert_eq!(s.row(1.0).0, 2);
        assert_eq!(s.row(1e4).0, 0);
    }
}
