"""Pieces of a run on Dask workers: the same results, in the same order, as in this process."""

from __future__ import annotations

import dataclasses
import filecmp
import json
import logging
import operator
import socket

import numpy as np
import pytest

from colmap_powerline import OptionError
from colmap_powerline.cli import main
from colmap_powerline.pairs import PairsOptions, select_pairs
from colmap_powerline.pipeline import ReconstructionOptions, primitives_for_pairs, probe_corridor
from colmap_powerline.tasks import ExecutionOptions, Tasks, tasks_for
from colmap_powerline.trace import TraceOptions

AZIMUTH = 35.0  # the small span's wires (conftest)
# These tests are about where the work runs, not what it finds: the faint-wire sweep (half of
# a small-span run, and it finds nothing there) is left out; test_faint covers it.
NO_SWEEP = TraceOptions(faint=False)


def test_tasks_keep_the_order_here_and_on_dask():
    here = Tasks().map(operator.mul, [3, 1, 2], 10)
    assert here == [30, 10, 20]
    with tasks_for(ExecutionOptions(workers=2)) as tasks:
        assert tasks.distributed
        assert tasks.map(operator.mul, list(range(20)), 10) == [10 * k for k in range(20)]
    with tasks_for(ExecutionOptions()) as tasks:
        assert not tasks.distributed


def test_execution_options_are_checked():
    with pytest.raises(OptionError, match="workers"):
        ExecutionOptions(workers=-1)


def test_pairs_on_dask_workers_are_the_same_as_here(small_scene, caplog):
    """The same primitives, and the same log, in the pairs' order: what a task logs on a
    worker is logged where the run is."""
    options = ReconstructionOptions(
        pairs=PairsOptions(wire_azimuth_deg=AZIMUTH, max_pairs=3), show_progress=False
    )
    corridor = probe_corridor(small_scene, options)
    pairs = select_pairs(small_scene, corridor, options.pairs)
    caplog.set_level(logging.INFO, logger="colmap_powerline")
    caplog.clear()
    here, decoded_here = primitives_for_pairs(small_scene, pairs, corridor, options)
    log_here = [r.getMessage() for r in caplog.records if r.name.endswith("pipeline")]
    with tasks_for(ExecutionOptions(workers=2)) as tasks:
        caplog.clear()
        there, decoded_there = primitives_for_pairs(small_scene, pairs, corridor, options, tasks)
        log_there = [r.getMessage() for r in caplog.records if r.name.endswith("pipeline")]
    assert len(log_here) == len(pairs) and log_here[0].startswith("pair 0 ")
    assert log_there == log_here
    assert decoded_here == decoded_there
    assert [p.pair_index for p in there] == list(range(len(pairs)))
    for a, b in zip(here, there, strict=True):
        assert len(a) > 0
        np.testing.assert_array_equal(a.pts_in_world, b.pts_in_world)
        np.testing.assert_array_equal(a.left_wire_px, b.left_wire_px)


def test_lines_as_tasks_are_the_same_as_here(small_scene):
    """Several lines on Dask workers: one task each, the same wires as here, and the pairs
    refer to the scene's own images again."""
    from colmap_powerline.pipeline import _reconstruct_corridors

    options = ReconstructionOptions(
        pairs=PairsOptions(wire_azimuth_deg=AZIMUTH, max_pairs=2), trace=NO_SWEEP,
        show_progress=False,
    )  # fmt: skip
    corridor = probe_corridor(small_scene, options)
    here = _reconstruct_corridors(small_scene, [corridor, corridor], options, {}, None)
    with tasks_for(ExecutionOptions(workers=2)) as tasks:
        there = _reconstruct_corridors(small_scene, [corridor, corridor], options, {}, tasks)
    assert len(here) == len(there) == 2
    for a, b in zip(here, there, strict=True):
        assert len(a.wires) > 0 and len(a.wires) == len(b.wires)
        np.testing.assert_array_equal(a.verified.pts_in_world, b.verified.pts_in_world)
        for wa, wb in zip(a.wires, b.wires, strict=True):
            np.testing.assert_array_equal(wa.point_indices, wb.point_indices)
        assert all(p.left is small_scene.images[small_scene.images.index(p.left)] for p in b.pairs)


def _cli(small_span, out, *more):
    return main(
        [
            "--quiet",
            "reconstruct",
            "--image_path",
            str(small_span.images),
            "--input_path",
            str(small_span.sparse),
            "--output_path",
            str(out),
            "--pairs.wire_azimuth_deg",
            str(AZIMUTH),
            "--pairs.max_pairs",
            "3",
            "--trace.faint",
            "false",
            *more,
        ]
    )


def test_a_run_on_two_workers_writes_the_same_outputs(small_span, tmp_path):
    assert _cli(small_span, tmp_path / "here") == 0
    assert _cli(small_span, tmp_path / "dask", "--workers", "2") == 0
    for name in ("wires.csv", "supports.csv", "wire_points.ply", "wires.ply"):
        assert filecmp.cmp(tmp_path / "here" / name, tmp_path / "dask" / name, shallow=False), name
    here, dask = (json.loads((tmp_path / d / "wires.json").read_text()) for d in ("here", "dask"))
    assert here["wires"] and here["wires"] == dask["wires"]


def test_a_scheduler_that_is_not_there_is_one_line(small_span, tmp_path, capsys):
    with socket.socket() as s:  # a local port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    code = _cli(small_span, tmp_path / "out", "--scheduler", f"tcp://127.0.0.1:{port}")
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no Dask scheduler at" in err[0], err
    assert not (tmp_path / "out" / "wires.json").exists()


def _run(small_span, out, execution=None, **changed):
    from colmap_powerline.pipeline import reconstruct

    options = ReconstructionOptions(
        pairs=PairsOptions(wire_azimuth_deg=AZIMUTH, max_pairs=2), trace=NO_SWEEP,
        show_progress=False,
    )  # fmt: skip
    if changed:
        options = dataclasses.replace(options, **changed)
    return reconstruct(small_span.images, small_span.sparse, out, options, None, execution)


def test_a_finished_run_leaves_no_pieces(small_span, tmp_path):
    out = tmp_path / "out"
    assert _run(small_span, out).wires
    assert (out / "wires.json").exists() and not (out / ".pieces").exists()


def test_an_interrupted_run_keeps_what_it_finished(small_span, tmp_path, monkeypatch):
    """Ctrl-C while a line is reconstructed: the corridors found before are kept, no
    output is written; started again, the run does not probe again (unless --redo or
    another option), and once its outputs are written its pieces go."""
    import colmap_powerline.pipeline as pipeline

    out = tmp_path / "out"
    real = pipeline.reconstruct_corridor

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(pipeline, "reconstruct_corridor", interrupted)
    with pytest.raises(KeyboardInterrupt):
        _run(small_span, out)
    assert not (out / "wires.json").exists()
    (kept,) = (out / ".pieces").iterdir()
    assert [p.name for p in kept.iterdir()] == ["corridors.pkl"]

    def never(*args, **kwargs):
        raise AssertionError("probed again")

    # --redo, or another option, probes again.
    monkeypatch.setattr(pipeline, "probe_corridors", never)
    with pytest.raises(AssertionError, match="probed again"):
        _run(small_span, out, ExecutionOptions(redo=True))
    with pytest.raises(AssertionError, match="probed again"):
        _run(small_span, out, min_clearance_m=3.0)
    # The same run: the corridors are taken, the line is done, the outputs written, and
    # the pieces go.
    monkeypatch.setattr(pipeline, "reconstruct_corridor", real)
    result = _run(small_span, out)
    assert result.wires and (out / "wires.json").exists()
    assert not (out / ".pieces").exists()
    images = {id(v) for v in result.scene.images}
    assert all(id(p.left) in images and id(p.right) in images for p in result.pairs)


def _tiled(**changed):
    """Options that cut the small span's line into tiles of about one image footprint."""
    return ReconstructionOptions(
        pairs=PairsOptions(wire_azimuth_deg=AZIMUTH, max_pairs=2),
        trace=NO_SWEEP,
        tile_footprints=1.0,
        show_progress=False,
        **changed,
    )


def test_a_long_line_is_cut_into_tiles(small_scene):
    """Tiles cover the line end to end, each core once; each tile reads only the images
    that see its stretch; their number does not depend on the workers."""
    from colmap_powerline.pairs import footprint_along
    from colmap_powerline.pipeline import line_tiles

    options = _tiled()
    corridor = probe_corridor(small_scene, options)
    tiles = line_tiles(small_scene, corridor, 0, options)
    assert len(tiles) >= 2
    assert tiles[0].core[0] == -np.inf and tiles[-1].core[1] == np.inf
    for a, b in zip(tiles, tiles[1:], strict=False):
        assert a.core[1] == b.core[0]
    footprint = footprint_along(small_scene, corridor)
    names = {v.name for v in small_scene.images}
    for t in tiles:
        lo, hi = t.corridor.s_range
        assert lo >= corridor.s_range[0] and hi <= corridor.s_range[1]
        assert (
            hi - lo <= (corridor.s_range[1] - corridor.s_range[0]) / len(tiles) + footprint + 1e-6
        )
        assert t.views and set(t.views) < names
    assert len({t.name for t in tiles}) == len(tiles)
    # The whole line is one tile at the default (the span is a few footprints long).
    assert len(line_tiles(small_scene, corridor, 0, ReconstructionOptions())) == 1


def test_tiles_on_dask_workers_are_the_same_as_here(small_scene):
    """The tiles of a line as tasks: the same wires as in this process, the pieces of a
    wire that a tile's end cut joined again."""
    from colmap_powerline.pipeline import _reconstruct_corridors, line_tiles

    options = _tiled()
    corridor = probe_corridor(small_scene, options)
    tiles = line_tiles(small_scene, corridor, 0, options)
    (here,) = _reconstruct_corridors(small_scene, [corridor], options, {}, None)
    with tasks_for(ExecutionOptions(workers=2)) as tasks:
        (there,) = _reconstruct_corridors(small_scene, [corridor], options, {}, tasks)
    assert len(here.wires) >= 4 and len(here.wires) == len(there.wires)
    np.testing.assert_array_equal(here.verified.pts_in_world, there.verified.pts_in_world)
    for a, b in zip(here.wires, there.wires, strict=True):
        np.testing.assert_array_equal(a.point_indices, b.point_indices)
    # A wire runs across the first tile's end: its pieces were joined into one.
    cut = tiles[0].core[1]
    along = [
        (here.verified.pts_in_world[w.point_indices, :2] - corridor.centre_xy)
        @ corridor.direction_xy
        for w in here.wires
    ]
    assert any(s.min() < cut - 5 and s.max() > cut + 5 for s in along)


def test_an_interrupted_tiled_run_redoes_only_the_tiles_it_had_not_finished(
    small_span, tmp_path, monkeypatch
):
    """Ctrl-C in the second tile: the first is kept; started again, it is not redone."""
    import colmap_powerline.pipeline as pipeline
    from colmap_powerline.pipeline import reconstruct

    out = tmp_path / "out"
    real = pipeline.reconstruct_corridor
    calls = []

    def second_interrupted(*args, **kwargs):
        calls.append(args[1].s_range)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(pipeline, "reconstruct_corridor", second_interrupted)
    with pytest.raises(KeyboardInterrupt):
        reconstruct(small_span.images, small_span.sparse, out, _tiled())
    (kept,) = (out / ".pieces").iterdir()
    names = sorted(p.name for p in kept.iterdir())
    assert names[0] == "corridors.pkl" and len(names) == 2
    assert names[1].startswith("line_0_tile_0_")
    # Started again: the tile done is taken, only the others run.
    calls.clear()

    def counted(*args, **kwargs):
        calls.append(args[1].s_range)
        return real(*args, **kwargs)

    monkeypatch.setattr(pipeline, "reconstruct_corridor", counted)
    result = reconstruct(small_span.images, small_span.sparse, out, _tiled())
    n_tiles = len(pipeline.line_tiles(result.scene, result.corridors[0], 0, _tiled()))
    assert len(calls) == n_tiles - 1
    assert result.wires and not (out / ".pieces").exists()
