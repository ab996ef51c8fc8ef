//! LABEL: which box each point of a scan falls in.
//!
//! [`LabelBox`] turns a box ([`Box3`], in the scan's frame) into a parry [`Cuboid`] (half
//! extents) with a centred pose;
//! [`Labeller`] answers "which box holds this point" for a whole scan with parry's containment
//! test, after a cheap prefilter by the boxes' axis-aligned bounds. A scan is labelled in runs
//! of 64 points, box by box: a box apart from the run's bounds is passed over, else its bounds
//! are tested on all 64 points at once (SIMD lanes, no branch), parry's test on those inside.
//! One point, or a scan among more than [`BY_BOX_MAX`] boxes (the 36 drives' tracklets have
//! 21 at most in a frame), goes through a 2D bucket grid over the bounds instead: one lookup a
//! point plus the boxes of its cell. Both give every point the same box.
//!
//! Rule for a point in several boxes: the box of the smallest volume wins (the more specific
//! claim: a cyclist box overlapping a car's keeps its points), ties go to the lower tracklet
//! index. Only boxes of a labelled class (car, pedestrian, cyclist) take part: a point in a Tram
//! or Misc box stays background with instance 0. Which object type is which class is the class
//! map's business ([`ClassMap::class_of_object`](super::ClassMap::class_of_object)).

use super::classes::ClassId;
use crate::geom::{na, Iso3, Point3, Real};
use crate::source::boxes::Box3;
use parry3d::query::PointQuery;
use parry3d::shape::Cuboid;

/// A tracklet box at one frame, ready for containment tests.
#[derive(Debug, Clone)]
pub struct LabelBox {
    /// Class of the object.
    pub class: ClassId,
    /// Instance id: tracklet index + 1.
    pub instance: u16,
    /// The box in its own frame (half extents l/2, w/2, h/2).
    pub cuboid: Cuboid,
    /// Box frame to the scan's frame; the origin is the box centre.
    pub pose: Iso3,
}

impl LabelBox {
    /// The box `b` (scan frame) of class `class` and instance `instance`.
    pub fn of(b: &Box3, class: ClassId, instance: u16) -> LabelBox {
        LabelBox {
            class,
            instance,
            cuboid: Cuboid::new(b.half_extents),
            pose: b.pose,
        }
    }

    /// Volume, cubic metres.
    pub fn volume(&self) -> Real {
        8.0 * self.cuboid.half_extents.product()
    }

    /// Whether `p` (the scan's frame) is inside the box, boundaries included.
    pub fn contains(&self, p: &Point3) -> bool {
        self.cuboid.contains_point(&self.pose, p)
    }
}

/// Per-point labels of a scan, in the scan's point order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointLabels {
    /// Class of each point.
    pub class: Vec<ClassId>,
    /// Instance id of each point (0 = none).
    pub instance: Vec<u16>,
}

impl PointLabels {
    /// Points per class among `n` classes.
    pub fn class_counts(&self, n: usize) -> super::ClassCounts {
        super::ClassCounts::count(n, self.class.iter().copied())
    }
}

/// Labels scans against a set of boxes (one frame's boxes).
#[derive(Debug, Clone)]
pub struct Labeller {
    background: ClassId,
    boxes: Vec<Prepared>,
    grid: Grid,
}

#[derive(Debug, Clone)]
struct Prepared {
    class: ClassId,
    instance: u16,
    cuboid: Cuboid,
    /// Velodyne frame to box frame, with the rotation as a matrix (cheaper per point than the
    /// quaternion of the box pose).
    velo_to_box: na::IsometryMatrix3<Real>,
    /// Axis-aligned bounds in the scan's frame: a cheap reject before parry's test.
    mins: Point3,
    maxs: Point3,
}

/// A uniform XY bucket grid over the union of the boxes' bounding boxes, stored CSR-style.
#[derive(Debug, Clone, Default)]
struct Grid {
    min: [Real; 2],
    inv_cell: Real,
    dims: [usize; 2],
    starts: Vec<u32>,
    items: Vec<u16>,
}

impl Labeller {
    /// Prepares the boxes among `boxes` whose class is not `background` (the class of every
    /// point outside them).
    pub fn new(boxes: &[LabelBox], background: ClassId) -> Labeller {
        let mut kept: Vec<&LabelBox> = boxes.iter().filter(|b| b.class != background).collect();
        // Smallest volume first, then lowest tracklet index: the first hit wins.
        kept.sort_by(|a, b| {
            a.volume()
                .total_cmp(&b.volume())
                .then(a.instance.cmp(&b.instance))
        });
        let mut aabbs = Vec::with_capacity(kept.len());
        let boxes: Vec<Prepared> = kept
            .iter()
            .map(|b| {
                let aabb = b.cuboid.aabb(&b.pose);
                aabbs.push(aabb);
                Prepared {
                    class: b.class,
                    instance: b.instance,
                    cuboid: b.cuboid,
                    velo_to_box: {
                        let inv = b.pose.inverse();
                        na::IsometryMatrix3::from_parts(
                            inv.translation,
                            inv.rotation.to_rotation_matrix(),
                        )
                    },
                    mins: aabb.mins,
                    maxs: aabb.maxs,
                }
            })
            .collect();
        let grid = Grid::build(&aabbs);
        Labeller {
            background,
            boxes,
            grid,
        }
    }

    /// Number of boxes that take part.
    pub fn len(&self) -> usize {
        self.boxes.len()
    }

    /// True when no box takes part (every point is background).
    pub fn is_empty(&self) -> bool {
        self.boxes.is_empty()
    }

    /// The winning box of one point: (class, instance), or `None`.
    #[inline]
    pub fn label_point(&self, p: &Point3) -> Option<(ClassId, u16)> {
        for &i in self.grid.candidates(p.x, p.y) {
            let b = &self.boxes[i as usize];
            if !b.bounds_hold(p.x, p.y, p.z) {
                continue;
            }
            if b.cuboid
                .contains_local_point(&b.velo_to_box.transform_point(p))
            {
                return Some((b.class, b.instance));
            }
        }
        None
    }

    /// Labels every point of a scan: each point as [`Labeller::label_point`] would. Up to
    /// [`BY_BOX_MAX`] boxes, box by box over blocks of points ([`Labeller::label_by_box`]),
    /// else point by point through the grid.
    pub fn label(&self, points: &[Point3]) -> PointLabels {
        let mut labels = PointLabels {
            class: vec![self.background; points.len()],
            instance: vec![0u16; points.len()],
        };
        if self.boxes.len() > BY_BOX_MAX {
            for (i, p) in points.iter().enumerate() {
                if let Some((c, id)) = self.label_point(p) {
                    labels.class[i] = c;
                    labels.instance[i] = id;
                }
            }
        } else if !self.is_empty() {
            for (start, pts) in (0..).step_by(BLOCK).zip(points.chunks(BLOCK)) {
                crate::simd::with_simd(
                    #[inline(always)]
                    || self.label_by_box(start, pts, &mut labels),
                );
            }
        }
        labels
    }

    /// The labels of a block of points (from `start` in the scan), 64 points at a time, box
    /// by box in the order of precedence: a box apart from the 64 points' bounds passed over,
    /// else its bounds tested on the 64 at once (branch-free, in SIMD lanes), then parry's
    /// test on those inside it and not yet labelled. The same result as the grid's, without
    /// its unpredictable branch per candidate box.
    #[inline(always)]
    fn label_by_box(&self, start: usize, pts: &[Point3], labels: &mut PointLabels) {
        let n = pts.len();
        assert!(n <= BLOCK);
        let (mut x, mut y, mut z) = ([0.0; BLOCK], [0.0; BLOCK], [0.0; BLOCK]);
        for (k, p) in pts.iter().enumerate() {
            (x[k], y[k], z[k]) = (p.x, p.y, p.z);
        }
        // A bit a point, set while it is free to take a box (not the slots past the block).
        let mut free = [0u64; BLOCK / 64];
        for (w, f) in free.iter_mut().enumerate() {
            let k = n.saturating_sub(w * 64).min(64);
            *f = if k == 64 { u64::MAX } else { (1u64 << k) - 1 };
        }
        for (w, f) in free.iter_mut().enumerate().take(n.div_ceil(64)) {
            let (x, y, z) = (&x[w * 64..][..64], &y[w * 64..][..64], &z[w * 64..][..64]);
            // The bounds of the 64 points (a slot past the block, at the origin, only widens
            // them; a NaN is passed over): most boxes lie outside them (a run of one ring).
            let lo = Point3::new(min_of(x), min_of(y), min_of(z));
            let hi = Point3::new(max_of(x), max_of(y), max_of(z));
            for b in &self.boxes {
                let apart = (b.mins.x > hi.x) | (b.maxs.x < lo.x) | (b.mins.y > hi.y);
                if apart | (b.maxs.y < lo.y) | (b.mins.z > hi.z) | (b.maxs.z < lo.z) {
                    continue;
                }
                // 64 bounds tests to one word (compares to mask registers, with AVX-512).
                let mut bits = 0u64;
                for j in 0..64 {
                    bits |= u64::from(b.bounds_hold(x[j], y[j], z[j])) << j;
                }
                bits &= *f;
                while bits != 0 {
                    let j = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    let k = w * 64 + j;
                    if b.cuboid
                        .contains_local_point(&b.velo_to_box.transform_point(&pts[k]))
                    {
                        *f &= !(1 << j);
                        labels.class[start + k] = b.class;
                        labels.instance[start + k] = b.instance;
                    }
                }
            }
        }
    }
}

/// The least of `v` (NaN passed over).
#[inline(always)]
fn min_of(v: &[Real]) -> Real {
    v.iter().fold(Real::INFINITY, |a, &b| a.min(b))
}

/// The greatest of `v` (NaN passed over).
#[inline(always)]
fn max_of(v: &[Real]) -> Real {
    v.iter().fold(Real::NEG_INFINITY, |a, &b| a.max(b))
}

/// Points per block of [`Labeller::label_by_box`].
const BLOCK: usize = 1024;

/// The most boxes labelled box by box ([`Labeller::label_by_box`]): its cost grows with the
/// boxes near each run of points, the grid's more slowly. Measured on a real scan among cars
/// scattered over 60 x 60 m (`cargo bench -p kitti2pgm-bench -- '^label/'`): box by box 3.0x the
/// grid's speed with 4 boxes, 2.8x with 64, 1.34x with 256; 0.97x with 512.
pub const BY_BOX_MAX: usize = 256;

impl Prepared {
    /// Whether the box's axis-aligned bounds hold the point, without a branch (a NaN
    /// coordinate never: parry's test would take it in).
    #[inline(always)]
    fn bounds_hold(&self, x: Real, y: Real, z: Real) -> bool {
        let (lo, hi) = (&self.mins, &self.maxs);
        (x >= lo.x) & (x <= hi.x) & (y >= lo.y) & (y <= hi.y) & (z >= lo.z) & (z <= hi.z)
    }
}

impl Grid {
    /// Cell edge in metres; about a car's width, so a cell rarely holds more than a few boxes.
    const CELL: Real = 2.0;
    /// Upper bound on cells per axis (the cell grows instead).
    const MAX_DIM: usize = 256;

    fn build(aabbs: &[parry3d::bounding_volume::Aabb]) -> Grid {
        if aabbs.is_empty() {
            return Grid::default();
        }
        let mut min = [Real::INFINITY; 2];
        let mut max = [Real::NEG_INFINITY; 2];
        for a in aabbs {
            for k in 0..2 {
                min[k] = min[k].min(a.mins[k]);
                max[k] = max[k].max(a.maxs[k]);
            }
        }
        let extent = (max[0] - min[0]).max(max[1] - min[1]);
        let cell = Self::CELL.max(extent / Self::MAX_DIM as Real);
        let inv_cell = 1.0 / cell;
        let dims = [0, 1]
            .map(|k| (((max[k] - min[k]) * inv_cell).floor() as usize + 1).min(Self::MAX_DIM + 1));
        let cell_of = |v: Real, k: usize| {
            (((v - min[k]) * inv_cell).floor().max(0.0) as usize).min(dims[k] - 1)
        };
        let mut lists: Vec<Vec<u16>> = vec![Vec::new(); dims[0] * dims[1]];
        for (i, a) in aabbs.iter().enumerate() {
            for cx in cell_of(a.mins.x, 0)..=cell_of(a.maxs.x, 0) {
                for cy in cell_of(a.mins.y, 1)..=cell_of(a.maxs.y, 1) {
                    lists[cx * dims[1] + cy].push(i as u16);
                }
            }
        }
        let mut starts = Vec::with_capacity(lists.len() + 1);
        let mut items = Vec::new();
        starts.push(0);
        for l in lists {
            items.extend(l);
            starts.push(items.len() as u32);
        }
        Grid {
            min,
            inv_cell,
            dims,
            starts,
            items,
        }
    }

    #[inline]
    fn candidates(&self, x: Real, y: Real) -> &[u16] {
        if self.items.is_empty() {
            return &[];
        }
        let fx = (x - self.min[0]) * self.inv_cell;
        let fy = (y - self.min[1]) * self.inv_cell;
        // Negative or NaN fails the comparison; the cell index is then in range.
        if !(fx >= 0.0 && fy >= 0.0 && fx < self.dims[0] as Real && fy < self.dims[1] as Real) {
            return &[];
        }
        let c = fx as usize * self.dims[1] + fy as usize;
        &self.items[self.starts[c] as usize..self.starts[c + 1] as usize]
    }
}
