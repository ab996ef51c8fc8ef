//! Named map layouts ([`MapPreset`]): the shapes users train with, and each source's default.

use super::{PgmSpec, RowMode};
use crate::geom::Degrees;
use crate::kitti::Layout;

/// A named map layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MapPreset {
    /// SqueezeSeg / PointSeg / El Madawi et al.: 64 x 512 over the front 90 degrees, rows from
    /// the laser rings (the default for KITTI raw and the object set).
    Squeezeseg,
    /// RangeNet++ (lidar-bonnetal): 64 x 2048 over 360 degrees, rows by elevation between +3
    /// and -25 degrees.
    Rangenet,
    /// 64 x 2048 over 360 degrees with rows from the laser rings: RangeNet++'s shape without
    /// its empty rows and stacked lasers (the default for SemanticKITTI).
    Full,
}

crate::named_enum!(MapPreset, "map preset", [
    Squeezeseg => "squeezeseg" [] "SqueezeSeg / PointSeg: 64 x 512 over the front 90 degrees, rows from the laser rings",
    Rangenet => "rangenet" [] "RangeNet++: 64 x 2048 over 360 degrees, rows by elevation between +3 and -25 degrees",
    Full => "full" [] "64 x 2048 over 360 degrees, rows from the laser rings",
]);

impl MapPreset {
    /// The map it stands for.
    pub fn spec(self) -> PgmSpec {
        let squeezeseg = PgmSpec::default();
        match self {
            MapPreset::Squeezeseg => squeezeseg,
            MapPreset::Rangenet => PgmSpec {
                cols: 2048,
                fov: Degrees(360.0),
                fov_up: Degrees(3.0),
                fov_down: Degrees(-25.0),
                row_mode: RowMode::Elevation,
                ..squeezeseg
            },
            MapPreset::Full => PgmSpec {
                cols: 2048,
                fov: Degrees(360.0),
                ..squeezeseg
            },
        }
    }

    /// The default of a source: `full` for SemanticKITTI (its benchmark scores every point of
    /// the 360-degree scan), `squeezeseg` for KITTI raw and the object set.
    pub fn default_for(layout: Layout) -> MapPreset {
        match layout {
            Layout::Sequence => MapPreset::Full,
            Layout::Raw | Layout::Object => MapPreset::Squeezeseg,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_are_the_published_shapes() {
        let r = MapPreset::Rangenet.spec();
        assert_eq!((r.rows, r.cols, r.fov.0), (64, 2048, 360.0));
        assert_eq!(
            (r.fov_up.0, r.fov_down.0, r.row_mode),
            (3.0, -25.0, RowMode::Elevation)
        );
        assert_eq!(MapPreset::Squeezeseg.spec(), PgmSpec::default());
        let f = MapPreset::Full.spec();
        assert_eq!((f.cols, f.fov.0, f.row_mode), (2048, 360.0, RowMode::Rings));
        for &p in MapPreset::ALL {
            assert_eq!(p.as_str().parse::<MapPreset>().ok(), Some(p));
            p.spec().validate().unwrap();
        }
        assert!("bonnetal".parse::<MapPreset>().is_err());
        assert_eq!(MapPreset::default_for(Layout::Sequence), MapPreset::Full);
    }
}
