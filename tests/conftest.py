"""Synthetic spans shared by the whole suite, rendered once per session."""

from __future__ import annotations

import cv2
import numpy as np
import pycolmap
import pytest

from colmap_powerline import load_scene
from colmap_powerline.scene import SceneImage
from colmap_powerline.synthetic import SyntheticSpanOptions, generate_span


@pytest.fixture(scope="session")
def small_span(tmp_path_factory):
    """The default span at scale 0.25 (~10 s on 2 cores).

    1000 x 750 px OPENCV camera, vegetation background and the default flight: four strips
    across the line, 32 images, with images/, sparse_gt/, sparse/0/ and truth/.
    """
    return generate_span(
        tmp_path_factory.mktemp("span") / "span",
        SyntheticSpanOptions(scale=0.25, show_progress=False),
    )


@pytest.fixture(scope="session")
def small_scene(small_span):
    """The true model of the small span, loaded with its images."""
    return load_scene(small_span.sparse_gt, small_span.images)


@pytest.fixture(scope="session")
def medium_span(tmp_path_factory):
    """2000x1500 px (wire GSD 4.4 cm), vegetation, across flight: the end-to-end check."""
    return generate_span(
        tmp_path_factory.mktemp("span_medium") / "span",
        SyntheticSpanOptions(scale=0.5, show_progress=False),
    )


def write_fused_ply(path, xyz, rgb=None):
    """A dense cloud exactly as COLMAP's stereo_fusion writes fused.ply: binary little
    endian, float x y z nx ny nz, uchar red green blue."""
    from colmap_powerline.dense import FUSED_PLY_DTYPE
    from colmap_powerline.files import ply_header

    pts = np.zeros(len(xyz), FUSED_PLY_DTYPE)
    pts["x"], pts["y"], pts["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    pts["nz"] = 1.0
    if rgb is not None:
        pts["red"], pts["green"], pts["blue"] = rgb[:, 0], rgb[:, 1], rgb[:, 2]
    with open(path, "wb") as f:
        f.write(ply_header(FUSED_PLY_DTYPE, len(pts)))
        f.write(pts.tobytes())
    return path


@pytest.fixture(scope="session")
def medium_dense(medium_span, tmp_path_factory):
    """A dense cloud of the medium span's true terrain (0.25 m grid, 2 cm noise, no wires),
    as dense matching would give it: the ground for clearance and the cloud to fill."""
    from colmap_powerline.synthetic import Terrain

    terrain = Terrain.load(medium_span.terrain)
    x, y = np.meshgrid(np.arange(-70, 70, 0.25), np.arange(-70, 70, 0.25))
    xy = np.c_[x.ravel(), y.ravel()]
    z = terrain.height(xy) + np.random.default_rng(1).normal(0, 0.02, len(xy))
    rgb = np.full((len(xy), 3), 90, np.uint8)
    return write_fused_ply(tmp_path_factory.mktemp("dense") / "fused.ply", np.c_[xy, z], rgb)


@pytest.fixture
def nadir_view(tmp_path):
    """A 400 × 300 px nadir view 50 m above the origin (f = 1000 px; world x is image u, world
    y image −v) of a given image, written to a file."""

    def make(image):
        path = tmp_path / "nadir.png"
        cv2.imwrite(str(path), image)
        h, w = image.shape[:2]
        camera = pycolmap.Camera(
            model="PINHOLE", width=w, height=h, params=[1000, 1000, w / 2, h / 2], camera_id=1
        )
        rot = np.diag([1.0, -1.0, -1.0])
        return SceneImage(1, "nadir.png", path, camera, rot, -rot @ np.array([0.0, 0.0, 50.0]))

    return make
