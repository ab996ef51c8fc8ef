//! The checks' thresholds: typed, with their defaults and meaning in one table, tunable by name
//! (`pose-jump.warn-m=3`).

use std::collections::BTreeMap;

use serde::Serialize;

use crate::error::{Error, Result};

/// The values a threshold may take (`--set` refuses others before any work).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Domain {
    /// A share, 0 to 1.
    Share,
    /// A whole number of frames or points, 0 to 1,000,000.
    Count,
    /// A length, speed or score above 0.
    Positive,
    /// A score, 0 or more.
    NonNegative,
    /// A factor, 1 or more.
    Factor,
    /// An angle of 0 to 180 degrees.
    Degrees180,
    /// A horizontal field of view, above 0 and at most 360 degrees.
    FieldOfView,
    /// A turn, above 0 and at most pi radians.
    HalfTurn,
}

impl Domain {
    /// Whether `v` is a value of the domain; the error says which values are.
    pub fn check(self, v: f64) -> std::result::Result<(), &'static str> {
        let ok = v.is_finite()
            && match self {
                Domain::Share => (0.0..=1.0).contains(&v),
                Domain::Count => v.fract() == 0.0 && (0.0..=1e6).contains(&v),
                Domain::Positive => v > 0.0,
                Domain::NonNegative => v >= 0.0,
                Domain::Factor => v >= 1.0,
                Domain::Degrees180 => (0.0..=180.0).contains(&v),
                Domain::FieldOfView => v > 0.0 && v <= 360.0,
                Domain::HalfTurn => v > 0.0 && v <= std::f64::consts::PI,
            };
        if ok {
            return Ok(());
        }
        Err(match self {
            Domain::Share => "a share from 0 to 1",
            Domain::Count => "a whole number from 0 to 1000000",
            Domain::Positive => "a finite number above 0",
            Domain::NonNegative => "a finite number >= 0",
            Domain::Factor => "a finite factor >= 1",
            Domain::Degrees180 => "an angle from 0 to 180 degrees",
            Domain::FieldOfView => "a field of view above 0 and at most 360 degrees",
            Domain::HalfTurn => "an angle above 0 and at most pi (3.14159) radians",
        })
    }
}

macro_rules! thresholds {
    ($($field:ident $domain:ident $name:literal $default:literal $doc:literal;)*) => {
        /// Every threshold of every check (`docs/check.md` explains each).
        #[derive(Debug, Clone, PartialEq, Serialize)]
        pub struct Thresholds {
            $(#[doc = $doc] pub $field: f64,)*
            /// Plausible box sizes per object type (`box-size.<type>.<l|w|h>.<min|max>`).
            pub sizes: BTreeMap<String, SizeRange>,
        }

        impl Default for Thresholds {
            fn default() -> Self {
                Thresholds { $($field: $default,)* sizes: default_sizes() }
            }
        }

        impl Thresholds {
            /// Every scalar threshold: name, value, meaning.
            pub fn scalars(&self) -> Vec<(&'static str, f64, &'static str)> {
                vec![$(($name, self.$field, $doc),)*]
            }

            fn scalar_mut(&mut self, name: &str) -> Option<(&mut f64, Domain)> {
                match name {
                    $($name => Some((&mut self.$field, Domain::$domain)),)*
                    _ => None,
                }
            }
        }
    };
}

thresholds! {
    max_rect_angle_deg Degrees180 "calibration.max-rect-angle-deg" 5.0 "Warning: a rectifying rotation (R_rect, R0_rect) turns by more than this many degrees (KITTI's: under 1).";
    max_focal_ratio Factor "calibration.max-focal-ratio" 1.05 "Warning: fx / fy of a rectified projection differs from 1 by more than this factor.";
    beam_model_warn Share "beam-model.warn-share" 0.01 "Warning: more than this share of a drive's points fit no beam of the sensor model (--sensor, --sensor-calibration).";
    beam_model_error Share "beam-model.error-share" 0.5 "Error: more than this share: the points are not in the sensor's frame, or the scans are another sensor's.";
    overlap_warn Share "camera-overlap.warn-share" 0.6 "Warning: fewer of the points ahead (velodyne x > 8 m, within 35 degrees left or right and 10 degrees up or down) land inside camera 2's image than this share.";
    overlap_error Share "camera-overlap.error-share" 0.2 "Error: fewer than this share land inside the image.";
    alignment_frames Count "camera-alignment.frames" 3.0 "Frames per drive (evenly spaced) whose images are read to judge the alignment.";
    alignment_min_score NonNegative "camera-alignment.min-score" 1.5 "Warning: the image edges at the calibrated position stand fewer than this many standard deviations above their mean over offsets of up to 20 px.";
    size_error_factor Factor "box-size.error-factor" 2.0 "Error (not warning): a dimension beyond the type's maximum times this, or below its minimum divided by it.";
    jump_warn_m Positive "pose-jump.warn-m" 2.0 "Warning: a box's displacement changes by more than this many metres from one frame to the next (an acceleration of 200 m/s2 at 10 Hz).";
    jump_error_m Positive "pose-jump.error-m" 6.0 "Error: it changes by more than this.";
    max_speed_mps Positive "pose-jump.max-speed-mps" 70.0 "Error: a box moves faster than this relative to the sensor (two cars at 126 km/h meeting).";
    yaw_warn_rad HalfTurn "yaw-flip.vehicle-rad" 0.6 "Warning: a vehicle's (Car, Van, Truck, Tram) heading turns by more than this many radians from one frame to the next.";
    yaw_flip_rad HalfTurn "yaw-flip.flip-rad" 2.5 "Warning, any type: the heading turns by more than this (a box turned around).";
    overlap_share_warn Share "box-overlap.warn-share" 0.3 "Warning: this share of the smaller box's volume lies inside another object's box.";
    overlap_share_error Share "box-overlap.error-share" 0.9 "Error: this share (a duplicate box).";
    ground_offset_m Positive "box-ground.max-offset-m" 0.6 "Warning: a box's bottom is more than this many metres below or above the ground around it.";
    ground_ring_m Positive "box-ground.ring-m" 2.0 "The ground around a box: points within this many metres of its footprint, outside it.";
    ground_min_points Count "box-ground.min-points" 30.0 "The ground is judged only from at least this many points around the box.";
    empty_max_range_m Positive "empty-box.max-range-m" 40.0 "Warning: a box marked fully visible (occlusion 0), nearer than this, holds no point.";
    ends_min_points Count "annotation-ends.min-points" 30.0 "Warning: the box carried one frame past the annotation's end (at its last velocity) still holds at least this many points...";
    ends_min_share Share "annotation-ends.min-share" 0.5 "...and at least this share of the points it held in its last annotated frame.";
    ends_fov_deg FieldOfView "annotation-ends.fov-deg" 80.0 "Only boxes within this horizontal field of view (degrees, centred forward; KITTI annotates the camera's view).";
    falloff_share Share "annotation-falloff.share" 0.25 "Warning: a run of frames with fewer annotated objects than this share of the drive's median count...";
    falloff_min_frames Count "annotation-falloff.min-frames" 10.0 "...at least this many frames long (drives with a median of 4 objects or more).";
    moving_still_m Positive "moving-static.still-m" 0.05 "Warning: an instance of a moving class whose points lie within this many metres of the previous scan's points (poses applied)...";
    moving_still_share Share "moving-static.share" 0.9 "...for at least this share of its points.";
    balance_min_count Count "split-balance.min-count" 100.0 "Balance is judged only when train and val each hold at least this many annotations (boxes, or labelled points).";
    balance_factor Factor "split-balance.factor" 3.0 "Warning: a class's share in val is more than this factor above or below its share in train.";
}

/// A plausible range of a box's length, width and height, metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SizeRange {
    /// Length (along the heading), min and max.
    pub l: [f64; 2],
    /// Width.
    pub w: [f64; 2],
    /// Height.
    pub h: [f64; 2],
}

/// KITTI's object types, with ranges that hold every box of the 36 annotated drives shared
/// here and the object set's frames, widened by a margin (`docs/check.md`).
fn default_sizes() -> BTreeMap<String, SizeRange> {
    let r = |l: [f64; 2], w: [f64; 2], h: [f64; 2]| SizeRange { l, w, h };
    [
        ("Car", r([2.0, 6.0], [1.0, 2.3], [1.0, 2.5])),
        ("Van", r([3.0, 7.5], [1.4, 2.6], [1.4, 3.6])),
        ("Truck", r([4.0, 20.0], [1.6, 3.2], [1.8, 4.6])),
        ("Pedestrian", r([0.1, 2.0], [0.2, 1.5], [0.8, 2.3])),
        ("Person_sitting", r([0.2, 2.0], [0.2, 1.5], [0.5, 1.8])),
        ("Person (sitting)", r([0.2, 2.0], [0.2, 1.5], [0.5, 1.8])),
        ("Cyclist", r([1.0, 2.6], [0.2, 1.5], [0.9, 2.3])),
        ("Tram", r([8.0, 40.0], [1.8, 3.4], [2.5, 4.6])),
        ("Misc", r([0.1, 20.0], [0.1, 5.0], [0.1, 5.0])),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect()
}

impl Thresholds {
    /// Sets the threshold `name` (`pose-jump.warn-m`, `box-size.Pedestrian.l.max`) to `value`.
    pub fn set(&mut self, name: &str, value: f64) -> Result<()> {
        let refuse = |what: &str| {
            Err(Error::Config(format!(
                "threshold {name} = {value}: must be {what}"
            )))
        };
        if let Some((v, domain)) = self.scalar_mut(name) {
            if let Err(what) = domain.check(value) {
                return refuse(what);
            }
            *v = value;
            return Ok(());
        }
        if let Err(what) = Domain::Positive.check(value) {
            return refuse(what);
        }
        let size = name.strip_prefix("box-size.").and_then(|rest| {
            let mut parts = rest.rsplitn(3, '.');
            let bound = parts.next()?;
            let dim = parts.next()?;
            let kind = parts.next()?;
            Some((kind.to_string(), dim, bound))
        });
        let Some((kind, dim, bound)) = size else {
            return Err(Error::Config(format!("unknown threshold `{name}`")));
        };
        let range = self.sizes.entry(kind).or_insert(SizeRange {
            l: [0.0, f64::INFINITY],
            w: [0.0, f64::INFINITY],
            h: [0.0, f64::INFINITY],
        });
        let pair = match dim {
            "l" => &mut range.l,
            "w" => &mut range.w,
            "h" => &mut range.h,
            _ => {
                return Err(Error::Config(format!(
                    "threshold `{name}`: the dimension is l, w or h"
                )))
            }
        };
        match bound {
            "min" => pair[0] = value,
            "max" => pair[1] = value,
            _ => {
                return Err(Error::Config(format!(
                    "threshold `{name}`: the bound is min or max"
                )))
            }
        }
        Ok(())
    }

    /// Parses `NAME=VALUE` and sets it.
    pub fn set_pair(&mut self, pair: &str) -> Result<()> {
        let (name, value) = pair
            .split_once('=')
            .ok_or_else(|| Error::Config(format!("threshold `{pair}`: write NAME=VALUE")))?;
        let value: f64 = value
            .trim()
            .parse()
            .map_err(|_| Error::Config(format!("threshold `{pair}`: `{value}` is not a number")))?;
        self.set(name.trim(), value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thresholds_are_set_by_name() {
        let mut t = Thresholds::default();
        t.set_pair("pose-jump.warn-m=3").unwrap();
        assert_eq!(t.jump_warn_m, 3.0);
        t.set_pair("box-size.Pedestrian.l.max=2.5").unwrap();
        assert_eq!(t.sizes["Pedestrian"].l[1], 2.5);
        for bad in [
            "nope=1",
            "pose-jump.warn-m",
            "pose-jump.warn-m=x",
            "box-size.Car.q.max=1",
            "pose-jump.warn-m=-1",
            // (Issue 26) each threshold has its domain.
            "camera-alignment.frames=2.5",
            "camera-alignment.frames=1e12",
            "split-balance.factor=0",
            "annotation-ends.fov-deg=720",
            "camera-overlap.warn-share=1.5",
            "box-size.Car.l.max=0",
        ] {
            assert!(t.set_pair(bad).is_err(), "{bad}");
        }
    }
}
