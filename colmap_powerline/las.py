"""LAS 1.4 output through laspy, classified as ASPRS expects.

Classes (ASPRS LAS 1.4 standard): 1 unclassified, 2 ground, 13 wire – guard (shield wire),
14 wire – conductor (phase), 15 transmission tower. Every point also carries the extra
dimension ``wire_id`` (−1 where it is not on a wire). Coordinates are stored with a 1 mm
scale and an offset at the data's minimum, so the precision is a millimetre everywhere.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import laspy
import numpy as np
import numpy.typing as npt

from .files import write_atomic

UNCLASSIFIED, GROUND, SHIELD_WIRE, CONDUCTOR, TOWER = 1, 2, 13, 14, 15
WIRE_CLASS = {"conductor": CONDUCTOR, "shield": SHIELD_WIRE}

F64 = npt.NDArray[np.float64]


def las_header(offset: F64, crs_wkt: str | None) -> laspy.LasHeader:
    header = laspy.LasHeader(point_format=7, version="1.4")  # 7: xyz, RGB, GPS time
    header.add_extra_dim(laspy.ExtraBytesParams(name="wire_id", type=np.int32))
    header.scales = np.array([0.001, 0.001, 0.001])
    header.offsets = np.floor(np.asarray(offset, np.float64))
    if crs_wkt:
        import pyproj

        header.add_crs(pyproj.CRS.from_wkt(crs_wkt))
    return header


def _record(
    header: laspy.LasHeader,
    xyz: F64,
    classification: npt.NDArray[np.integer],
    wire_id: npt.NDArray[np.integer],
    rgb: npt.NDArray[np.uint8] | None,
) -> laspy.ScaleAwarePointRecord:
    rec = laspy.ScaleAwarePointRecord.zeros(len(xyz), header=header)
    rec.x, rec.y, rec.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    rec.classification = np.asarray(classification, np.uint8)
    rec.wire_id = np.asarray(wire_id, np.int32)
    if rgb is not None:
        rgb16 = np.asarray(rgb, np.uint16) * 257  # LAS colours are 16 bit
        rec.red, rec.green, rec.blue = rgb16[:, 0], rgb16[:, 1], rgb16[:, 2]
    return rec


def write_las(
    path: Path | str,
    chunks: Iterable[tuple[F64, npt.NDArray, npt.NDArray, npt.NDArray[np.uint8] | None]],
    offset: F64,
    crs_wkt: str | None = None,
) -> Path:
    """Write (xyz, classification, wire_id, rgb or None) chunks as one LAS 1.4 file,
    streaming, atomically."""

    def write(tmp: Path) -> None:
        header = las_header(offset, crs_wkt)
        with laspy.open(tmp, mode="w", header=header) as out:
            for xyz, cls, wid, rgb in chunks:
                if len(xyz):
                    out.write_points(_record(header, np.asarray(xyz, np.float64), cls, wid, rgb))

    return write_atomic(path, write)
