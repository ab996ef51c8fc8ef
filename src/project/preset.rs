//! Named map layouts ([`MapPreset`]): the shapes users train with, and each source's default.

use std::fmt;
use std::str::FromStr;

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

impl MapPreset {
    /// Every preset, in the order `--help` lists them.
    pub const ALL: [MapPreset; 3] = [MapPreset::Squeezeseg, MapPreset::Rangenet, MapPreset::Full];

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

    /// Its name (`squeezeseg`, `rangenet`, `full`).
    pub fn name(self) -> &'static str {
        match self {
            MapPreset::Squeezeseg => "squeezeseg",
            MapPreset::Rangenet => "rangenet",
            MapPreset::Full => "full",
        }
    }
}

impl fmt::Display for MapPreset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for MapPreset {
    type Err = String;

    fn from_str(s: &str) -> Result<MapPreset, String> {
        MapPreset::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| format!("unknown map preset {s:?}: squeezeseg, rangenet or full"))
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
        for p in MapPreset::ALL {
            assert_eq!(p.name().parse::<MapPreset>(), Ok(p));
            p.spec().validate().unwrap();
        }
        assert!("bonnetal".parse::<MapPreset>().is_err());
        assert_eq!(MapPreset::default_for(Layout::Sequence), MapPreset::Full);
    }
}
