//! Reading a scan as its conversion did: the one path from a file to points in the sensor's
//! frame with their beam rows, for `convert`, `check`, `unproject`, `score`, `preview` and the
//! Python module alike.

use std::path::Path;

use super::params::{BeamRowsOf, SensorParams};
use crate::error::Result;
use crate::source::Scan;

/// Reads the scan at `path` as a conversion with `sensor` does: its `.bin` records in the
/// declared layout (`--fields`), and with a sensor its points moved into the sensor's frame
/// (those then beyond the range limit dropped, as the readers drop them) and the beam row (and
/// Ouster column) of every point ([`SensorParams::beam_rows`]). Without a sensor: KITTI's
/// HDL-64E, the scan as the file holds it (its rows come from the scan order).
pub fn read_scan(sensor: Option<&SensorParams>, path: &Path) -> Result<(Scan, Option<BeamRowsOf>)> {
    let layout = sensor.map(SensorParams::layout).transpose()?.flatten();
    let scan = crate::source::read_file(path, layout.as_ref())?;
    prepare_scan(sensor, scan, path)
}

/// A scan read elsewhere (a bag's message: `what` names it) made what [`read_scan`] makes of a
/// file: with a sensor, its points in the sensor's frame and every point's beam row.
pub fn prepare_scan(
    sensor: Option<&SensorParams>,
    mut scan: Scan,
    what: &Path,
) -> Result<(Scan, Option<BeamRowsOf>)> {
    if let Some(pose) = sensor.and_then(|s| s.pose) {
        // The range limit holds in the sensor's frame: points the pose carries past it go.
        pose.to_sensor_frame(&mut scan.points);
        scan.drop_beyond_range();
    }
    let beams = sensor
        .map(|s| s.beam_rows(&scan.points, scan.ring.as_deref(), what))
        .transpose()?;
    Ok((scan, beams))
}
