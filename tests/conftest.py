"""One small synthetic span shared by the whole suite (rendered once per session, ~10 s)."""

from __future__ import annotations

import pytest

from colmap_powerline import load_scene
from colmap_powerline.synthetic import SyntheticSpanOptions, generate_span


@pytest.fixture(scope="session")
def small_span(tmp_path_factory):
    """1000x750 px, vegetation, four strips across the line (32 images)."""
    return generate_span(
        tmp_path_factory.mktemp("span") / "span",
        SyntheticSpanOptions(scale=0.25, show_progress=False),
    )


@pytest.fixture(scope="session")
def small_scene(small_span):
    """The true model of the small span."""
    return load_scene(small_span.sparse_gt, small_span.images)


@pytest.fixture(scope="session")
def medium_span(tmp_path_factory):
    """2000x1500 px (wire GSD 4.4 cm), vegetation, across flight: the end-to-end check."""
    return generate_span(
        tmp_path_factory.mktemp("span_medium") / "span",
        SyntheticSpanOptions(scale=0.5, show_progress=False),
    )
