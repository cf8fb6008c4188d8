"""Put a model into metres: GPS from EXIF, known camera positions, or a known scale.

Sag and clearance mean nothing in SfM's arbitrary units. :func:`georeference_model` moves a
model into a local east-north-up frame (metres, WGS84 ellipsoid, z = height in the GPS's
vertical datum) by a robust similarity from its camera centres to their GPS positions,
using pycolmap's RANSAC alignment. The frame's WGS84 origin, the similarity and the
residuals of every camera are kept in a :class:`Georeference` and written as
``georef.json`` next to the model, so later runs (and ``wires.json``) can state where the
coordinates are. :func:`enu_to_crs` converts local coordinates into a projected CRS (e.g.
the UTM zone) with pyproj.

Without GPS the model is only up to scale: a warning says so once, and a known scale
(``scale_m_per_unit``) or a file of known camera positions (``ref_images_path``, one line
``name X Y Z`` per image, or ``name lat lon alt`` with ``ref_is_gps``) can be given instead.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt
import pycolmap

from .errors import InputError
from .options import check_limits

logger = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]
GEOREF_FILE = "georef.json"


@dataclass(kw_only=True)
class GeoreferenceOptions:
    """How a model is put into metres (see the module docstring)."""

    use_gps: bool = True  # align to EXIF GPS when at least min_images images have it
    origin_wgs84: tuple[float, float, float] | None = None  # (lat, lon, alt); None: the
    # cameras' mean latitude/longitude at altitude 0, so z is a height in the GPS datum
    max_error_m: float = 10.0  # RANSAC inlier distance (consumer GNSS: σ ≈ 1.5 m h, 3 m v)
    min_images: int = 3  # fewer positions than this: no alignment
    ref_images_path: Path | None = None  # known camera positions, one "name X Y Z" per line
    ref_is_gps: bool = False  # ref_images_path holds "name lat lon alt" (WGS84) instead
    scale_m_per_unit: float | None = None  # known scale for a model without GPS
    random_seed: int = 0

    LIMITS: ClassVar[dict[str, str]] = {
        "max_error_m": "> 0",
        "min_images": ">= 3",
        "scale_m_per_unit": "> 0",
        "random_seed": ">= 0",
    }

    def __post_init__(self) -> None:
        check_limits(self)


@dataclass
class Georeference:
    """How a model was put into metres.

    Attributes:
        source: ``exif_gps``, ``ref_images`` or ``scale``.
        origin_wgs84: (lat, lon, alt) of the local ENU frame's origin, None when the frame
            is metric but not geographic (known XYZ positions or a scale).
        scale, rotation_xyzw, translation: the applied similarity (new = s R old + t).
        num_images: positions used; num_inliers: those within ``max_error_m``.
        rms_horizontal_m, rms_vertical_m, max_error_m: residuals of the camera centres
            against their positions after the alignment (inliers).
        residuals_m: per image name, (east, north, up) residual.
    """

    source: str
    origin_wgs84: tuple[float, float, float] | None
    scale: float
    rotation_xyzw: tuple[float, float, float, float]
    translation: tuple[float, float, float]
    num_images: int = 0
    num_inliers: int = 0
    rms_horizontal_m: float = 0.0
    rms_vertical_m: float = 0.0
    max_error_m: float = 0.0
    residuals_m: dict[str, tuple[float, float, float]] = field(default_factory=dict)

    @property
    def frame(self) -> str:
        if self.origin_wgs84 is not None:
            lat, lon, alt = self.origin_wgs84
            return f"local ENU (WGS84) at lat {lat:.7f}, lon {lon:.7f}, alt {alt:.2f} m"
        return "metric (known positions)" if self.source == "ref_images" else "metric (scale)"

    def summary(self) -> str:
        if self.source == "scale":
            return f"model scaled by {self.scale:.6g} m per unit"
        return (
            f"georeferenced by {self.source} into {self.frame}: {self.num_inliers}/"
            f"{self.num_images} cameras within tolerance, residual RMS "
            f"{self.rms_horizontal_m:.2f} m horizontal, {self.rms_vertical_m:.2f} m vertical "
            f"(max {self.max_error_m:.2f} m), scale {self.scale:.4g}"
        )

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        d["frame"] = self.frame
        return d

    def write(self, model_path: Path) -> Path:
        path = Path(model_path) / GEOREF_FILE
        path.write_text(json.dumps(self.to_json(), indent=1))
        return path


def read_georeference(model_path: Path | str) -> Georeference | None:
    """The ``georef.json`` next to a model, or None when the model has none."""
    path = Path(model_path) / GEOREF_FILE
    if not path.exists():
        return None
    try:
        d = json.loads(path.read_text())
        d.pop("frame", None)
        for key in ("origin_wgs84", "rotation_xyzw", "translation"):
            if d.get(key) is not None:
                d[key] = tuple(d[key])
        d["residuals_m"] = {k: tuple(v) for k, v in d.get("residuals_m", {}).items()}
        return Georeference(**d)
    except (ValueError, TypeError) as e:
        raise InputError(f"{path}: not a valid georeference file ({e})") from None


def _gps() -> pycolmap.GPSTransform:
    return pycolmap.GPSTransform(pycolmap.GPSTransformEllipsoid.WGS84)


def wgs84_to_enu(lat_lon_alt: F64, origin: tuple[float, float, float]) -> F64:
    """(N, 3) WGS84 latitude, longitude (degrees), altitude (m) → local ENU metres."""
    return np.asarray(_gps().ellipsoid_to_enu(np.asarray(lat_lon_alt, float), *origin))


def enu_to_wgs84(xyz: F64, origin: tuple[float, float, float]) -> F64:
    """(N, 3) local ENU metres → WGS84 latitude, longitude (degrees), altitude (m)."""
    return np.asarray(_gps().enu_to_ellipsoid(np.asarray(xyz, float).reshape(-1, 3), *origin))


def utm_epsg(lat: float, lon: float) -> int:
    """EPSG code of the WGS84 UTM zone that holds (lat, lon)."""
    zone = int(math.floor((lon + 180) / 6)) % 60 + 1
    return (32600 if lat >= 0 else 32700) + zone


def _projected_crs(crs: str, origin: tuple[float, float, float]) -> Any:
    """The pyproj CRS named by ``crs`` (``"utm"``: the zone of ``origin``), checked to be
    projected."""
    import pyproj

    if crs.lower() == "utm":
        crs = f"EPSG:{utm_epsg(origin[0], origin[1])}"
    try:
        target = pyproj.CRS.from_user_input(crs)
    except pyproj.exceptions.CRSError as e:
        raise InputError(f"output CRS {crs!r}: not a CRS pyproj knows ({e})") from None
    if not target.is_projected:
        raise InputError(f"output CRS {crs!r}: not a projected CRS (metres east/north needed)")
    return target


def crs_converter(origin: tuple[float, float, float], crs: str) -> tuple[Callable[[F64], F64], str]:
    """(local ENU metres → ``crs`` function, the CRS's name); the transformer is built once.

    Heights stay heights in the GPS's vertical datum (no geoid is applied).
    """
    import pyproj

    target = _projected_crs(crs, origin)
    tf = pyproj.Transformer.from_crs("EPSG:4326", target, always_xy=True)

    def convert(xyz: F64) -> F64:
        lla = enu_to_wgs84(xyz, origin)
        east, north = tf.transform(lla[:, 1], lla[:, 0])
        return np.c_[east, north, lla[:, 2]]

    return convert, f"{target.name} ({target.to_string()})"


def enu_to_crs(xyz: F64, origin: tuple[float, float, float], crs: str) -> tuple[F64, str]:
    """Local ENU metres → a projected CRS (``"utm"`` picks the zone), and the CRS's name."""
    convert, name = crs_converter(origin, crs)
    return convert(xyz), name


def read_ref_images(path: Path) -> dict[str, F64]:
    """Known camera positions: one ``name X Y Z`` (or ``name lat lon alt``) per line."""
    if not path.is_file():
        raise InputError(f"{path}: camera position file does not exist")
    out = {}
    for k, line in enumerate(path.read_text().splitlines(), 1):
        parts = line.split("#", 1)[0].split()
        if not parts:
            continue
        try:
            if len(parts) != 4:
                raise ValueError
            out[parts[0]] = np.array([float(v) for v in parts[1:]])
        except ValueError:
            raise InputError(
                f"{path}:{k}: expected 'image_name X Y Z', got {line.strip()!r}"
            ) from None
    return out


def _align(
    rec: pycolmap.Reconstruction, positions: dict[str, F64], opts: GeoreferenceOptions, source: str
) -> pycolmap.Sim3d:
    registered = {im.name for im in rec.images.values() if im.has_pose}
    names = [n for n in positions if n in registered]
    if len(names) < opts.min_images:
        raise InputError(
            f"{source}: only {len(names)} of the model's images have a known position "
            f"(at least {opts.min_images} are needed)"
        )
    ransac = pycolmap.RANSACOptions()
    ransac.max_error = opts.max_error_m
    ransac.random_seed = opts.random_seed
    sim = pycolmap.align_reconstruction_to_locations(
        rec, names, np.array([positions[n] for n in names]), opts.min_images, ransac
    )
    if sim is None:
        raise InputError(
            f"{source}: the camera positions do not fit the model by a similarity within "
            f"{opts.max_error_m} m (wrong positions, or a broken model)"
        )
    return sim


def _residuals(
    rec: pycolmap.Reconstruction, positions: dict[str, F64], max_error_m: float
) -> tuple[dict[str, tuple[float, float, float]], int, float, float, float]:
    res = {}
    for im in rec.images.values():
        if im.has_pose and im.name in positions:
            res[im.name] = tuple(float(v) for v in im.projection_center() - positions[im.name])
    r = np.array(list(res.values()))
    inl = np.linalg.norm(r, axis=1) <= max_error_m
    h = float(np.sqrt(np.mean(np.sum(r[inl, :2] ** 2, axis=1)))) if inl.any() else math.nan
    v = float(np.sqrt(np.mean(r[inl, 2] ** 2))) if inl.any() else math.nan
    return res, int(inl.sum()), h, v, float(np.linalg.norm(r, axis=1).max())


def georeference_model(
    rec: pycolmap.Reconstruction,
    gps_lat_lon_alt: dict[str, F64],
    options: GeoreferenceOptions | None = None,
) -> Georeference | None:
    """Move ``rec`` (in place) into metres; None (and one warning) when nothing says how.

    Known positions (``ref_images_path``) win over EXIF GPS, which wins over a known scale.
    """
    opts = options or GeoreferenceOptions()
    origin: tuple[float, float, float] | None = None
    if opts.ref_images_path is not None:
        source = "ref_images"
        positions = read_ref_images(Path(opts.ref_images_path))
        if opts.ref_is_gps:
            origin = opts.origin_wgs84 or _default_origin(positions)
            positions = _to_enu(positions, origin)
        label = str(opts.ref_images_path)
    elif opts.use_gps and len(gps_lat_lon_alt) >= opts.min_images:
        source = "exif_gps"
        origin = opts.origin_wgs84 or _default_origin(gps_lat_lon_alt)
        positions = _to_enu(gps_lat_lon_alt, origin)
        label = "EXIF GPS"
    elif opts.scale_m_per_unit is not None:
        s = float(opts.scale_m_per_unit)
        if not s > 0:
            raise InputError(f"scale_m_per_unit must be positive, got {s}")
        rec.transform(pycolmap.Sim3d(s, pycolmap.Rotation3d(), np.zeros(3)))
        return Georeference("scale", None, s, (0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.0))
    else:
        logger.warning(
            "the images have no GPS and no scale was given: the model and every result "
            "(heights, sag, clearance) are in SfM's arbitrary units, not metres. Give "
            "--scale_m_per_unit or --ref_images_path to fix the scale."
        )
        return None
    sim = _align(rec, positions, opts, label)
    rec.transform(sim)
    res, n_inl, rms_h, rms_v, worst = _residuals(rec, positions, opts.max_error_m)
    q = np.asarray(sim.rotation.quat, float)
    return Georeference(
        source,
        origin,
        float(sim.scale),
        tuple(q.tolist()),
        tuple(np.asarray(sim.translation, float).tolist()),
        num_images=len(res),
        num_inliers=n_inl,
        rms_horizontal_m=rms_h,
        rms_vertical_m=rms_v,
        max_error_m=worst,
        residuals_m=res,
    )


def _default_origin(lat_lon_alt: dict[str, F64]) -> tuple[float, float, float]:
    a = np.array(list(lat_lon_alt.values()))
    return float(a[:, 0].mean()), float(a[:, 1].mean()), 0.0


def _to_enu(lat_lon_alt: dict[str, F64], origin: tuple[float, float, float]) -> dict[str, F64]:
    names = list(lat_lon_alt)
    enu = wgs84_to_enu(np.array([lat_lon_alt[n] for n in names]), origin)
    return dict(zip(names, enu, strict=True))


def crs_wkt(georef: Georeference | None, output_crs: str | None) -> str | None:
    """WKT of the CRS the outputs are written in, for LAS headers; None when not geographic.

    With ``output_crs`` that CRS. In the local ENU frame itself: a transverse Mercator
    centred on the frame's origin on WGS84, which matches ENU east/north to < 1 mm within
    1 km of the origin (heights stay ENU heights, within 1 cm of ellipsoidal heights
    inside 350 m of it).
    """
    if georef is None or georef.origin_wgs84 is None:
        return None
    return frame_wkt(georef.origin_wgs84, output_crs)


def frame_wkt(origin: tuple[float, float, float], output_crs: str | None) -> str:
    """:func:`crs_wkt` for the local ENU frame at ``origin`` (lat, lon, alt)."""
    import pyproj

    lat, lon, _ = origin
    if output_crs:
        return _projected_crs(output_crs, origin).to_wkt()
    local = (
        f"+proj=tmerc +lat_0={lat} +lon_0={lon} +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs"
    )
    return pyproj.CRS.from_proj4(local).to_wkt()
