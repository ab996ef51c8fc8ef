"""Decodes one frame of an Ouster capture with the vendor's SDK (``ouster-sdk``) into an .npz:
``range`` (H, W) uint32 mm and ``reflectivity`` staggered, ``xyz`` (H, W, 3) float32 (the SDK's
points: the sensor frame, metres), and ``d_range`` / ``d_xyz`` destaggered (the image Ouster's
tools show); ``shift`` the pixel shift of each row (staggered column m of row u is destaggered
column (m + shift[u]) mod W).

Run by test_ouster.py with the Python of its own environment ($OUSTER_PYTHON, made by
tools/run-tests.sh): ouster-sdk pins versions (rosbags, flask, click) that the test environment
does not share. ``python ouster_decode.py META.json OUT.npz`` (the .pcap beside the .json).
"""

import pathlib
import sys

import numpy as np
from ouster.sdk import core, open_source


def main(meta: str, out: str) -> None:
    pcap = pathlib.Path(meta).with_suffix(".pcap")
    src = open_source(str(pcap), meta=[meta])
    info = src.sensor_info[0]
    frame = next(iter(src))[0]
    rng = frame.field(core.ChanField.RANGE)
    xyz = core.XYZLut(info)(frame).astype(np.float32)
    np.savez(out, range=rng, reflectivity=frame.field(core.ChanField.REFLECTIVITY),
             xyz=xyz, d_range=core.destagger(info, rng), d_xyz=core.destagger(info, xyz),
             shift=np.asarray(info.format.pixel_shift_by_row))


if __name__ == "__main__":
    main(*sys.argv[1:])
