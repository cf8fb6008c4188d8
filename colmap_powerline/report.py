"""``OUT/report/``: figures a person looks at, and an HTML page that links them.

- ``plan.png``: the whole survey in plan: the wires over the ground points, coloured by
  height, and the supports found (towers and poles, by kind, numbered).
- ``span_<line>_<span>.png``: per span, every wire of it over the distance along the span,
  the ground under it, the supports at its ends and its lowest clearance.
- ``profile_<id>.png``: per wire, its height and the ground below it along the span, the
  clearance, the chord and the sag, and the stretches below ``min_clearance_m`` in red.
- ``pair_<k>.png``: the left image of each pair (decoded at a reduced size), with the wire
  centres the pair's detection found there (kept by the pipeline, not detected again) and
  the final wires projected onto it.
- ``cameras.png``: camera positions, the chosen pairs and the wire corridor.
"""

from __future__ import annotations

import html
import logging
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .files import wire_colors, write_atomic  # noqa: E402
from .geometry import plan_axes  # noqa: E402

if TYPE_CHECKING:
    from .results import ReconstructionOptions, ReconstructionResult
    from .scene import GroundModel

logger = logging.getLogger(__name__)


def _rgb(wire_id: int) -> tuple[float, float, float]:
    c = wire_colors(np.array([wire_id]))[0] / 255.0
    return float(c[0]), float(c[1]), float(c[2])


def _save(fig: plt.Figure, path: Path) -> Path:
    def write(tmp: Path) -> None:
        fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")

    write_atomic(path, write)
    plt.close(fig)
    return path


def _finish_plan(ax: plt.Axes, units: str, title: str) -> None:
    """Equal-scale east/north axes with units, a title and a light grid."""
    ax.set_aspect("equal")
    ax.set_xlabel(f"east ({units})")
    ax.set_ylabel(f"north ({units})")
    ax.set_title(title)
    ax.grid(alpha=0.3)


def _plan(result: ReconstructionResult, units: str, path: Path) -> Path:
    scene = result.scene
    fig, ax = plt.subplots(figsize=(9, 8))
    pts = scene.pts_in_world
    all_xy = (
        np.concatenate([w.polyline(1.0)[:, :2] for w in result.wires])
        if result.wires
        else pts[:, :2]
    )
    lo, hi = all_xy.min(axis=0) - 25, all_xy.max(axis=0) + 25
    near = np.all((pts[:, :2] >= lo) & (pts[:, :2] <= hi), axis=1)
    sc = ax.scatter(pts[near, 0], pts[near, 1], c=pts[near, 2], s=2, cmap="terrain", alpha=0.6)
    fig.colorbar(sc, ax=ax, label=f"sparse point height ({units})", shrink=0.7)
    for w, m in zip(result.wires, result.measures, strict=True):
        p = w.polyline(0.5)
        ax.plot(
            p[:, 0],
            p[:, 1],
            "-",
            color=_rgb(w.wire_id),
            lw=2.2,
            label=f"wire {w.wire_id} ({m.kind})",
        )
        ax.annotate(str(w.wire_id), p[0, :2], fontsize=9, fontweight="bold")
        for f in m.flagged:
            ax.plot(*f.lowest_clearance_point[:2], "rx", ms=10, mew=2)
    marks = {
        "suspension": ("s", "suspension"),
        "angle": ("D", "angle"),
        "junction": ("*", "junction"),
        "end": ("^", "end"),
    }
    for kind, (marker, label) in marks.items():
        sup = [t for t in result.line_supports if t.kind == kind]
        if sup:
            xy = np.array([t.position[:2] for t in sup])
            ax.plot(xy[:, 0], xy[:, 1], marker, ms=11, mfc="none", mec="k", mew=2,
                    label=f"{label} support")  # fmt: skip
            for t in sup:
                ax.annotate(f"S{t.support_id}", t.position[:2], xytext=(8, -12),
                            textcoords="offset points", fontsize=9)  # fmt: skip
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    lines = len({p.line for p in result.placement}) if result.placement else 1
    _finish_plan(
        ax,
        units,
        f"{len(result.wires)} wires of {lines} line(s), {len(result.line_supports)} supports "
        "(plan view)",
    )
    if result.wires:
        ax.legend(loc="best", fontsize=8, ncol=2)
    return _save(fig, path)


def _span_profile(
    result: ReconstructionResult,
    key: tuple[int, int],
    units: str,
    path: Path,
    ground_model: GroundModel | None = None,
) -> Path:
    """All the wires of one span (``key`` = (line, span)) in one profile: each conductor's
    catenary over the distance along the span from its first support, the ground under the
    span's axis, the supports at its ends (up to their highest attachment), and the lowest
    clearance of the span."""
    ks = [k for k, p in enumerate(result.placement) if (p.line, p.span) == key]
    ids = {i for k in ks for i in result.placement[k].supports if i is not None}
    sups = [s for s in result.line_supports if s.support_id in ids]
    polys = [result.wires[k].polyline(0.5) for k in ks]
    ends = np.concatenate([p[[0, -1], :2] for p in polys])
    if len(sups) == 2:
        origin, far = sups[0].position[:2], sups[1].position[:2]
    else:
        origin, far = ends[0], ends[int(np.argmax(np.linalg.norm(ends - ends[0], axis=1)))]
    along = (far - origin) / max(float(np.linalg.norm(far - origin)), 1e-9)
    s_all = np.concatenate([(p[:, :2] - origin) @ along for p in polys])
    if s_all.min() < -0.5 * np.ptp(s_all):  # the far end first: walk from the other one
        along = -along
    fig, ax = plt.subplots(figsize=(11, 4.6))
    lo_s = min(0.0, float(min(((p[:, :2] - origin) @ along).min() for p in polys)))
    hi_s = max(float(((p[:, :2] - origin) @ along).max()) for p in polys)
    s_axis = np.linspace(lo_s, hi_s, 400)
    ground = (ground_model or result.scene.ground).height(origin + s_axis[:, None] * along)
    ax.fill_between(s_axis, ground.min() - 2, ground, color="0.85", label="ground")
    ax.plot(s_axis, ground, color="0.4", lw=1)
    lowest = (np.inf, -1)
    for k, poly in zip(ks, polys, strict=True):
        w, m = result.wires[k], result.measures[k]
        ax.plot(
            (poly[:, :2] - origin) @ along,
            poly[:, 2],
            color=_rgb(w.wire_id),
            lw=1.8,
            label=f"wire {w.wire_id} ({m.kind}, sag {m.sag_max_m:.2f})",
        )
        lowest = min(lowest, (m.clearance_vertical_m, w.wire_id))
    for sup in sups:
        at = float((sup.position[:2] - origin) @ along)
        ax.vlines(at, sup.position[2], sup.top_z, color="k", lw=3, alpha=0.6)
        ax.annotate(
            f"support {sup.support_id} ({sup.kind})",
            (at, sup.top_z),
            xytext=(0, 4),
            textcoords="offset points",
            ha="center",
            fontsize=8,
        )
    top = max(max(float(p[:, 2].max()) for p in polys), max((s.top_z for s in sups), default=0))
    ax.set_ylim(ground.min() - 1, top + 0.12 * (top - ground.min()))
    ax.set_xlabel(f"distance along the span from its first support ({units})")
    ax.set_ylabel(f"height ({units})")
    ax.set_title(
        f"line {key[0]}, span {key[1]}: {len(ks)} wires, lowest clearance {lowest[0]:.2f} "
        f"{units} (wire {lowest[1]})"
    )
    ax.legend(loc="lower right", fontsize=7, ncol=2)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def _profile(
    result: ReconstructionResult,
    k: int,
    units: str,
    limit: float | None,
    path: Path,
    ground_model: GroundModel | None = None,
) -> Path:
    w, m = result.wires[k], result.measures[k]
    lo, hi = w.s_range
    s_plane = np.linspace(lo, hi, 800)
    poly = w.points(s_plane)
    s = s_plane - lo
    ground = (ground_model or result.scene.ground).height(poly[:, :2])
    fig, ax = plt.subplots(figsize=(10, 4.2))
    ax.fill_between(s, ground.min() - 2, ground, color="0.8", label=f"ground ({m.ground_source})")
    ax.plot(s, ground, color="0.4", lw=1)
    ax.plot(s, poly[:, 2], color=_rgb(w.wire_id), lw=2.2, label=f"wire {w.wire_id} (catenary)")
    ax.plot([s[0], s[-1]], [poly[0, 2], poly[-1, 2]], "k--", lw=0.8, label="chord")
    ax.vlines(
        m.sag_max_at_m,
        poly[:, 2].min() - 0.05,
        poly[0, 2] + (poly[-1, 2] - poly[0, 2]) * m.sag_max_at_m / max(s[-1], 1e-9),
        color="k",
        lw=1,
    )
    ax.annotate(
        _sag_label(result, k, units),
        (m.sag_max_at_m, poly[:, 2].max()),
        ha="center",
        va="bottom",
        fontsize=9,
    )
    kv = int(np.argmin(np.abs(s - m.clearance_vertical_at_m)))
    ax.annotate(
        "",
        (s[kv], ground[kv]),
        (s[kv], poly[kv, 2]),
        arrowprops={"arrowstyle": "<->", "color": "tab:blue"},
    )
    ax.annotate(
        f"clearance {m.clearance_vertical_m:.2f} {units}",
        (s[kv], 0.5 * (ground[kv] + poly[kv, 2])),
        xytext=(6, 0),
        textcoords="offset points",
        color="tab:blue",
        fontsize=9,
    )
    for j, f in enumerate(m.flagged):
        ax.axvspan(
            f.s_start_m,
            f.s_end_m,
            color="red",
            alpha=0.25,
            label=f"closer than {limit:g} {units}" if j == 0 else None,
        )
    labelled: set[bool] = set()
    for g in result.coverage[k].gaps if k < len(result.coverage) else ():
        label = (
            "not measurable from these images"
            if g.flight_limited
            else "not measured (the catenary spans it)"
        )
        ax.axvspan(
            g.from_m,
            g.to_m,
            color="tab:orange" if g.flight_limited else "0.5",
            alpha=0.2,
            hatch="//",
            label=None if g.flight_limited in labelled else label,
        )
        labelled.add(g.flight_limited)
    ax.set_xlabel(f"distance along the wire from its first end ({units})")
    ax.set_ylabel(f"height ({units})")
    ax.set_title(
        f"wire {w.wire_id} ({m.kind}): span {m.span_length_m:.1f} {units}, sag "
        f"{m.sag_max_m:.2f} {units}, lowest clearance {m.clearance_vertical_m:.2f} {units}"
    )
    ax.set_ylim(ground.min() - 1, poly[:, 2].max() + 0.15 * (poly[:, 2].max() - ground.min()))
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def _reduced_grey(path: Path, width: int, target_px: int = 1600) -> tuple[np.ndarray, int]:
    """The image decoded in grey at 1/2, 1/4 or 1/8 of its size (libjpeg scales while it
    decodes: a fraction of a full decode), about ``target_px`` wide; and the factor."""
    import cv2

    from .scene import read_image

    flags = {1: cv2.IMREAD_GRAYSCALE, 2: cv2.IMREAD_REDUCED_GRAYSCALE_2}
    flags |= {4: cv2.IMREAD_REDUCED_GRAYSCALE_4, 8: cv2.IMREAD_REDUCED_GRAYSCALE_8}
    factor = max((f for f in flags if width / f >= target_px), default=1)
    return read_image(path, flags[factor]), factor


def _pair_overlay(result: ReconstructionResult, k: int, path: Path) -> Path:
    """The left image of pair ``k`` with the wire centres its detection found (kept by the
    pipeline: nothing is detected again) and every wire projected."""
    view = result.pairs[k].left
    grey, _ = _reduced_grey(view.path, view.width)
    found = result.primitives[k].left_wire_px if k < len(result.primitives) else None
    fig, ax = plt.subplots(figsize=(12, 9))
    ax.imshow(grey, cmap="gray", extent=(0, view.width, view.height, 0))
    if found is not None and len(found):
        ax.scatter(
            found[:, 0],
            found[:, 1],
            s=0.2,
            c="gold",
            alpha=0.35,
            label="wire centres found (rectified rows)",
            linewidths=0,
        )
    for w in result.wires:
        uv, _, ok = view.project(w.polyline(0.2))
        ax.plot(
            uv[ok, 0],
            uv[ok, 1],
            "-",
            color=_rgb(w.wire_id),
            lw=2.5,
            alpha=0.9,
            label=f"wire {w.wire_id}",
        )
    ax.set_xlim(0, view.width)
    ax.set_ylim(view.height, 0)
    ax.set_xlabel("image column (px)")
    ax.set_ylabel("image row (px)")
    p = result.pairs[k]
    ax.set_title(
        f"pair {k}: {p.left.name} (with {p.right.name}), crossing {p.crossing_deg:.0f}°, "
        f"B/H {p.base_height:.2f}"
    )
    ax.legend(loc="upper right", fontsize=8, markerscale=20)
    return _save(fig, path)


def _cameras(result: ReconstructionResult, units: str, path: Path) -> Path:
    centres = result.scene.centers_in_world
    fig, ax = plt.subplots(figsize=(8, 8))
    ax.plot(centres[:, 0], centres[:, 1], "o", color="0.5", ms=4, label="camera positions")
    for k, p in enumerate(result.pairs):
        a, b = p.left.center_in_world, p.right.center_in_world
        ax.plot([a[0], b[0]], [a[1], b[1]], "-", lw=2, label=f"pair {k}")
    cor = result.corridor
    d, n = plan_axes(cor.azimuth_deg)
    s0, s1 = cor.s_range
    box = [
        cor.centre_xy + s * d + c * n
        for s, c in (
            (s0, -cor.half_width),
            (s1, -cor.half_width),
            (s1, cor.half_width),
            (s0, cor.half_width),
            (s0, -cor.half_width),
        )
    ]
    box_a = np.array(box)
    ax.plot(box_a[:, 0], box_a[:, 1], "k--", lw=1, label=f"wire corridor ({cor.azimuth_deg:.1f}°)")
    for w in result.wires:
        line = w.polyline(1.0)
        ax.plot(line[:, 0], line[:, 1], "-", color=_rgb(w.wire_id), lw=1)
    _finish_plan(ax, units, "camera positions and the chosen crossing pairs")
    ax.legend(loc="best", fontsize=8)
    return _save(fig, path)


def _sag_label(result: ReconstructionResult, k: int, units: str) -> str:
    """Wire ``k``'s sag, said to come from its curve where it was not measured where it
    sags most (:meth:`WireCoverage.measured_at`)."""
    from .results import sag_from_curve

    label = f"sag {result.measures[k].sag_max_m:.2f} {units}"
    return label + (" (from its curve: not measured there)" if sag_from_curve(result, k) else "")


def _measured(result: ReconstructionResult, k: int) -> str:
    """The table cell: measured share and longest gap of wire ``k``."""
    if k >= len(result.coverage):
        return ""
    cov = result.coverage[k]
    gap = f" (gap {cov.longest_gap_m:.1f})" if cov.gaps else ""
    return f"{100 * cov.measured_share:.0f} %{gap}"


def _agreement(result: ReconstructionResult, k: int) -> str:
    """The table cell: how far wire ``k``'s pairs' points lie from its traced points."""
    if k >= len(result.coverage) or result.coverage[k].disagreement_m is None:
        return "–"
    return f"{result.coverage[k].disagreement_m:.3f}"


def _where(result: ReconstructionResult, k: int) -> str:
    if not result.placement:
        return ""
    p = result.placement[k]
    return f"{p.line} / {p.span} / {p.conductor}"


def _supports_table(result: ReconstructionResult, units: str) -> str:
    """The supports found: where, how high, what kind, and from what."""
    if not result.line_supports:
        return "<p>No support found (the wires end where the images end).</p>"
    rows = "".join(
        f"<tr><td>S{t.support_id}</td><td>{', '.join(str(n) for n in t.lines)}</td>"
        f"<td>{t.kind}</td>"
        f"<td>{t.position[0]:.2f}</td><td>{t.position[1]:.2f}</td>"
        f"<td>{t.top_z - t.position[2]:.2f}</td><td>{t.turn_deg:.1f}</td>"
        f"<td>{len(t.wire_ids)}</td><td>{t.found_by}</td></tr>"
        for t in result.line_supports
    )
    return (
        "<h2>Supports</h2><table><tr><th>support</th><th>line</th><th>kind</th>"
        f"<th>east ({units})</th><th>north ({units})</th><th>highest attachment above "
        "ground</th><th>turn (°)</th><th>wires</th><th>found by</th></tr>"
        f"{rows}</table><p>Found by: <i>kink</i>, a wire measured across the support bends "
        "there; <i>pieces meeting</i>, one conductor's curves in the two spans meet there; "
        "<i>wires ending</i>, the wires end together where the images see past them (the "
        "position is where the measurements end, short of the tower by its insulators at "
        "most); <i>wires turning</i>, an angle support where the wires end and the images "
        "show them going on turned (its next leg not measured); <i>cross-arm</i>, the "
        "images show a pole's cross-arm under the wires there; <i>spans crossing</i>, an "
        "angle support: where each conductor's spans on the two legs cross in plan.</p>"
    )


def write_report(
    result: ReconstructionResult,
    output_path: Path,
    options: ReconstructionOptions,
    metric: bool,
    ground: GroundModel | None = None,
) -> Path:
    """Render every figure and ``index.html`` into ``output_path / "report"``."""
    out = Path(output_path) / "report"
    out.mkdir(parents=True, exist_ok=True)
    units = "m" if metric else "units"
    figures: list[tuple[str, Path]] = [
        ("Plan view", _plan(result, units, out / "plan.png")),
        ("Camera positions and pairs", _cameras(result, units, out / "cameras.png")),
    ]
    for line, span in sorted({(p.line, p.span) for p in result.placement}):
        figures.append(
            (
                f"Line {line}, span {span}: profile",
                _span_profile(result, (line, span), units, out / f"span_{line}_{span}.png", ground),
            )
        )
    for k in range(len(result.wires)):
        figures.append(
            (
                f"Wire {result.wires[k].wire_id} profile",
                _profile(
                    result, k, units, options.min_clearance_m, out / f"profile_{k}.png", ground
                ),
            )
        )
    for k in range(len(result.pairs)):
        figures.append(
            (
                f"Pair {k}: detections and wires",
                _pair_overlay(result, k, out / f"pair_{k}.png"),
            )
        )
    rows = "".join(
        f"<tr><td>{w.wire_id}</td><td>{_where(result, k)}</td><td>{m.kind}</td>"
        f"<td>{m.span_length_m:.2f}</td>"
        f"<td>{m.sag_max_m:.3f}</td><td>{m.sag_midspan_m:.3f}</td>"
        f"<td>{m.clearance_vertical_m:.2f}</td><td>{m.clearance_3d_m:.2f}</td>"
        f"<td>{len(m.flagged)}</td><td>{len(w.point_indices)}</td><td>{w.rms_residual:.3f}</td>"
        f"<td>{_measured(result, k)}</td><td>{_agreement(result, k)}</td></tr>"
        for k, (w, m) in enumerate(zip(result.wires, result.measures, strict=True))
    )
    limit = (
        f"<p>Stretches closer than {options.min_clearance_m:g} {units} to the ground are "
        "flagged in red.</p>"
        if options.min_clearance_m is not None
        else ""
    )
    imgs = "".join(
        f'<h2>{html.escape(t)}</h2><a href="{p.name}"><img src="{p.name}" '
        f'style="max-width:100%"></a>'
        for t, p in figures
    )
    page = (
        "<!doctype html><html><head><meta charset='utf-8'><title>colmap-powerline report</title>"
        "<style>body{font-family:sans-serif;max-width:1200px;margin:auto}"
        "td,th{padding:3px 8px;text-align:right}</style></head><body>"
        f"<h1>Wires of {html.escape(str(result.scene.image_path))}</h1>"
        f"<p>{len(result.wires)} wires from {len(result.verified)} verified points, "
        f"{len(result.pairs)} pairs, {len(result.scene)} images. Units: {units}.</p>{limit}"
        f"{_supports_table(result, units)}"
        "<table><tr><th>wire</th><th>line / span / conductor</th><th>kind</th><th>span</th>"
        "<th>sag max</th><th>sag mid</th>"
        "<th>clearance vertical</th><th>clearance 3D</th><th>flagged</th><th>points</th>"
        f"<th>fit RMS</th><th>measured</th><th>pairs vs traced</th></tr>{rows}</table>"
        "<p>Measured: the share of the wire between its ends that its measured points cover, "
        "and its longest unmeasured stretch (hatched in the profiles; orange where these "
        "images cannot measure it, with what to fly in the log and in <code>wires.json</code>). "
        "Pairs vs traced: how far the pairs' points lie from the points traced in every view "
        "near them (median): the wire's position is uncertain by about that much."
        f"</p>{imgs}</body></html>"
    )
    index = write_atomic(out / "index.html", lambda p: p.write_text(page))
    logger.info("report: %s (%d figures)", index, len(figures))
    return index
