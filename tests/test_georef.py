"""Georeferencing: EXIF GPS, known positions, a known scale, projected CRSs."""

from __future__ import annotations

import json
import logging

import numpy as np
import pycolmap
import pyproj
import pytest

from colmap_powerline import InputError
from colmap_powerline.georef import (
    GeoreferenceOptions,
    enu_to_crs,
    enu_to_wgs84,
    georeference_model,
    read_georeference,
    utm_epsg,
    wgs84_to_enu,
)
from colmap_powerline.synthetic import read_exif_gps


def _arbitrary_frame(small_span) -> tuple[pycolmap.Reconstruction, dict[str, np.ndarray]]:
    """The true model moved into an SfM-like frame (scale 0.05, turned, shifted)."""
    rec = pycolmap.Reconstruction(small_span.sparse_gt)
    truth = {im.name: im.projection_center() for im in rec.images.values()}
    rot = pycolmap.Rotation3d(
        np.array([0.3, -0.2, 0.5, 0.8]) / np.linalg.norm([0.3, -0.2, 0.5, 0.8])
    )
    rec.transform(pycolmap.Sim3d(0.05, rot, np.array([3.0, -1.0, 7.0])))
    return rec, truth


def _origin(small_span) -> tuple[float, float, float]:
    return tuple(json.loads(small_span.truth_wires.read_text())["origin_wgs84"])


def test_exif_gps_puts_cameras_within_gps_noise(small_span, tmp_path):
    rec, truth = _arbitrary_frame(small_span)
    gps = {name: np.array(read_exif_gps(small_span.images / name)) for name in truth}
    georef = georeference_model(rec, gps, GeoreferenceOptions(origin_wgs84=_origin(small_span)))
    assert georef is not None and georef.source == "exif_gps"
    # Simulated GNSS: σ 1.5 m horizontal, 3 m vertical; 32 cameras average it down.
    err = np.array([rec.find_image_with_name(n).projection_center() - c for n, c in truth.items()])
    assert np.sqrt(np.mean(np.sum(err[:, :2] ** 2, axis=1))) < 1.5
    assert np.sqrt(np.mean(err[:, 2] ** 2)) < 3.0
    assert georef.scale == pytest.approx(20.0, rel=0.02)
    # Residuals are camera-vs-GPS: about the simulated noise.
    assert georef.num_inliers == georef.num_images == 32
    assert 0.8 < georef.rms_horizontal_m < 3.5 and 1.0 < georef.rms_vertical_m < 5.0
    # Distances inside the model are metric now.
    a, b = "DJI_0001.JPG", "DJI_0032.JPG"
    d = np.linalg.norm(
        rec.find_image_with_name(a).projection_center()
        - rec.find_image_with_name(b).projection_center()
    )
    assert d == pytest.approx(np.linalg.norm(truth[a] - truth[b]), rel=0.02)
    georef.write(tmp_path)
    back = read_georeference(tmp_path)
    assert back == georef
    assert "local ENU" in back.frame and "32/32" in back.summary()


def test_default_origin_is_the_cameras_mean_at_altitude_zero(small_span):
    rec, truth = _arbitrary_frame(small_span)
    gps = {name: np.array(read_exif_gps(small_span.images / name)) for name in truth}
    georef = georeference_model(rec, gps)
    lat, lon, alt = georef.origin_wgs84
    lla = np.array(list(gps.values()))
    assert (lat, lon, alt) == pytest.approx((lla[:, 0].mean(), lla[:, 1].mean(), 0.0))
    # z is then the height in the GPS datum: cameras sit at their GPS altitude.
    z = np.array([im.projection_center()[2] for im in rec.images.values()])
    assert np.median(z) == pytest.approx(np.median(lla[:, 2]), abs=2.0)


def test_known_positions_file_and_outliers(small_span, tmp_path):
    rec, truth = _arbitrary_frame(small_span)
    lines = [f"{n} {c[0]:.6f} {c[1]:.6f} {c[2]:.6f}" for n, c in truth.items()]
    lines[3] = lines[3].split()[0] + " 500 500 500  # a wrong position"
    ref = tmp_path / "positions.txt"
    ref.write_text("# name X Y Z\n" + "\n".join(lines) + "\n")
    georef = georeference_model(rec, {}, GeoreferenceOptions(ref_images_path=ref))
    assert georef.source == "ref_images" and georef.origin_wgs84 is None
    assert georef.num_inliers == 31 and georef.num_images == 32
    err = [
        np.linalg.norm(rec.find_image_with_name(n).projection_center() - c)
        for n, c in truth.items()
    ]
    assert np.median(err) < 1e-6


def test_known_positions_as_gps(small_span, tmp_path):
    rec, truth = _arbitrary_frame(small_span)
    origin = _origin(small_span)
    names = list(truth)
    lla = enu_to_wgs84(np.array([truth[n] for n in names]), origin)
    ref = tmp_path / "gps.txt"
    ref.write_text(
        "".join(f"{n} {a:.9f} {b:.9f} {c:.4f}\n" for n, (a, b, c) in zip(names, lla, strict=True))
    )
    opts = GeoreferenceOptions(ref_images_path=ref, ref_is_gps=True, origin_wgs84=origin)
    georef = georeference_model(rec, {}, opts)
    assert georef.origin_wgs84 == origin
    err = [
        np.linalg.norm(rec.find_image_with_name(n).projection_center() - truth[n]) for n in names
    ]
    assert np.max(err) < 1e-3


def test_scale_only_and_no_gps_warns(small_span, caplog):
    rec, truth = _arbitrary_frame(small_span)
    georef = georeference_model(rec, {}, GeoreferenceOptions(scale_m_per_unit=20.0))
    assert georef.source == "scale" and georef.scale == 20.0
    a, b = list(truth)[:2]
    d = np.linalg.norm(
        rec.find_image_with_name(a).projection_center()
        - rec.find_image_with_name(b).projection_center()
    )
    assert d == pytest.approx(np.linalg.norm(truth[a] - truth[b]), rel=1e-9)
    with caplog.at_level(logging.WARNING):
        assert georeference_model(rec, {}) is None
    assert "arbitrary units" in caplog.text


@pytest.mark.parametrize(
    ("content", "message"),
    [("img_0000.jpg 1 2\n", "positions.txt:1: expected"), ("a 1 2 3\nb 1 2 3\n", "only 0 of")],
)
def test_bad_positions_file_is_one_line(small_span, tmp_path, content, message):
    rec, _ = _arbitrary_frame(small_span)
    ref = tmp_path / "positions.txt"
    ref.write_text(content)
    with pytest.raises(InputError, match=message) as e:
        georeference_model(rec, {}, GeoreferenceOptions(ref_images_path=ref))
    assert "\n" not in str(e.value)


def test_enu_to_utm_and_back():
    origin = (41.036, -83.304, 0.0)  # Seneca, Ohio: UTM zone 17N
    assert utm_epsg(*origin[:2]) == 32617
    assert utm_epsg(-33.9, 18.4) == 32734
    xyz = np.array([[0.0, 0.0, 250.0], [100.0, 0.0, 250.0], [0.0, 100.0, 260.0]])
    utm, name = enu_to_crs(xyz, origin, "utm")
    assert "UTM zone 17N" in name
    ref = pyproj.Transformer.from_crs("EPSG:4326", "EPSG:32617", always_xy=True)
    e0, n0 = ref.transform(origin[1], origin[0])
    assert utm[0, :2] == pytest.approx([e0, n0], abs=1e-3)
    # Local distances survive up to UTM's scale factor (0.9996 … 1.0004).
    assert np.linalg.norm(utm[1, :2] - utm[0, :2]) == pytest.approx(100.0, rel=5e-4)
    assert utm[2, 2] == pytest.approx(260.0, abs=0.01)
    back = wgs84_to_enu(enu_to_wgs84(xyz, origin), origin)
    assert np.abs(back - xyz).max() < 1e-6
    with pytest.raises(InputError, match="not a projected CRS"):
        enu_to_crs(xyz, origin, "EPSG:4326")
    with pytest.raises(InputError, match="not a CRS"):
        enu_to_crs(xyz, origin, "EPSG:999999")


def test_las_crs_for_georeferenced_models():
    from colmap_powerline.georef import Georeference, crs_wkt

    g = Georeference("exif_gps", (41.036, -83.304, 0.0), 1.0, (0, 0, 0, 1), (0, 0, 0))
    assert "UTM zone 17N" in crs_wkt(g, "utm")
    local = pyproj.CRS.from_wkt(crs_wkt(g, None))
    assert local.is_projected and "Transverse Mercator" in local.to_wkt().replace("_", " ")
    # The local transverse Mercator matches the ENU frame (east/north) to < 1 mm at 500 m.
    xyz = np.array([[500.0, 300.0, 10.0], [-400.0, 200.0, 0.0]])
    lla = enu_to_wgs84(xyz, g.origin_wgs84)
    e, n = pyproj.Transformer.from_crs("EPSG:4326", local, always_xy=True).transform(
        lla[:, 1], lla[:, 0]
    )
    assert np.abs(np.c_[e, n] - xyz[:, :2]).max() < 1e-3
    assert crs_wkt(None, "utm") is None
    assert crs_wkt(Georeference("scale", None, 2.0, (0, 0, 0, 1), (0, 0, 0)), None) is None
