//! Named map layouts ([`MapPreset`]): the shapes users train with, and each source's default;
//! a map chosen by preset and single values ([`MapChoice`], what the CLI's `--preset`, `--rows`
//! ... and the Python module's `preset=`, `rows=` ... ask for), and how it was chosen
//! ([`MapOrigin`], the summary's `map_origin`).

use super::{PgmSpec, RowMode};
use crate::geom::Degrees;
use crate::source::kitti::DatasetKind;

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
    pub fn default_for(layout: DatasetKind) -> MapPreset {
        match layout {
            DatasetKind::Sequence => MapPreset::Full,
            DatasetKind::Raw | DatasetKind::Object => MapPreset::Squeezeseg,
        }
    }
}

/// A single value of a map, given over its preset's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum MapValue {
    /// Rows.
    Rows,
    /// Columns.
    Cols,
    /// Horizontal field of view.
    FovDeg,
    /// Upper bound of the elevation bins.
    FovUpDeg,
    /// Lower bound of the elevation bins.
    FovDownDeg,
    /// Where rows come from.
    RowMode,
}

crate::named_enum!(MapValue, "map value", [
    Rows => "rows" [] "rows of the map",
    Cols => "cols" [] "columns of the map",
    FovDeg => "fov-deg" ["fov_deg"] "horizontal field of view, degrees",
    FovUpDeg => "fov-up-deg" ["fov_up_deg"] "upper bound of the elevation bins, degrees",
    FovDownDeg => "fov-down-deg" ["fov_down_deg"] "lower bound of the elevation bins, degrees",
    RowMode => "row-mode" ["row_mode"] "where rows come from",
]);

/// A map asked for by preset and single values; unset values are the preset's, an unset preset
/// the source's default ([`MapPreset::default_for`]; `squeezeseg` without a source).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MapChoice {
    /// The preset.
    pub preset: Option<MapPreset>,
    /// Rows.
    pub rows: Option<usize>,
    /// Columns.
    pub cols: Option<usize>,
    /// Horizontal field of view, degrees.
    pub fov_deg: Option<f64>,
    /// Upper bound of the elevation bins, degrees.
    pub fov_up_deg: Option<f64>,
    /// Lower bound of the elevation bins, degrees.
    pub fov_down_deg: Option<f64>,
    /// Where rows come from.
    pub row_mode: Option<RowMode>,
}

impl MapChoice {
    /// The preset in force for a source of `layout` (none: no source known).
    pub fn preset(&self, layout: Option<DatasetKind>) -> MapPreset {
        self.preset
            .unwrap_or_else(|| layout.map_or(MapPreset::Squeezeseg, MapPreset::default_for))
    }

    /// The map: the preset's, each value given in its place (not yet validated).
    pub fn spec(&self, layout: Option<DatasetKind>) -> PgmSpec {
        let p = self.preset(layout).spec();
        PgmSpec {
            rows: self.rows.unwrap_or(p.rows),
            cols: self.cols.unwrap_or(p.cols),
            fov: self.fov_deg.map_or(p.fov, Degrees),
            fov_up: self.fov_up_deg.map_or(p.fov_up, Degrees),
            fov_down: self.fov_down_deg.map_or(p.fov_down, Degrees),
            row_mode: self.row_mode.unwrap_or(p.row_mode),
        }
    }

    /// How the map came about.
    pub fn origin(&self, layout: Option<DatasetKind>) -> MapOrigin {
        let given = [
            (MapValue::Rows, self.rows.is_some()),
            (MapValue::Cols, self.cols.is_some()),
            (MapValue::FovDeg, self.fov_deg.is_some()),
            (MapValue::FovUpDeg, self.fov_up_deg.is_some()),
            (MapValue::FovDownDeg, self.fov_down_deg.is_some()),
            (MapValue::RowMode, self.row_mode.is_some()),
        ];
        MapOrigin {
            preset: self.preset(layout),
            default_for: if self.preset.is_some() { None } else { layout },
            given: given
                .into_iter()
                .filter(|(_, g)| *g)
                .map(|(v, _)| v)
                .collect(),
        }
    }
}

/// How a conversion's map was chosen: its preset, why (asked for, or a source's default) and the
/// values given over it. Written as one line (`preset full (the default for SemanticKITTI)`,
/// `preset rangenet (asked for), with cols given`) in the summary's `map_origin`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MapOrigin {
    /// The preset.
    pub preset: MapPreset,
    /// `None`: the preset was asked for; else the source it is the default of.
    pub default_for: Option<DatasetKind>,
    /// The values given over the preset's.
    pub given: Vec<MapValue>,
}

impl std::fmt::Display for MapOrigin {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "preset {} (", self.preset)?;
        match self.default_for {
            Some(l) => write!(f, "the default for {})", l.dataset())?,
            None => f.write_str("asked for)")?,
        }
        if !self.given.is_empty() {
            let names: Vec<&str> = self.given.iter().map(|v| v.as_str()).collect();
            write!(f, ", with {} given", names.join(", "))?;
        }
        Ok(())
    }
}

impl std::str::FromStr for MapOrigin {
    type Err = crate::Error;

    /// The line [`Display`](std::fmt::Display) writes; also the form of earlier versions
    /// (`(--preset)`, `with --cols, --rows given`).
    fn from_str(s: &str) -> crate::Result<MapOrigin> {
        let bad = || {
            crate::Error::Config(format!(
                "{s:?} is not a map origin like `preset full (the default for SemanticKITTI)`"
            ))
        };
        let rest = s.strip_prefix("preset ").ok_or_else(bad)?;
        let (preset, rest) = rest.split_once(" (").ok_or_else(bad)?;
        let (why, rest) = rest.split_once(')').ok_or_else(bad)?;
        let default_for = match why {
            "asked for" | "--preset" => None,
            _ => {
                let dataset = why.strip_prefix("the default for ").ok_or_else(bad)?;
                let layout = DatasetKind::ALL.iter().find(|l| l.dataset() == dataset);
                Some(*layout.ok_or_else(bad)?)
            }
        };
        let given = match rest
            .strip_prefix(", with ")
            .and_then(|r| r.strip_suffix(" given"))
        {
            Some(list) => list
                .split(", ")
                .map(|v| v.trim_start_matches("--").parse())
                .collect::<crate::Result<Vec<MapValue>>>()?,
            None if rest.is_empty() => Vec::new(),
            None => return Err(bad()),
        };
        Ok(MapOrigin {
            preset: preset.parse()?,
            default_for,
            given,
        })
    }
}

impl serde::Serialize for MapOrigin {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> serde::Deserialize<'de> for MapOrigin {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = <String as serde::Deserialize>::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
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
        // The map of a choice, and how it came about, read back from its line.
        let c = MapChoice {
            preset: Some(MapPreset::Rangenet),
            cols: Some(1024),
            ..Default::default()
        };
        assert_eq!(c.spec(Some(DatasetKind::Raw)).cols, 1024);
        let o = c.origin(Some(DatasetKind::Raw));
        assert_eq!(
            o.to_string(),
            "preset rangenet (asked for), with cols given"
        );
        assert_eq!(o.to_string().parse::<MapOrigin>().unwrap(), o);
        let d = MapChoice::default().origin(Some(DatasetKind::Sequence));
        assert_eq!(d.to_string(), "preset full (the default for SemanticKITTI)");
        assert_eq!(d.to_string().parse::<MapOrigin>().unwrap(), d);
        let old: MapOrigin = "preset rangenet (--preset), with --cols, --rows given"
            .parse()
            .unwrap();
        assert_eq!(old.given, [MapValue::Cols, MapValue::Rows]);
        assert_eq!(MapChoice::default().spec(None), PgmSpec::default());
        assert_eq!(
            MapPreset::default_for(DatasetKind::Sequence),
            MapPreset::Full
        );
    }
}
