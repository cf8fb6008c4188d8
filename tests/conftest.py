"""Synthetic spans shared by the whole suite, rendered once per session."""

from __future__ import annotations

import pytest

from colmap_powerline import load_scene
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
