"""The shared plan geometry (geometry.py) on hand-computed cases: the package's conventions
(azimuth clockwise from +y, across = along turned 90° clockwise, image directions in
[0, 180) with 90 = down)."""

from __future__ import annotations

import numpy as np
import pytest

from colmap_powerline.geometry import (
    across_of,
    axial_diff_deg,
    axial_mean_deg,
    azimuth_deg_of,
    crossing_views,
    image_axes,
    image_direction_deg,
    image_direction_of_azimuth,
    offsets_across,
    plan_axes,
)
from colmap_powerline.pairs import WireCorridor


@pytest.mark.parametrize(
    "azimuth,along,across",
    [
        (0.0, (0.0, 1.0), (1.0, 0.0)),  # north: across points east
        (90.0, (1.0, 0.0), (0.0, -1.0)),  # east: across points south
        (180.0, (0.0, -1.0), (-1.0, 0.0)),
        (45.0, (0.5**0.5, 0.5**0.5), (0.5**0.5, -(0.5**0.5))),
    ],
)
def test_plan_axes(azimuth, along, across):
    a, c = plan_axes(azimuth)
    np.testing.assert_allclose(a, along, atol=1e-15)
    np.testing.assert_allclose(c, across, atol=1e-15)
    assert abs(a @ c) < 1e-15
    np.testing.assert_array_equal(across_of(a), c)


def test_plan_axes_are_the_corridors():
    corridor = WireCorridor(
        azimuth_deg=35.0, centre_xy=np.zeros(2), half_width=20.0, wires_half_width=5.0,
        s_range=(-50.0, 50.0), height=20.0, height_range=(15.0, 25.0), from_images=True,
        measured=True,
    )  # fmt: skip
    along, across = plan_axes(35.0)
    np.testing.assert_array_equal(corridor.direction_xy, along)
    np.testing.assert_array_equal(corridor.normal_xy, across)


def test_azimuth_of_a_direction_is_axial():
    assert azimuth_deg_of([1.0, 0.0]) == pytest.approx(90.0)
    assert azimuth_deg_of([0.0, 1.0]) == 0.0
    assert azimuth_deg_of([-1.0, 0.0]) == pytest.approx(90.0)  # the same line
    assert azimuth_deg_of([-1.0, -1.0]) == pytest.approx(45.0)
    assert azimuth_deg_of([-1.0, -1.0], axial=False) == pytest.approx(-135.0)
    for az in (0.0, 12.5, 90.0, 179.0):
        assert azimuth_deg_of(plan_axes(az)[0]) == pytest.approx(az)


def test_axial_differences_wrap_at_180():
    assert axial_diff_deg(10.0, 190.0) == pytest.approx(0.0)
    assert axial_diff_deg(5.0, 175.0) == pytest.approx(10.0)
    assert axial_diff_deg(0.0, 90.0) == pytest.approx(90.0)
    assert axial_diff_deg(-30.0, 30.0) == pytest.approx(60.0)
    np.testing.assert_allclose(axial_diff_deg([0.0, 100.0], 179.0), [1.0, 79.0])


def test_axial_mean_joins_directions_across_0():
    mean = axial_mean_deg(np.array([178.0, 2.0]), np.ones(2))
    assert axial_diff_deg(mean, 0.0) < 1e-9  # (180.0 here: a tiny negative mean, mod 180)
    assert axial_mean_deg(np.array([10.0, 190.0, 20.0]), np.array([1.0, 1.0, 2.0])) == (
        pytest.approx(15.0, abs=0.01)
    )


def test_image_directions():
    assert image_direction_deg(np.array([[10.0, 10.0], [10.0, 30.0]])) == 90.0  # going down
    assert image_direction_deg(np.array([[10.0, 30.0], [10.0, 10.0]])) == 90.0  # up: the same
    assert image_direction_deg(np.array([[0.0, 0.0], [-5.0, 0.0]])) == 0.0
    assert image_direction_deg(np.array([[0.0, 0.0], [1.0, -1.0]])) == pytest.approx(135.0)
    along, across = image_axes(90.0)
    np.testing.assert_allclose(along, [0.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(across, [-1.0, 0.0], atol=1e-15)
    assert image_direction_deg(np.stack([np.zeros(2), image_axes(30.0)[0]])) == (
        pytest.approx(30.0)
    )


def test_image_direction_of_an_azimuth_seen_from_above():
    # A nadir camera with image x east and y south: north-east (45°) runs up and right on
    # the image, 135° in image directions; east runs along +x.
    def project(pts):
        return np.c_[pts[:, 0], -pts[:, 1]] * 10.0

    centre = np.array([3.0, 4.0, 20.0])
    assert image_direction_of_azimuth(project, centre, 45.0) == pytest.approx(135.0)
    assert image_direction_of_azimuth(project, centre, 90.0) == pytest.approx(0.0)
    assert image_direction_of_azimuth(project, centre, 0.0) == pytest.approx(90.0)


def test_offsets_across_a_line():
    # A line through (1, 1) going east: across points south, so north is negative.
    xy = np.array([[5.0, 1.0], [1.0, 3.0], [-2.0, -1.0]])
    np.testing.assert_allclose(offsets_across(xy, np.array([1.0, 1.0]), np.array([1.0, 0.0])),
                               [0.0, -2.0, 2.0])  # fmt: skip


def test_crossing_views_need_an_offset_from_both_pair_cameras():
    # Wires running north (azimuth 0), cameras 50 above them: 0.2 × 50 = 10 m needed across.
    pair = np.array([[[0.0, 0.0, 50.0], [0.0, 30.0, 50.0]], [[0.0, 0.0, 50.0], [12.0, 0.0, 50.0]]])
    views = np.array([[0.0, 100.0, 50.0], [11.0, -40.0, 50.0], [-20.0, 5.0, 50.0]])
    can = crossing_views(views, pair, 0.0, 50.0, 0.2)
    # Pair 0 (along the wires): the view along them cannot tell, those 11 and 20 m off can.
    # Pair 1 (across): the view at 11 m is 1 m from its second camera.
    np.testing.assert_array_equal(can, [[False, True, True], [False, False, True]])
