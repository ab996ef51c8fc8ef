//! Built-in sensor models by name: the nominal beam tables of common spinning LiDARs, as the
//! vendors' drivers ship them (Autoware's nebula, Apache-2.0: `tables/LICENSE-nebula`). A unit's
//! own calibration file (`--sensor-calibration`) is more exact where its angles differ from the
//! nominal ones; Ouster has no preset, its angles differ per unit (read its metadata file).

use std::path::Path;

use super::{hesai, velodyne, SensorModel};
use crate::error::Result;

/// A sensor with a built-in beam table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Sensor {
    /// Velodyne VLP-16 (Puck), 16 beams.
    Vlp16,
    /// Velodyne VLP-32C (Ultra Puck), 32 beams.
    Vlp32c,
    /// Velodyne HDL-32E, 32 beams (nuScenes' sensor).
    Hdl32e,
    /// Velodyne HDL-64E S2, 64 beams (KITTI's sensor).
    Hdl64eS2,
    /// Velodyne HDL-64E S3, 64 beams.
    Hdl64eS3,
    /// Velodyne VLS-128 (Alpha Prime), 128 beams.
    Vls128,
    /// Hesai Pandar40P, 40 beams.
    Pandar40p,
    /// Hesai Pandar64, 64 beams.
    Pandar64,
    /// Hesai PandarQT64, 64 beams.
    PandarQt64,
    /// Hesai PandarQT128, 128 beams.
    PandarQt128,
    /// Hesai PandarXT16, 16 beams.
    PandarXt16,
    /// Hesai PandarXT32, 32 beams.
    PandarXt32,
    /// Hesai PandarXT32M, 32 beams.
    PandarXt32m,
    /// Hesai OT128 (Pandar128E4X), 128 beams.
    Ot128,
}

crate::named_enum!(Sensor, "sensor", [
    Vlp16 => "vlp16" ["vlp-16"] "Velodyne VLP-16, 16 beams",
    Vlp32c => "vlp32c" ["vlp-32c", "vlp32"] "Velodyne VLP-32C, 32 beams",
    Hdl32e => "hdl32e" ["hdl-32e", "hdl32"] "Velodyne HDL-32E, 32 beams (nuScenes)",
    Hdl64eS2 => "hdl64e-s2" ["hdl64e", "hdl-64e"] "Velodyne HDL-64E S2, 64 beams (KITTI)",
    Hdl64eS3 => "hdl64e-s3" [] "Velodyne HDL-64E S3, 64 beams",
    Vls128 => "vls128" ["vls-128"] "Velodyne VLS-128, 128 beams",
    Pandar40p => "pandar40p" [] "Hesai Pandar40P, 40 beams",
    Pandar64 => "pandar64" [] "Hesai Pandar64, 64 beams",
    PandarQt64 => "pandarqt64" ["qt64"] "Hesai PandarQT64, 64 beams",
    PandarQt128 => "pandarqt128" ["qt128"] "Hesai PandarQT128, 128 beams",
    PandarXt16 => "pandarxt16" ["xt16"] "Hesai PandarXT16, 16 beams",
    PandarXt32 => "pandarxt32" ["xt32"] "Hesai PandarXT32, 32 beams",
    PandarXt32m => "pandarxt32m" ["xt32m"] "Hesai PandarXT32M, 32 beams",
    Ot128 => "ot128" ["pandar128e4x"] "Hesai OT128 (Pandar128E4X), 128 beams",
]);

impl Sensor {
    /// The vendor's model name (`VLP-16`, `Pandar40P`).
    pub fn model(self) -> &'static str {
        match self {
            Sensor::Vlp16 => "VLP-16",
            Sensor::Vlp32c => "VLP-32C",
            Sensor::Hdl32e => "HDL-32E",
            Sensor::Hdl64eS2 => "HDL-64E S2",
            Sensor::Hdl64eS3 => "HDL-64E S3",
            Sensor::Vls128 => "VLS-128",
            Sensor::Pandar40p => "Pandar40P",
            Sensor::Pandar64 => "Pandar64",
            Sensor::PandarQt64 => "PandarQT64",
            Sensor::PandarQt128 => "PandarQT128",
            Sensor::PandarXt16 => "PandarXT16",
            Sensor::PandarXt32 => "PandarXT32",
            Sensor::PandarXt32m => "PandarXT32M",
            Sensor::Ot128 => "OT128",
        }
    }

    /// The built-in table: (file name, text).
    fn table(self) -> (&'static str, &'static str) {
        macro_rules! t {
            ($f:literal) => {
                ($f, include_str!(concat!("tables/", $f)))
            };
        }
        match self {
            Sensor::Vlp16 => t!("VLP16.yaml"),
            Sensor::Vlp32c => t!("VLP32.yaml"),
            Sensor::Hdl32e => t!("HDL32.yaml"),
            Sensor::Hdl64eS2 => t!("HDL64e_s2.yaml"),
            Sensor::Hdl64eS3 => t!("HDL64e_s3.yaml"),
            Sensor::Vls128 => t!("VLS128.yaml"),
            Sensor::Pandar40p => t!("Pandar40P.csv"),
            Sensor::Pandar64 => t!("Pandar64.csv"),
            Sensor::PandarQt64 => t!("PandarQT64.csv"),
            Sensor::PandarQt128 => t!("PandarQT128.csv"),
            Sensor::PandarXt16 => t!("PandarXT16.csv"),
            Sensor::PandarXt32 => t!("PandarXT32.csv"),
            Sensor::PandarXt32m => t!("PandarXT32M.csv"),
            Sensor::Ot128 => t!("Pandar128E4X.csv"),
        }
    }

    /// The sensor's nominal model.
    pub fn model_table(self) -> SensorModel {
        let (file, text) = self.table();
        let path = Path::new("(built-in)").join(file);
        let name = self.model().to_string();
        let parsed: Result<SensorModel> = if file.ends_with(".yaml") {
            velodyne::parse(text, &path, name)
        } else {
            hesai::parse(text, &path, name)
        };
        parsed.expect("the built-in tables parse (tested)")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_built_in_table_parses_with_its_beam_count() {
        let beams = [16, 32, 32, 64, 64, 128, 40, 64, 64, 128, 16, 32, 32, 128];
        assert_eq!(Sensor::ALL.len(), beams.len());
        for (&s, n) in Sensor::ALL.iter().zip(beams) {
            assert_eq!(s.model_table().beams(), n, "{s}");
        }
    }
}
