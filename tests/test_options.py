"""Option values: checked against their ranges (constructed, changed afterwards, or given as
flags), named by their flag in one line, and an option either acts or is refused."""

import dataclasses
import json
import re

import pytest

import colmap_powerline.pipeline as pipeline
from colmap_powerline.cli import main
from colmap_powerline.detect import DetectOptions
from colmap_powerline.options import OptionError, check_limits, validate
from colmap_powerline.results import OutputOptions, ReconstructionOptions
from colmap_powerline.wires import WiresOptions


def test_the_defaults_are_valid():
    validate(ReconstructionOptions())
    validate(OutputOptions())


@pytest.mark.parametrize(
    ("rule", "good", "bad"),
    [
        ("> 0", [1e-9, 5], [0, -1]),
        (">= 1", [1, 2], [0, 0.999]),
        ("[0, 1)", [0, 0.5], [1, -0.1]),
        ("(0, 20]", [20, 0.1], [0, 20.1]),
        ("0 or >= 3", [0, 3, 9], [1, 2, -5]),
        ("-1 or >= 1", [-1, 1], [0, -2]),
        ("1 or 2", [1, 2], [3, 0]),
    ],
)
def test_rules(rule, good, bad):
    @dataclasses.dataclass
    class Opt:
        x: float = 0.0

    Opt.LIMITS = {"x": rule}  # type: ignore[attr-defined]
    for v in good:
        check_limits(Opt(v))
    for v in bad:
        with pytest.raises(OptionError, match="^" + re.escape(f"x={v!r} but expected {rule}")):
            check_limits(Opt(v))


def test_nan_and_inf_are_refused_everywhere():
    for value in (float("nan"), float("inf")):
        with pytest.raises(OptionError, match="finite"):
            WiresOptions(max_gap=value)  # a field with a range
        with pytest.raises(OptionError, match="finite"):
            DetectOptions(min_component_length_px=value)  # an optional one


def test_a_value_changed_after_construction_is_caught_by_its_place():
    options = ReconstructionOptions()
    options.wires.sample_step = 0.0
    with pytest.raises(OptionError, match=r"^wires\.sample_step=0\.0 but expected > 0$"):
        validate(options)
    options = ReconstructionOptions()
    options.triangulate.max_wire_height = 3.0  # below min_wire_height: the check between fields
    with pytest.raises(OptionError, match=r"triangulate\.max_wire_height"):
        validate(options)


def test_reconstruct_checks_the_options_before_reading_anything(tmp_path):
    options = ReconstructionOptions()
    options.verify.num_threads = -3
    # The model does not exist: the option is refused first.
    with pytest.raises(OptionError, match=r"verify\.num_threads=-3"):
        pipeline.reconstruct(tmp_path, tmp_path / "nope", tmp_path / "out", options)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("flags", "named"),
    [
        (["--verify.tolerance_px", "nan"], "--verify.tolerance_px=nan but expected a finite"),
        (["--verify.num_threads", "-3"], "--verify.num_threads=-3 but expected >= 1"),
        (["--detect.template_length_px", "-5"], "--detect.template_length_px=-5 but expected"),
        (["--pairs.wire_azimuth_deg", "nan"], "--pairs.wire_azimuth_deg=nan"),
        (["--wires.sample_step", "0"], "--wires.sample_step=0.0 but expected > 0"),
        (["--triangulate.max_wire_height", "3"], "> min_wire_height (5.0)"),
        (["--support.min_confidence", "1"], "--support.min_confidence=1.0 but expected [0.5, 1)"),
        (["--spans.min_improvement", "0.5"], "--spans.min_improvement=0.5 but expected >= 1"),
        (["--min_clearance_m", "-1"], "--min_clearance_m=-1.0 but expected >= 0"),
        (["--alignment_max_error", "0"], "--alignment_max_error=0.0 but expected > 0"),
        (["--sfm.num_threads", "0"], "--sfm.num_threads=0 but expected -1 or >= 1"),
    ],
)
def test_cli_refuses_a_bad_value_in_one_line_naming_the_flag(tmp_path, capsys, flags, named):
    out = tmp_path / "out"
    out.mkdir()
    (out / "wires.json").write_text("{}")  # an earlier result stays as it was
    argv = ["--quiet", "reconstruct", "--image_path", str(tmp_path), "--input_path"]
    code = main([*argv, str(tmp_path / "nope"), "--output_path", str(out), *flags])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and named in err, err
    assert sorted(p.name for p in out.iterdir()) == ["wires.json"]
    assert json.loads((out / "wires.json").read_text()) == {}


@pytest.mark.parametrize(
    "flags",
    [
        ["--scale_m_per_unit", "2"],
        ["--ref_images_path", "refs.txt"],
        ["--sfm.max_num_features", "500"],
    ],
)
def test_cli_refuses_sfm_flags_that_would_not_act(tmp_path, capsys, flags):
    """With --input_path SfM does not run: its flags and the georeferencing flags would be
    ignored; they are refused in one line instead (an option acts or is refused)."""
    argv = ["--quiet", "reconstruct", "--image_path", str(tmp_path), "--input_path"]
    code = main([*argv, str(tmp_path / "model"), "--output_path", str(tmp_path / "out"), *flags])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and flags[0] in err and "only when SfM runs" in err, err
    assert not (tmp_path / "out").exists()


def test_cli_flags_come_from_the_options():
    """Every field of the options that a flag can carry has exactly one flag (the duplicate
    --wire_azimuth_deg is gone)."""
    from colmap_powerline.cli import build_parser

    rec = build_parser()._subparsers._group_actions[0].choices["reconstruct"]  # type: ignore[union-attr]
    flags = {s for a in rec._actions for s in a.option_strings}
    assert "--wire_azimuth_deg" not in flags and "--pairs.wire_azimuth_deg" in flags
    for name in ("--las", "--report", "--debug", "--dense_path", "--output_crs"):
        assert name in flags
    for stage in ("pairs", "verify", "wires", "spans", "trace", "support", "sfm"):
        cls = type(getattr(ReconstructionOptions(), stage))
        for f in dataclasses.fields(cls):
            if f.name == "show_progress":  # --quiet
                continue
            if f.type in ("bool", "int", "float", "str", "float | None", "int | None") or (
                f.name in ("polarity", "matching")
            ):
                assert f"--{stage}.{f.name}" in flags, f"--{stage}.{f.name}"


def test_a_bug_keeps_its_traceback(tmp_path, monkeypatch):
    """Only the tool's own input errors become one line: a ValueError from inside is a bug."""

    def broken(*args, **kwargs):
        raise ValueError("an internal bug")

    monkeypatch.setattr(pipeline, "reconstruct", broken)
    argv = ["--quiet", "reconstruct", "--image_path", str(tmp_path), "--input_path"]
    with pytest.raises(ValueError, match="an internal bug"):
        main([*argv, str(tmp_path), "--output_path", str(tmp_path / "out")])
