"""Measuring confirmed wires in every view: guided multi-image matching along the curve.

The pairs' primitives reach only where one pair's two images both see a wire, and where
few other views see it a true primitive cannot become sure on its own: a confirmed wire's
points then have gaps, and stop short of where the images still see it (on the shared
generator's flight across the line, the points reach 57–94 % of each conductor while the
curve through them reaches 77–100 %).

Once a wire is confirmed its curve predicts where every view sees it. Along the curve, every
``step_px`` pixels of the view nearest to it, each view that sees the place looks for the
wire centre within ``reach_px`` of the projection, across the wire's direction in that view
(the verification's line template and its sub-pixel peak). Beside another wire's image
(within the response's reach) both lines are fitted at once: the response across them is
taken as the sum of two copies of the view's own line profile, measured on its lone places
(:func:`_line_profile`, :func:`_joint_offsets`), where the two lie farther apart than that
profile's core is wide and this line stands above the detector's contrast threshold on its
own; nearer, or where the view has too few lone places to measure its profile, the search
stops a pixel clear of the other line's response, and a view where it cannot is not asked
there (:func:`_beside_others`). A view whose two-line fit puts a centre there, strong on
its own, counts among the views that would fix the place; one whose fit does not, or whose
search was narrowed, adds its measurement (where it has one) without counting, since beside
another line not finding this one is no evidence that it is absent. A wire centre found at image
offset ``o`` says that the wire point lies on the plane through the camera and that image
line: one linear equation in the two unknown offsets of the point across the wire's tangent.
Two views offset across the wires fix both; more views are redundant, and the one that
disagrees most (a neighbouring wire, a road marking) is dropped while any disagrees by more
than the verification's tolerance. A point is kept where at least three views agree (two
fix it, the third checks it) and its predicted precision — from the geometry of those views
and the image noise measured on the redundant points themselves — is within
``WiresOptions.inlier_distance / 2.33``. On a confirmed wire, a point only two views fix is
kept where it lies on the wire's curve within their joint error, wherever the curve is
known that well: the curve is the check (:func:`_checked_by_curve`). Between a wire's
measured ends the curve also fixes what views of one strip, whose rays meet at a narrow
angle, leave loose along their rays: there the views and the curve are combined. Views
along the wires from one strip give nearly the same plane and cannot fix a point: only their
combination with views offset across the wire does.

Each view's offset on each wire (its pose error, how the wire looks there) is estimated from
the places the other views check and removed. On a wire the views find (its traced share), a
response peak above the detector's contrast threshold counts as the wire centre (the curve
is the evidence the detector's length filter gives elsewhere), and between the wire's
measured ends also a peak where the median of its and its neighbours' responses along the
curve over a few template lengths stands out; on the others only the detector's wire pixels
do. The wires are refitted to their measured and traced points, and traced again past their
new ends, ``extend`` at a time, while the views keep finding them there, no farther along
the line than the measured wires reach (or, once the supports are found, than the ``limits``
of each wire's span). In a round past the ends, the wires whose ends have stopped are
context: their images still narrow the search beside them (without, a shield traced on past
where the conductors had stopped ran 50 m on beside them, 28 cm off, on the shared
generator's flight across the line, seed 6), but for where one lies on the wire traced on
(another piece of it). A round's points past an end that leave the curve continued by more
than ``MAX_BEND`` standard errors (the fit's own, from its residuals, and the points';
across the wire also how far its vertical plane, continued as far, leaves its own confirmed
points at its ends: a wire the wind blew out of the vertical bows in plan) are dropped and
that end stops: past a support the next span's wire bends away or the line turns, and
clutter a peak test took does not follow a catenary. "While the views keep finding them"
means at no less than ``MIN_EXTEND_SHARE`` of the rate at which they find the wire along its
confirmed stretch: a round whose end they find less often is dropped and that end stops (a
field's rows along the line give chance agreements at a few places, and those do follow a
curve, refitted to them). Where a round past an end finds that fewer than three views see
the wire at all (an area survey's strips see a shield in stretches 5-20 m apart), nothing
says the wire ends there: the next round looks on from where that one looked, while the
curve continued predicts the wire where it looks to the precision a point must have.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import cv2
import numpy as np
import numpy.typing as npt
from scipy.ndimage import median_filter
from scipy.spatial import cKDTree
from scipy.stats import chi2

from .detect import DetectOptions, contrast_threshold
from .geometry import across_of, plan_axes
from .options import check_limits
from .scene import Scene, SceneImage, read_image
from .verify import (
    WireMaskFn,
    _projection_jacobian,
    _roughly_in_view,
    _wire_offsets,
    image_wire_direction_deg,
    samples_across,
)
from .wires import FittedWire, WiresOptions, catenary_mid, refit

logger = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]
F32 = npt.NDArray[np.float32]
I64 = npt.NDArray[np.int64]


# Views that must agree on a traced point: two fix it, a third checks it (a view that
# found a tower member or a road line instead of the wire is dropped only when others agree).
MIN_VIEWS = 3

# A wire not confirmed by the support check is traced with every view checked by the others:
# its redundancy number (1 − its leverage) at least this (a view with less is all but alone
# in fixing some direction of the point: two views of one strip along the wire and one of
# another, with which a false pairing of two strips passes). On wires already confirmed
# that would cost a third of some wires' points on the shared area survey, and is not asked.
MIN_REDUNDANCY = 0.2

# A view's offset on a wire is estimated from at least this many places the others check.
MIN_BIAS_PLACES = 20

# A confirmed wire that the views which would fix it find at fewer than this share of its
# places is dropped (strict detection). On the shared generator's flight across and area
# survey the true wires are found at 59-100 % of those places, the false pairings at none.
MIN_TRACED_SHARE = 0.2

# A round's points past an end that leave the wire's curve, continued, by more than this many
# standard errors (its fit's and theirs) are not the wire's: a support, with the next span's
# wire bending away, or clutter the looser test took. They are dropped and that end stops.
# On the shared generator's single spans the true extensions stay within 3.8 (one round of a
# shield piece on the area survey: 7.1); on the real road flight (poles every ~65 m) the
# rounds past a pole reach 5-13.
MAX_BEND = 4.0

# A wire's traced share is judged on at least this many places where the views would fix it
# (a metre of wire at the half-scale GSD).
MIN_MEASURABLE_PLACES = 10

# A round past an end goes on (and its points count) only where the views found the wire at
# no less than this share of the rate at which they find it along its confirmed stretch, at
# the places they would fix: a wire runs on as it was, while clutter that a peak test takes
# (a ploughed field's rows beside and along the line) is found at a few places in each round.
MIN_EXTEND_SHARE = 0.5


@dataclass(kw_only=True)
class TraceOptions:
    enabled: bool = True  # measure the confirmed wires in every view that sees them
    step_px: float = 2.5  # spacing of the traced places, in pixels of the nearest view
    reach_px: float = 3.0  # the wire centre is searched this far either side of the curve
    extend: float = 5.0  # then past the wire's ends by this much per round (model units)
    max_rounds: int = 20  # at most this many rounds past the ends
    loose: bool = True  # within the stretch confirmed, of a wire the views find, take a
    # response peak that stands out as the wire centre (no length filter)
    faint: bool = True  # sweep each line's cross-section for wires too faint for the
    # detector, by the line evidence of all views together (colmap_powerline.faint)
    faint_min_z: float = 6.0  # a hypothesis of the sweep is traced where its evidence is
    # this many of the sweep's robust standard deviations
    stretch_min_z: float = 4.0  # a span-wire's unmeasured stretch next to a measured one is
    # measured where the views' line evidence together stands this many robust standard
    # deviations out of the offsets around it (colmap_powerline.faint.evidence_stretches;
    # with ``faint``)

    LIMITS: ClassVar[dict[str, str]] = {
        "step_px": "> 0",
        "reach_px": "[0.5, 20]",
        "extend": ">= 0",
        "max_rounds": ">= 0",
        "faint_min_z": ">= 3",
        "stretch_min_z": ">= 3",
    }

    def __post_init__(self) -> None:
        check_limits(self)


@dataclass(frozen=True, eq=False)
class TracedPoints:
    """Wire points measured in the views along the confirmed curves."""

    pts_in_world: F64  # (N, 3)
    wire_id: I64  # (N,) the wire traced
    views: npt.NDArray[np.int32]  # (N,) views that agree on the point
    sigma: F64  # (N,) predicted precision (largest standard deviation, model units)
    decoded: list[Path]  # the images decoded
    share: F64  # (W,) per wire given: the share of the places where the views would fix it
    # (enough views, offset across it enough) at which they found it (NaN: too few such)

    def __len__(self) -> int:
        return len(self.pts_in_world)


@dataclass(frozen=True, eq=False)
class _Places:
    """The places traced in one round: points on the curves and their frames."""

    pts: F64  # (M, 3) on the curve
    wire: I64  # (M,) index into the wires
    across: F64  # (M, 2, 3) the two unit directions perpendicular to the curve's tangent
    tangent: F64  # (M, 3)
    n_traced: int  # wires numbered from this on are context: they make places near them
    # ambiguous in a view, and are not measured
    group: I64 | None = None  # (wires + context,) the look each wire belongs to (context:
    # -1, beside every look): wires of different looks do not narrow each other's search
    inside: npt.NDArray[np.bool_] | None = None  # (M,) between its wire's measured ends


def _frames(wire: FittedWire, s: F64) -> tuple[F64, F64, F64]:
    """Points, unit tangents and the (horizontal, upward) normals of a wire at ``s``."""
    pts = wire.points(s)
    d = wire.plane_direction_xy
    slope = np.sinh((s - wire.s0) / wire.catenary_a)
    tangent = np.c_[np.outer(np.ones(len(s)), d), slope]
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    horizontal = np.tile(np.r_[across_of(d), 0.0], (len(s), 1))
    up = np.cross(horizontal, tangent)
    up *= np.sign(up[:, 2:3])
    return pts, tangent, np.stack([horizontal, up], axis=1)


def image_normals(view: SceneImage, pts: F64, tangent: F64) -> tuple[F64, F64]:
    """The wire's unit normal in the image at each point (from its projected tangent), and
    the row of the projection's Jacobian across it: an offset of the image line along that
    normal is that row times the point's move (px per model unit). (N, 2) and (N, 3)."""
    jac = _projection_jacobian(view, pts)  # (n, 2, 3)
    t_img = np.einsum("nij,nj->ni", jac, tangent)
    t_img /= np.linalg.norm(t_img, axis=1, keepdims=True)
    normal = np.c_[-t_img[:, 1], t_img[:, 0]]
    return normal, np.einsum("ni,nij->nj", normal, jac)


def _response_reach(reach_px: float, side_offset_px: int) -> float:
    """How far across (px) a search of ``reach_px`` and another line's template response
    (side taps ``side_offset_px`` beyond its line) can meet: beyond it they never do."""
    return float(np.ceil(reach_px) + side_offset_px + 1)


def _beside_others(
    uv: F64,
    normal: F64,
    wire: I64,
    reach_px: float,
    side_offset_px: int,
    group: I64 | None = None,
) -> tuple[F64, F64]:
    """(N,) how far across each projected place (px) its wire centre may be searched in this
    view: ``reach_px`` where no other wire passes near; where one does, a whole number of
    pixels that keeps the search's last sample a pixel clear of the other wire's response
    (its template's side taps reach ``side_offset_px`` beyond its line); 0 where not even
    one pixel is clear (the place is ambiguous in this view). The other wire's distance is
    its offset across this one's image direction: stacked wires that one strip sees 3-4 px
    apart are measured there, as the separate lines they are. ``group`` (per place): places
    of two different looks (both ≥ 0) are not each other's neighbours.
    Also (N,) the signed offset (px, along each place's normal) of the nearest other wire's
    image within reach of its response (NaN: none)."""
    full = float(reach_px)
    reach = np.full(len(uv), full)
    near = np.full(len(uv), np.nan)
    radius = _response_reach(reach_px, side_offset_px)  # beyond it the full reach is clear
    pairs = cKDTree(uv).query_pairs(radius, output_type="ndarray")
    if len(pairs) == 0:
        return reach, near
    pairs = pairs[wire[pairs[:, 0]] != wire[pairs[:, 1]]]
    if group is not None:
        ga, gb = group[pairs[:, 0]], group[pairs[:, 1]]
        pairs = pairs[(ga == gb) | (ga < 0) | (gb < 0)]
    nearest = np.full(len(uv), np.inf)
    for a, b in ((pairs[:, 0], pairs[:, 1]), (pairs[:, 1], pairs[:, 0])):
        signed = np.einsum("ni,ni->n", uv[b] - uv[a], normal[a])
        across = np.abs(signed)
        clear = np.clip(np.floor(across - side_offset_px - 1), 0, None)
        np.minimum.at(reach, a, np.minimum(clear, full))
        np.minimum.at(nearest, a, across)
        # The signed offset of the nearest (ties: either).
        at = across <= nearest[a]
        near[a[at]] = signed[at]
    return reach, near


@dataclass(frozen=True)
class _LineProfile:
    """One view's template response across a lone wire, measured on its own lone places
    found: the median of their profiles, each divided by its value at the centre."""

    steps: F64  # (K,) px across, PROFILE_STEP_PX apart, centred on 0
    value: F64  # (K,) 1 at the centre
    polarity: float  # +1: the wires respond positively here (brighter than the ground)
    separation: float  # px: its core's full width (between the zero crossings); two lines
    # nearer than that overlap in their cores and are not told apart

    def at(self, x: F64) -> F64:
        return np.interp(x, self.steps, self.value, left=0.0, right=0.0)


# Sub-pixel step of a line profile and of the two-line fit's positions (px); the grid's
# rounding error (≤ half a step) is small beside a wire centre's image noise (0.2-0.4 px).
PROFILE_STEP_PX = 0.1
# Lone places a view must have found to measure its line profile (the profile is their
# median; fewer, and a place beside another wire is searched the narrowed way).
MIN_PROFILE_PLACES = 20


def _line_profile(
    response: F32, uv: F64, normal: F64, offset: F64, half_px: float
) -> _LineProfile | None:
    """The view's line profile out to ``half_px`` from its lone places found (``offset``
    finite), or None when fewer than ``MIN_PROFILE_PLACES`` are."""
    found = np.isfinite(offset)
    if found.sum() < MIN_PROFILE_PLACES:
        return None
    n = int(round(half_px / PROFILE_STEP_PX))
    steps = np.arange(-n, n + 1) * PROFILE_STEP_PX
    centre = uv[found] + offset[found, None] * normal[found]
    s = samples_across(response, centre, normal[found], steps)
    c = s[:, n]
    s, c = s[c != 0], c[c != 0]
    if len(c) < MIN_PROFILE_PLACES:
        return None
    value = np.median(s / c[:, None], axis=0)
    value /= value[n]
    # The core: from the centre out to where the profile first crosses zero (two lines
    # farther apart than its width have cores that do not overlap).
    below = value <= 0.0
    right = int(np.argmax(below[n:])) if below[n:].any() else n
    left = int(np.argmax(below[n::-1])) if below[n::-1].any() else n
    return _LineProfile(
        steps, value, float(np.sign(np.median(c))), (left + right) * PROFILE_STEP_PX
    )


def _joint_offsets(
    response: F32, uv: F64, normal: F64, near: F64, reach_px: float, profile: _LineProfile
) -> tuple[F64, F64]:
    """(N,) each wire centre's offset (px, along ``normal``) where another wire's image lies
    ``near`` px beside it, from both lines fitted at once: the sampled response is taken as
    the sum of two of the view's line profiles, at this wire's offset (within ``reach_px``)
    and at the other's (within a pixel of its projection), with least-squares amplitudes of
    the wires' polarity; the pair of positions that explains most of the response wins.
    NaN where the best lies at the end of the reach (no peak there) or none fits. Also
    (N,) this line's amplitude: the root of what it adds to the response explained by the
    best single line anywhere in the window, per unit of its profile's energy (its response
    at its centre where the two lie apart; 0: none); a line the fit puts beside the other
    where there is none adds next to nothing."""
    out = np.full(len(uv), np.nan)
    amplitude = np.zeros(len(uv))
    if len(uv) == 0:
        return out, amplitude
    half = float(profile.steps[-1])
    k_max = int(np.ceil(max(reach_px, float(np.max(np.abs(near))) + 1.0) + half))
    k = np.arange(-k_max, k_max + 1, dtype=np.float64)
    p1 = np.arange(-round(reach_px / PROFILE_STEP_PX), round(reach_px / PROFILE_STEP_PX) + 1)
    p1 = p1 * PROFILE_STEP_PX
    dp = np.arange(-round(1 / PROFILE_STEP_PX), round(1 / PROFILE_STEP_PX) + 1) * PROFILE_STEP_PX
    h1 = profile.at(k[None, :] - p1[:, None])  # (P, K)
    s11 = (h1**2).sum(1)
    pa = np.arange(-round(k_max / PROFILE_STEP_PX), round(k_max / PROFILE_STEP_PX) + 1)
    ha = profile.at(k[None, :] - pa[:, None] * PROFILE_STEP_PX)  # (A, K): one line anywhere
    sa = (ha**2).sum(1)
    chunk = 256
    for lo in range(0, len(uv), chunk):
        sl = slice(lo, lo + chunk)
        r = samples_across(response, uv[sl], normal[sl], k) * profile.polarity  # (n, K)
        p2 = near[sl, None] + dp[None, :]  # (n, D)
        h2 = profile.at(k[None, None, :] - p2[:, :, None])  # (n, D, K)
        s22 = (h2**2).sum(2)
        s12 = np.einsum("pk,ndk->npd", h1, h2)
        b1 = r @ h1.T  # (n, P)
        b2 = np.einsum("ndk,nk->nd", h2, r)
        det = s11[None, :, None] * s22[:, None, :] - s12**2
        with np.errstate(divide="ignore", invalid="ignore"):
            a1 = (s22[:, None, :] * b1[:, :, None] - s12 * b2[:, None, :]) / det
            a2 = (s11[None, :, None] * b2[:, None, :] - s12 * b1[:, :, None]) / det
            explained = a1 * b1[:, :, None] + a2 * b2[:, None, :]
        apart = np.abs(p1[None, :, None] - p2[:, None, :]) >= profile.separation
        ok = apart & (a1 > 0) & (a2 > 0) & (det > 1e-9 * s11[None, :, None] * s22[:, None, :])
        explained = np.where(ok, explained, -np.inf)
        flat = explained.reshape(len(r), -1)
        best = np.argmax(flat, axis=1)
        i1 = best // len(dp)
        fits = np.isfinite(flat[np.arange(len(r)), best])
        inner = (i1 > 0) & (i1 < len(p1) - 1)
        out[sl] = np.where(fits & inner, p1[i1], np.nan)
        # What this line adds to the best single line anywhere in the window (a single
        # line off the profile's sub-pixel shape is otherwise split into two).
        b = r @ ha.T  # (n, A)
        one = np.max(np.where(b > 0, b**2 / sa[None, :], 0.0), axis=1)
        gain = np.clip(flat[np.arange(len(r)), best] - one, 0.0, None)
        amplitude[sl] = np.where(fits & inner, np.sqrt(gain / s11[i1]), 0.0)
    return out, amplitude


# The loose test also takes, at each place, the median of its and its neighbours' responses
# across the wire along the curve, over this many line templates: a wire too faint for one
# template to stand out from the ground's texture stands out from the median, whose noise
# falls with the root of the independent lengths taken (on the shared generator's faint
# stretches, over yellow grass and bare soil, the true centre passes at 50-81 % of the places
# with one 15 px template and at 63-97 % over 75 px). Within that length the curve predicts
# the wire to within a pixel once each view's offset is removed, so the median stays on it;
# a median, it is not carried by a strong line under a third of that length.
INTEGRATED_TEMPLATES = 3
# The noise of a median of n normal samples over that of their mean: sqrt(pi / 2).
MEDIAN_NOISE = float(np.sqrt(np.pi / 2))


def _integrated_offsets(
    response: F32,
    threshold: F32,
    uv: F64,
    normal: F64,
    wire: I64,
    reach_px: float,
    template_px: int,
) -> F64:
    """(N,) each place's offset (px, along ``normal``) to the wire centre where the median
    of the signed response across the wire over ``INTEGRATED_TEMPLATES`` template lengths
    of its wire's places in this view (in place order: along the curve) stands above the
    contrast threshold there, scaled to the noise of that median (``MEDIAN_NOISE`` over the
    root of the independent template lengths: a length S of a template L long holds 1 + S /
    L of them), and the place's own
    response, of the median's sign, peaks within a pixel of the median's peak above that same
    level: the offset of that peak, NaN elsewhere."""
    out = np.full(len(uv), np.nan)
    if len(uv) == 0:
        return out
    # Half-pixel steps: at whole ones a thin line's main lobe can sample below its side
    # lobe, of the other sign, and the median would take the lobe for the wire.
    steps = np.arange(-np.ceil(reach_px), np.ceil(reach_px) + 0.25, 0.5)
    n = len(steps)
    prof = samples_across(response, uv, normal, steps)
    thr = samples_across(threshold, uv, normal, np.array([0.0]))[:, 0]
    length_px = INTEGRATED_TEMPLATES * template_px
    for k in np.unique(wire):
        m = np.flatnonzero(wire == k)
        if len(m) < 2:
            continue
        # The median over the places within the length (their spacing in this view): a
        # strong line under a third of it (a dash of a field's rows crossing under the
        # curve) does not carry the places beside it, as it would carry a mean.
        spacing = float(np.median(np.linalg.norm(np.diff(uv[m], axis=0), axis=1)))
        size = 2 * int(round(length_px / 2 / max(spacing, 1e-6))) + 1
        total = median_filter(prof[m], size=(size, 1), mode="nearest")
        independent = 1.0 + (size - 1) * spacing / template_px
        limit = median_filter(thr[m], size=size, mode="nearest") * (
            MEDIAN_NOISE / np.sqrt(independent)
        )
        rows = np.arange(len(m))
        j = np.argmax(np.abs(total), axis=1)
        # The wire's sign here (its side lobes, of the other sign, are not its centre).
        sign = np.sign(total[rows, j])[:, None]
        signed = total * sign
        j = np.argmax(signed, axis=1)
        mid = signed[rows, j]
        # The place's own centre: the peak of its own response, of the median's sign, within
        # a pixel of the median's (that says the wire is there; each place measures where, so
        # that neighbouring places' errors stay as independent as elsewhere), standing
        # above that level too: a stretch whose median stands out only from a strong line a
        # little way along (a dash of a field's rows under the curve) is not the wire.
        own = prof[m] * sign
        near = np.clip(j[:, None] + np.arange(-2, 3), 0, n - 1)
        best = near[rows, np.argmax(own[rows[:, None], near], axis=1)]
        bc = np.clip(best, 1, n - 2)
        o_left, o_mid, o_right = own[rows, bc - 1], own[rows, bc], own[rows, bc + 1]
        o_denom = o_left - 2 * o_mid + o_right
        with np.errstate(divide="ignore", invalid="ignore"):
            o_vertex = np.where(o_denom < 0, 0.5 * (o_left - o_right) / o_denom, 0.0)
        peak = (best > 0) & (best < n - 1) & (o_mid >= o_left) & (o_mid >= o_right)
        ok = (j > 0) & (j < n - 1) & (mid > limit) & peak & (o_mid > limit)
        out[m[ok]] = steps[bc[ok]] + 0.5 * np.clip(o_vertex[ok], -0.5, 0.5)
    return out


def _observe(
    view: SceneImage,
    places: _Places,
    wire_mask: WireMaskFn,
    azimuth_deg: float,
    reach_px: float,
    margin_px: int,
    detect: DetectOptions,
    template_px: int = 0,
) -> tuple[I64, F64, F64, F64, npt.NDArray[np.bool_]] | None:
    """One view's observations of the places it sees (not where another wire passes too
    near to tell, :func:`_beside_others`): (place,
    Jacobian row across the wire in the image (px per model unit), offset to the wire
    centre (px; NaN where it found none), the same where a peak stands out (loose), and
    whether the view counts among those that fix the place: ``_Observations.clear``), or
    None."""
    cand = np.flatnonzero(_roughly_in_view(view, places.pts))
    if len(cand) == 0:
        return None
    uv, _, inside = view.project(places.pts[cand])
    idx, uv = cand[inside], uv[inside]
    if len(idx) == 0:
        return None
    normal, rows = image_normals(view, places.pts[idx], places.tangent[idx])
    reach, near = _beside_others(
        uv,
        normal,
        places.wire[idx],
        reach_px,
        detect.side_offset_px,
        None if places.group is None else places.group[places.wire[idx]],
    )
    # Beside another wire's image, the two lines fitted at once may tell them apart where
    # even the narrowed search cannot.
    keep = ((reach > 0) | np.isfinite(near)) & (places.wire[idx] < places.n_traced)
    idx, uv, normal, rows = idx[keep], uv[keep], normal[keep], rows[keep]
    reach, near = reach[keep], near[keep]
    if len(idx) == 0:
        return None
    px = np.floor(uv).astype(np.int64)
    x0 = max(int(px[:, 0].min()) - margin_px, 0)
    y0 = max(int(px[:, 1].min()) - margin_px, 0)
    x1 = min(int(px[:, 0].max()) + margin_px + 1, view.width)
    y1 = min(int(px[:, 1].max()) + margin_px + 1, view.height)
    image = read_image(view.path)
    direction = image_wire_direction_deg(view, places.pts[idx[len(idx) // 2]], azimuth_deg)
    wm = wire_mask(view, image, direction, (x0, y0, x1, y1))
    del image
    local = uv - [x0, y0]
    lone = reach == reach_px
    offset = np.full(len(idx), np.nan)
    offset[lone] = _wire_offsets(wm.response, local[lone], normal[lone], reach_px)
    # Beside another wire: both lines fitted at once with this view's own line profile,
    # where the two are farther apart than its core is wide; else the narrowed search.
    joint = np.zeros(len(idx), bool)
    amplitude = np.zeros(len(idx))
    if (~lone).any():
        profile = _line_profile(
            wm.response,
            local[lone],
            normal[lone],
            offset[lone],
            _response_reach(reach_px, detect.side_offset_px),
        )
        if profile is not None:
            joint = ~lone & (np.abs(near) >= profile.separation)
            offset[joint], amplitude[joint] = _joint_offsets(
                wm.response, local[joint], normal[joint], near[joint], reach_px, profile
            )
    narrowed = ~lone & ~joint & (reach > 0)
    for r in np.unique(reach[narrowed]):
        at = narrowed & (reach == r)
        offset[at] = _wire_offsets(wm.response, local[at], normal[at], float(r))
    found = np.isfinite(offset)
    centre = uv[found] + offset[found, None] * normal[found] - [x0, y0]
    cx = np.clip(np.floor(centre[:, 0]).astype(np.int64), 0, wm.mask.shape[1] - 1)
    cy = np.clip(np.floor(centre[:, 1]).astype(np.int64), 0, wm.mask.shape[0] - 1)
    # Strict: the centre is a wire pixel of the detector (within a pixel), as anywhere else.
    strict = found.copy()
    strict[np.flatnonzero(found)[~wm.dilated(1.0)[cy, cx]]] = False
    # Loose: a peak above the detector's contrast threshold, without its length filter (on a
    # wire the views already find, the curve is the evidence the length gave).
    magnitude = np.abs(wm.response)
    threshold = contrast_threshold(magnitude, detect)
    strong = magnitude > threshold
    strong = cv2.dilate(strong.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    loose = found.copy()
    loose[np.flatnonzero(found)[~strong[cy, cx]]] = False
    loose_offset = offset.copy()
    # Only between the wire's measured ends: past them a point leaving the curve may be a
    # support's bend, which the bend test tells from the curve's systematic error only at the
    # single template's precision (with the median's, the shared cross seed 6's R2 stopped
    # where its curve, 4.5 cm off the wire from pose errors shared along it, met its
    # continuation). Rounds past the ends look there alone and skip it.
    between = places.inside[idx] if places.inside is not None else np.ones(len(idx), bool)
    if template_px and (lone & between).any():
        # A lone place no single template finds may be found by the median along the curve
        # (over every lone place of its wire in this view: the places past an end are the
        # median's neighbours at the end).
        at = np.full(len(idx), np.nan)
        at[lone] = _integrated_offsets(
            wm.response,
            threshold,
            local[lone],
            normal[lone],
            places.wire[idx[lone]],
            reach_px,
            template_px,
        )
        extra = np.isfinite(at) & between & ~loose
        loose |= extra
        loose_offset[extra] = at[extra]
    if joint.any():
        # Beside another wire, its pixels and response spill over a centre the fit put
        # there: the line must stand above the threshold on its own (the other's removed).
        weak = np.zeros(len(idx), bool)
        weak[np.flatnonzero(found)] = amplitude[found] <= threshold[cy, cx]
        strict &= ~(joint & weak)
        loose &= ~(joint & weak)
    # A view that resolves this line beside the other (the fit's centre, strong on its own)
    # counts among those that fix the place; one that does not is no evidence either way.
    clear = lone | (joint & loose)
    return (
        idx,
        rows,
        np.where(strict, offset, np.nan),
        np.where(loose, loose_offset, np.nan),
        clear,
    )


def _solve(
    rows: F64, offsets: F64, across: F64, tolerance_px: float
) -> tuple[F64, npt.NDArray[np.bool_], F64, float] | None:
    """The offset (2,) of one place across its curve from its views' equations, the views
    kept, the (2, 2) normal matrix and the smallest redundancy number of the views kept
    (1 − leverage: 0 for a view no other checks); None when fewer than two views agree."""
    a = rows @ across.T  # (n, 2)
    keep = np.ones(len(a), bool)
    while keep.sum() >= 2:
        ak, bk = a[keep], offsets[keep]
        normal = ak.T @ ak
        if np.linalg.cond(normal) > 1e8:
            return None
        x = np.linalg.solve(normal, ak.T @ bk)
        res = offsets - a @ x
        worst = np.argmax(np.where(keep, np.abs(res), -1.0))
        if abs(res[worst]) <= tolerance_px:
            leverage = np.einsum("ni,ij,nj->n", ak, np.linalg.inv(normal), ak)
            return x, keep, normal, float(1.0 - leverage.max())
        keep[worst] = False
    return None


@dataclass(frozen=True, eq=False)
class _Solution:
    x: F64  # (M, 2) offsets across the curve (NaN: not measured)
    rss: F64  # (M,) residual sum of squares (px²)
    n_views: npt.NDArray[np.int32]  # (M,) views kept
    normal: F64  # (M, 2, 2) normal matrices (px² per model unit²)
    redundancy: F64  # (M,) smallest redundancy number of the views kept
    seen: npt.NDArray[np.int32]  # (M,) views that see the place, no other wire near it
    normal_seen: F64  # (M, 2, 2) the normal matrix had they all found the wire


def _solve_places(
    m: int,
    place: I64,
    rows: F64,
    offsets: F64,
    across: F64,
    tolerance_px: float,
    clear: npt.NDArray[np.bool_],
) -> tuple[_Solution, F64, npt.NDArray[np.bool_]]:
    """Every place's solution from its observations (offset NaN: the view found no wire
    there), and each observation's residual and whether it was kept. The views that see a
    place (``seen``, ``normal_seen``) are those whose search no other wire narrowed
    (``clear``)."""
    x = np.full((m, 2), np.nan)
    rss = np.zeros(m)
    n_views = np.zeros(m, np.int32)
    normal = np.zeros((m, 2, 2))
    res = np.full(len(place), np.nan)
    kept = np.zeros(len(place), bool)
    redundancy = np.zeros(m)
    a_all = np.einsum("nj,nkj->nk", rows, across[place])  # (n, 2)
    normal_seen = np.zeros((m, 2, 2))
    np.add.at(normal_seen, place[clear], a_all[clear, :, None] * a_all[clear, None, :])
    seen = np.bincount(place[clear], minlength=m).astype(np.int32)
    found = np.flatnonzero(np.isfinite(offsets))
    order = found[np.argsort(place[found], kind="stable")]
    bounds = np.flatnonzero(np.diff(place[order])) + 1
    for obs in np.split(order, bounds) if len(order) else []:
        if len(obs) < 2:
            continue
        i = place[obs[0]]
        sol = _solve(rows[obs], offsets[obs], across[i], tolerance_px)
        if sol is None:
            continue
        x[i], keep, normal[i], redundancy[i] = sol
        r = offsets[obs] - a_all[obs] @ x[i]
        res[obs], kept[obs] = r, keep
        rss[i], n_views[i] = float((r[keep] ** 2).sum()), int(keep.sum())
    return _Solution(x, rss, n_views, normal, redundancy, seen, normal_seen), res, kept


@dataclass(frozen=True, eq=False)
class _Observations:
    place: I64  # (n,) place observed
    view: I64  # (n,) by this view
    rows: F64  # (n, 3) Jacobian row across the wire (px per model unit)
    strict: F64  # (n,) offset to the detector's wire centre (px; NaN: none)
    loose: F64  # (n,) offset to a peak that stands out (px; NaN: none)
    clear: npt.NDArray[np.bool_]  # (n,) the view counts among those that see the place:
    # no other wire's image within the search's reach, or the two-line fit found this line
    # beside it standing above the contrast threshold on its own (counted without that test,
    # the fitted views let a curve 0.4 m above the real road flight's field-side conductor,
    # in its vertical plane, pass as a wire). A view searched the narrowed way, or fitted
    # without finding, adds its measurement where it has one and does not count


def _look(
    scene: Scene,
    places: _Places,
    wire_mask: WireMaskFn,
    azimuth_deg: float,
    reach_px: float,
    num_threads: int,
    margin_px: int,
    detect: DetectOptions,
    template_px: int = 0,
) -> tuple[_Observations, list[Path]]:
    """Every view's observations of the places (decoding each image that sees one)."""
    parts: list[tuple[int, tuple[I64, F64, F64, F64, npt.NDArray[np.bool_]]]] = []
    decoded: list[Path] = []

    def look(v: int):
        return v, _observe(
            scene.images[v],
            places,
            wire_mask,
            azimuth_deg,
            reach_px,
            margin_px,
            detect,
            template_px,
        )

    with ThreadPoolExecutor(max_workers=num_threads) as pool:
        for v, obs in pool.map(look, range(len(scene.images))):
            if obs is not None:
                decoded.append(scene.images[v].path)
                parts.append((v, obs))
    if not parts:
        z = np.zeros(0)
        return (
            _Observations(
                z.astype(np.int64), z.astype(np.int64), z.reshape(0, 3), z, z, z.astype(bool)
            ),
            decoded,
        )
    return (
        _Observations(
            np.concatenate([o[0] for _, o in parts]),
            np.concatenate([np.full(len(o[0]), v, np.int64) for v, o in parts]),
            np.concatenate([o[1] for _, o in parts]),
            np.concatenate([o[2] for _, o in parts]),
            np.concatenate([o[3] for _, o in parts]),
            np.concatenate([o[4] for _, o in parts]),
        ),
        decoded,
    )


def _measure(
    obs: _Observations,
    places: _Places,
    tolerance_px: float,
    bias: dict[tuple[int, int], float],
    loose: npt.NDArray[np.bool_] | None = None,
) -> _Solution:
    """Each place solved from its views; ``bias`` (view, wire) → the offset a view finds on a
    wire beside where the others put it (its pose, the wire's look there): estimated from
    the strict observations when empty, subtracted always. ``loose`` (M,): places that take
    the loose observations."""
    m = len(places.pts)
    wire = places.wire[obs.place]
    if not bias and len(obs.place):
        sol, res, kept = _solve_places(
            m, obs.place, obs.rows, obs.strict, places.across, tolerance_px, obs.clear
        )
        # From the residuals at places the other views check (more than two views kept).
        checked = kept & (sol.n_views[obs.place] > 2)
        for v, k in set(zip(obs.view[checked].tolist(), wire[checked].tolist(), strict=True)):
            r = res[checked & (obs.view == v) & (wire == k)]
            if len(r) >= MIN_BIAS_PLACES:
                bias[v, k] = float(np.median(r))
    offsets = obs.strict
    if loose is not None:
        offsets = np.where(loose[obs.place], obs.loose, obs.strict)
    if bias:
        shift = [bias.get(vk, 0.0) for vk in zip(obs.view.tolist(), wire.tolist(), strict=True)]
        offsets = offsets - np.array(shift)
    return _solve_places(m, obs.place, obs.rows, offsets, places.across, tolerance_px, obs.clear)[0]


def _image_noise(sol: _Solution, tolerance_px: float) -> float:
    """The image noise of a wire centre (px), from the places seen by more views than the two
    unknowns need: the median of each place's residuals over the chi-square median (robust
    to places where one view found a neighbouring line within the tolerance)."""
    redundant = np.isfinite(sol.x[:, 0]) & (sol.n_views > 2)
    if redundant.sum() < 10:
        return tolerance_px / 2
    dof = sol.n_views[redundant] - 2
    sigma_px = float(np.sqrt(np.median(sol.rss[redundant] / chi2.median(dof))))
    logger.info(
        "trace: wire centres measured to %.2f px (%d places seen by more than two views)",
        sigma_px,
        int(redundant.sum()),
    )
    return sigma_px


def _kept(
    sol: _Solution, sigma_px: float, max_sigma: float, min_redundancy: float
) -> tuple[npt.NDArray[np.bool_], F64]:
    """The places measured well enough, and each place's predicted precision (its largest
    standard deviation; inf: not solved)."""
    solved = np.isfinite(sol.x[:, 0])
    sigma = np.full(len(sol.x), np.inf)
    ok = np.flatnonzero(solved)
    if len(ok):
        cov = np.linalg.inv(sol.normal[ok]) * sigma_px**2
        sigma[ok] = np.sqrt(np.linalg.eigvalsh(cov)[:, -1])
    # Two views fix a point with no check on it; a third makes the outlier test work.
    checked = sol.redundancy >= min_redundancy
    return solved & (sigma <= max_sigma) & (sol.n_views >= MIN_VIEWS) & checked, sigma


# A place two views fix (a third would check them) is kept on a confirmed wire when its point
# lies on the wire's curve within their joint error: the chi-square test at 99 % (2 dof).
CURVE_CHI2 = float(chi2.ppf(0.99, 2))


def _checked_by_curve(
    sol: _Solution,
    sigma: F64,
    sigma_px: float,
    max_sigma: float,
    places: _Places,
    wires: list[FittedWire],
    all_pts: F64,
    corr: float,
    model_error: Sequence[float] | None = None,
    one_way_sigma: float = 0.0,
) -> tuple[npt.NDArray[np.bool_], F64, F64]:
    """The places the wire's curve checks, and their offsets and precision (the solution's,
    or, where the curve is what fixes them, the two combined).

    A place fixed by exactly two views (well enough) is kept where its point lies on its
    wire's curve within the point's error and the curve's there (from the points it was
    fitted to, ``corr`` neighbours counted as one; across, also ``model_error[k]``, how far
    the wire's plane leaves its own points: a wire the wind tilted bows in plan), where the
    curve itself is known to ``max_sigma``: the curve is the check a third view would give
    (near a support, where three views see a wire's end and one of them misses it, or where
    only two views see the wire at all).

    Between the wire's measured ends the curve also fixes what the views leave loose: views
    of one strip whose rays meet at a narrow angle fix a point across their rays well and
    along them poorly (on the shared area survey, 7 cm where a point must be known to 5 cm,
    with the curve known to 2 mm there). Such a place (its views fix it to ``max_sigma`` in
    one direction, and to ``one_way_sigma`` in the other: the test must still be able to tell
    the wire from another one beside it, which the views see within their reach where their
    rays are near parallel: a wire 6 m above the curve, from two views nearly overhead) is
    kept where it passes the same test and the views and the curve together fix it to
    ``max_sigma``; its point is their weighted combination, with its precision. Past the
    ends, where the curve is continued and the bend test must see where the wire leaves it,
    only the views fix a point."""
    solved = np.isfinite(sol.x[:, 0]) & (places.wire < places.n_traced)
    x_out, sigma_out = sol.x.copy(), sigma.copy()
    two = solved & (sol.n_views == 2) & (sigma <= max_sigma)
    one_way = solved & (sol.n_views >= 2) & (sigma > max_sigma) & (sigma <= one_way_sigma)
    out = np.zeros(len(two), bool)
    for k in np.unique(places.wire[two | one_way]):
        m = np.flatnonzero((two | one_way) & (places.wire == k))
        w = wires[k]
        s = w.plane_coords(places.pts[m])[0]
        sig_a, sig_z = _prediction_sigma(w, all_pts[w.point_indices], s, corr)
        if model_error is not None:
            sig_a = np.hypot(sig_a, model_error[k])
        cov_views = np.linalg.inv(sol.normal[m]) * sigma_px**2
        cov = cov_views.copy()
        cov[:, 0, 0] += sig_a**2
        cov[:, 1, 1] += sig_z**2
        x = sol.x[m]
        # Only where the curve is known well enough to check (not far past a short piece).
        ok = (np.einsum("ni,nij,nj->n", x, np.linalg.inv(cov), x) <= CURVE_CHI2) & (
            np.hypot(sig_a, sig_z) <= max_sigma
        )
        weak = one_way[m]
        if weak.any():
            # The views' best-fixed direction within max_sigma; the curve, known between
            # the ends, fixes the rest: the two combined (the curve's offset is 0).
            views_best = np.sqrt(np.linalg.eigvalsh(cov_views[weak])[:, 0])
            inside = (s[weak] >= w.s_range[0]) & (s[weak] <= w.s_range[1])
            info = sol.normal[m[weak]] / sigma_px**2
            prior = np.zeros_like(info)
            prior[:, 0, 0] = 1.0 / sig_a[weak] ** 2
            prior[:, 1, 1] = 1.0 / sig_z[weak] ** 2
            post = np.linalg.inv(info + prior)
            post_sigma = np.sqrt(np.linalg.eigvalsh(post)[:, -1])
            x_out[m[weak]] = np.einsum("nij,njk,nk->ni", post, info, x[weak])
            sigma_out[m[weak]] = post_sigma
            ok[weak] &= inside & (views_best <= max_sigma) & (post_sigma <= max_sigma)
        out[m] = ok
    return out, x_out, sigma_out


def _measurable(sol: _Solution, sigma_px: float, max_sigma: float) -> npt.NDArray[np.bool_]:
    """The places the views would fix well enough had they all found the wire."""
    seen_ok = sol.seen >= MIN_VIEWS
    sigma_seen = np.full(len(sol.x), np.inf)
    with np.errstate(all="ignore"):
        cov = np.linalg.pinv(sol.normal_seen[seen_ok]) * sigma_px**2
    sigma_seen[seen_ok] = np.sqrt(np.abs(np.linalg.eigvalsh(cov)[:, -1]))
    return seen_ok & (sigma_seen <= max_sigma)


def _found_share(
    good: npt.NDArray[np.bool_], measurable: npt.NDArray[np.bool_], wire: I64, n_wires: int
) -> F64:
    """(n_wires,) per wire, the share of the places the views would fix where they found it
    (NaN: fewer than ``MIN_MEASURABLE_PLACES`` such places)."""
    fixable = np.bincount(wire[measurable], minlength=n_wires)[:n_wires]
    found = np.bincount(wire[measurable & good], minlength=n_wires)[:n_wires]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(fixable >= MIN_MEASURABLE_PLACES, found / fixable, np.nan)


def _ends_found(
    w: FittedWire,
    k: int,
    places: _Places,
    good: npt.NDArray[np.bool_],
    measurable: npt.NDArray[np.bool_],
) -> list[tuple[int, npt.NDArray[np.bool_], float]]:
    """For each end of wire ``k`` (0: low ``s``, 1: high) traced past in this round: the
    places past it, and the share of those the views would fix where they found the wire
    (NaN: fewer than ``MIN_MEASURABLE_PLACES`` such places)."""
    at_k = places.wire == k
    s = np.full(len(places.pts), np.nan)
    s[at_k] = w.plane_coords(places.pts[at_k])[0]
    out = []
    for j, side in enumerate((s < w.s_range[0], s > w.s_range[1])):
        fixable = side & measurable
        n = int(fixable.sum())
        share = (good & fixable).sum() / n if n >= MIN_MEASURABLE_PLACES else np.nan
        out.append((j, side, float(share)))
    return out


def _places(
    wires: list[FittedWire],
    ranges: list[list[tuple[float, float]]],
    step: F64,
    context: list[FittedWire],
    groups: Sequence[int] | None = None,
    context_groups: Sequence[int] | None = None,
    distinct: tuple[int, float] | None = None,
) -> _Places | None:
    """Places every ``step[k]`` over the ``ranges`` of each wire, then over the whole of
    each context wire (None: no place on the wires); ``groups``: each wire's look, and
    ``context_groups`` each context wire's (None: -1, beside every look). ``distinct``
    (first, distance): the context wires from ``first`` on have no place within that
    distance of a wire's place (there they are that wire, measured in another piece)."""
    if not any(hi > lo for rs in ranges for lo, hi in rs):
        return None
    n_traced = len(wires)
    wires = wires + context
    ranges = ranges + [[c.s_range] for c in context]
    step = np.r_[step, np.full(len(context), np.min(step) if len(step) else 0.1)]
    pts, wire, across, tangent, inside = [], [], [], [], []
    for k, (w, rs) in enumerate(zip(wires, ranges, strict=True)):
        for lo, hi in rs:
            if hi <= lo:
                continue
            n = max(int(np.ceil((hi - lo) / step[k])), 1)
            s = lo + (np.arange(n) + 0.5) * (hi - lo) / n
            p, t, acr = _frames(w, s)
            pts.append(p)
            tangent.append(t)
            across.append(acr)
            wire.append(np.full(len(s), k, np.int64))
            inside.append((s >= w.s_range[0]) & (s <= w.s_range[1]))
    if not pts:
        return None
    wire_all, pts_all = np.concatenate(wire), np.concatenate(pts)
    keep = np.ones(len(wire_all), bool)
    if distinct is not None:
        mine = wire_all < n_traced
        later = wire_all >= n_traced + distinct[0]
        if mine.any() and later.any():
            near = cKDTree(pts_all[mine]).query(pts_all[later], distance_upper_bound=distinct[1])[0]
            keep[np.flatnonzero(later)[np.isfinite(near)]] = False
    return _Places(
        pts_all[keep],
        wire_all[keep],
        np.concatenate(across)[keep],
        np.concatenate(tangent)[keep],
        n_traced,
        None
        if groups is None
        else np.r_[
            np.asarray(groups, np.int64),
            np.full(len(context), -1) if context_groups is None else context_groups,
        ],
        np.concatenate(inside)[keep],
    )


def _height_jacobian(wire: FittedWire, s_m: float) -> Callable[[F64], F64]:
    """d height / d (curvature, slope, height at ``s_m``) of the wire's catenary, by central
    differences: unlike (a, s0, z0), well conditioned on a short or straight piece, whose
    lowest point is far off."""
    k = 1.0 / wire.catenary_a
    theta = np.array([k, k * (s_m - wire.s0), float(wire.z_at(np.array([s_m]))[0])])
    steps = np.array([1e-6, 1e-4, 1e-3])

    def jac(t: F64) -> F64:
        cols = []
        for i in range(3):
            d = np.zeros(3)
            d[i] = steps[i]
            hi, lo = theta + d, theta - d
            cols.append((catenary_mid(t - s_m, *hi) - catenary_mid(t - s_m, *lo)) / (2 * steps[i]))
        return np.stack(cols, axis=1)

    return jac


def _prediction_sigma(wire: FittedWire, pts: F64, s: F64, corr: float) -> tuple[F64, F64]:
    """(len(s),) standard errors of the wire's curve at ``s`` (continued past its ends),
    across and in height, from its fit to ``pts``: linearised least squares, with the
    residuals of ``corr`` neighbouring points counted as one (they share image evidence)."""
    sp, acr, dz = wire.plane_coords(pts)
    n = len(sp)
    # Across: the plane, a line c = c0 + slope s.
    x = np.c_[np.ones(n), sp]
    cov_a = np.linalg.pinv(x.T @ x) * float(np.var(acr) * n / max(n - 2, 1)) * corr
    g = np.c_[np.ones(len(s)), s]
    sig_a = np.sqrt(np.abs(np.einsum("ni,ij,nj->n", g, cov_a, g)))
    # Height: the catenary's curvature, slope and height at the middle of the points.
    jac = _height_jacobian(wire, float(np.mean(sp)))
    j = jac(sp)
    cov_z = np.linalg.pinv(j.T @ j) * float(np.var(dz) * n / max(n - 3, 1)) * corr
    gz = jac(np.asarray(s, np.float64))
    sig_z = np.sqrt(np.abs(np.einsum("ni,ij,nj->n", gz, cov_z, gz)))
    return sig_a, sig_z


def _continuation_error(wire: FittedWire, pts: F64, depth: float) -> float:
    """How far the wire's own points within ``depth`` of an end lie across the wire from its
    vertical plane fitted to the rest and continued over them (the median offset of the half
    nearest the end, farthest from the rest; the smaller of the two ends, so that a bend at
    one end does not count). A wire blown out by the wind hangs in a tilted plane, and its
    path in plan bows away from the straight line of a vertical plane by up to its sag times
    the sine of the tilt: continued, that line leaves the wire by a few centimetres over a
    few metres (the real road flight's conductors: 1.4-1.5 cm at 2.5-5 m from the ends of a
    30 m stretch). In height the tilt changes the curve to second order only, and there a
    support's bend shows. 0.0 where neither end has a rest at least twice ``depth`` long
    (a short piece: there the curve's predicted error already says how little it is known)."""
    sp, acr, _ = wire.plane_coords(pts)
    x = np.c_[np.ones(len(sp)), sp]
    errs = []
    for inside in (sp - wire.s_range[0], wire.s_range[1] - sp):
        rest = inside > depth
        held = (inside >= 0) & (inside <= depth)
        if rest.sum() < MIN_MEASURABLE_PLACES or not held.any() or np.ptp(sp[rest]) < 2 * depth:
            continue
        near = held & (inside <= np.median(inside[held]))
        line = np.linalg.lstsq(x[rest], acr[rest], rcond=None)[0]
        errs.append(abs(float(np.median(acr[near] - x[near] @ line))))
    return min(errs, default=0.0)


def _leaves_curve(
    wire: FittedWire,
    pts: F64,
    new: F64,
    new_sigma: F64,
    corr: float,
    model_error: float = 0.0,
) -> float:
    """How far the points ``new`` past one end of the wire lie from its curve, continued, in
    standard errors: the larger of the statistics across the wire and in height, on the
    farther half of them (median offset over the curve's error there and theirs, with
    ``corr`` neighbouring points counted as one; across, also over ``model_error``, how
    far its vertical plane continued leaves the wire's own points: :func:`_continuation_error`).
    ``pts``: the points the wire was fitted to; ``new_sigma``: the new points' predicted
    precision."""
    s, acr, dz = wire.plane_coords(new)
    d_end = np.minimum(np.abs(s - wire.s_range[0]), np.abs(s - wire.s_range[1]))
    far = d_end >= np.median(d_end)
    sig_a, sig_z = _prediction_sigma(wire, pts, s[far], corr)
    noise = float(np.median(new_sigma[far])) / np.sqrt(max(far.sum() / corr, 1.0))
    t_across = abs(float(np.median(acr[far]))) / np.linalg.norm(
        [float(np.median(sig_a)), noise, model_error]
    )
    t_height = abs(float(np.median(dz[far]))) / np.hypot(float(np.median(sig_z)), noise)
    return max(t_across, t_height)


# The pairs' matches continue a wire past its end, one metre at a time, while a metre holds
# more than MATCH_CHANCE_RATIO times the matches of the same tube displaced above and below
# the curve (the clutter there: a support's members, ground lines) and at least
# MIN_MATCHES of them (a true wire seen by one pair gives one match per image row, tens per
# metre at the half-scale GSD).
MATCH_CHANCE_RATIO = 3.0
MIN_MATCHES = 3
# A run of matches continuing the wires is taken as wire where it goes on for more than this
# past the measured wires (model units, metres where the model is): a support's in-line
# hardware (clamps, a distribution line's insulators) gives a shorter one, 0.8 m on the
# package's span across the line. Chosen on the shared generator's flight across the line
# (seed 8: 4.9 m of wire to tower B, which one round of ``extend``, 5 m, left out).
MIN_MATCHED_RUN = 2.0
# The displaced tubes: this many inlier distances above and below the curve.
MATCH_CONTROL_OFFSETS = (-6.0, -3.0, 3.0, 6.0)


def primitive_reach(
    wires: list[FittedWire], primitives: F64, along: F64, inlier: float, bin_len: float = 1.0
) -> tuple[float, float] | None:
    """How far along the line (``along``) the pairs' matches follow the wires' curves
    continued past their ends: from each end outwards, metre by metre (``bin_len``), while a
    metre holds at least ``MIN_MATCHES`` matches within ``inlier`` of the curve and more than
    ``MATCH_CHANCE_RATIO`` times as many as the same tube displaced above and below it
    (one metre short of that is let pass). None: no wire or no match.

    A wrong match lands on a confirmed curve, within centimetres, only by accident; a run of
    them continuing it is the wire where too few views saw it for the verification to be
    sure (the last strip of a flight across the line). Past a support the next span's wire
    leaves the curve within a metre, and the members' clutter lies on the displaced tubes
    as much as on the curve."""
    if not wires or len(primitives) == 0:
        return None
    tree = cKDTree(primitives)
    longest = max(w.s_range[1] - w.s_range[0] for w in wires)
    n_bins = int(np.ceil(longest / bin_len)) + 1
    reach_z = (max(abs(o) for o in MATCH_CONTROL_OFFSETS) + 1.0) * inlier
    reached = []
    for w in wires:
        lo, hi = w.s_range
        for sign, s0 in ((-1.0, lo), (1.0, hi)):
            # The matches near the curve continued, in metres past the end.
            s = s0 + sign * np.arange(0.0, longest + bin_len, 0.5 * bin_len)
            near = tree.query_ball_point(w.points(s), r=reach_z + bin_len)
            idx = np.unique(np.concatenate([np.asarray(n, np.int64) for n in near]))
            ps, across, dz = w.plane_coords(primitives[idx])
            past = sign * (ps - s0)
            inside = (past >= 0) & (np.abs(across) < inlier)
            b = np.clip((past / bin_len).astype(np.int64), 0, n_bins - 1)
            on = inside & (np.abs(dz) < inlier)
            on_curve = np.bincount(b[on], minlength=n_bins)
            control = np.mean(
                [
                    np.bincount(b[inside & (np.abs(dz - o * inlier) < inlier)], minlength=n_bins)
                    for o in MATCH_CONTROL_OFFSETS
                ],
                axis=0,
            )
            ok = (on_curve >= MIN_MATCHES) & (on_curve > MATCH_CHANCE_RATIO * control)
            # The farthest match on the curve in each metre.
            farthest = np.zeros(n_bins)
            np.maximum.at(farthest, b[on], past[on])
            # Walk out while the metres continue it (one short metre let pass).
            last, miss = 0.0, 0
            for k in range(n_bins):
                if ok[k]:
                    last, miss = float(farthest[k]), 0
                else:
                    miss += 1
                    if miss > 1:
                        break
            reached.append(float(w.points(np.array([s0 + sign * last]))[0, :2] @ along))
    return (min(reached), max(reached))


def matched_reach(
    measured: tuple[float, float], matched: tuple[float, float]
) -> tuple[float, float]:
    """How far along the line tracing may go: at each end, as far as the matches continue
    the wires (``matched``, :func:`primitive_reach`) where they run on for more than
    ``MIN_MATCHED_RUN`` past the measured wires (``measured``), else the measured end."""
    return (
        matched[0] if matched[0] < measured[0] - MIN_MATCHED_RUN else measured[0],
        matched[1] if matched[1] > measured[1] + MIN_MATCHED_RUN else measured[1],
    )


def support_reach(
    wires: list[FittedWire],
    pts_in_world: F64,
    along: F64,
    extend: float,
    measured: tuple[float, float] | None = None,
) -> tuple[float | None, float | None]:
    """Where along the line (``along``) the first support beyond each end of the measured
    wires stands, from the verified points none of the wires holds (None at an end: no
    support marked beyond it, or the wires already reach one).

    A support's members (lattice, arms, insulators) give false matches that the other views
    confirm in every direction: its verified points pile up along the line around it more
    densely than anywhere along the wires' own stretch, where only chance pairings lie. The
    density is counted in bins of a fifth of ``extend``, within the wires' band across the
    line (one ``extend`` either side); its reference is the highest bin over the stretch
    between the ends, short of one ``extend`` at each (where a support the wires reach
    begins). Beyond an end, the first run of bins above the reference by more than its
    Poisson noise is a support; the arms hold the wires at its middle along the line: its
    density-weighted centre. An end
    that lies in such a run already reaches its support. ``measured``: how far along the
    line the measured wires reach, other wires than ``wires`` included (default: the ends
    of ``wires``)."""
    if not wires or len(pts_in_world) == 0 or extend <= 0:
        return None, None
    across = across_of(along)
    held = np.zeros(len(pts_in_world), bool)
    held[np.concatenate([w.point_indices for w in wires])] = True
    ends = np.concatenate([w.points(np.array(w.s_range))[:, :2] for w in wires])
    lo, hi = measured or (float((ends @ along).min()), float((ends @ along).max()))
    c = ends @ across
    xy = pts_in_world[~held, :2]
    band = (xy @ across > c.min() - extend) & (xy @ across < c.max() + extend)
    u = xy[band] @ along
    if len(u) == 0:
        return None, None
    bin_len = extend / 5.0
    start = min(float(u.min()), lo) - bin_len
    edges = start + bin_len * np.arange(
        int(np.ceil((max(float(u.max()), hi) - start) / bin_len)) + 2
    )
    count = np.histogram(u, edges)[0].astype(np.float64)
    centre = 0.5 * (edges[:-1] + edges[1:])
    inner = (centre > lo + extend) & (centre < hi - extend)
    if not inner.any():
        return None, None
    # Above the highest count between the ends by more than its Poisson noise (three standard
    # deviations): not a chance high of the matches scattered along the line.
    top = float(count[inner].max())
    above = count > top + 3.0 * np.sqrt(max(top, 1.0))
    out: list[float | None] = []
    for end, sign in ((lo, -1), (hi, 1)):
        at_end = int(np.clip(np.searchsorted(edges, end) - 1, 0, len(count) - 1))
        walk = np.flatnonzero(sign * (centre - end) > 0)[::sign]  # past the end, outwards
        hits = np.flatnonzero(above[walk])
        if above[at_end] or len(hits) == 0:
            out.append(None)
            continue
        run = walk[hits[0] :]
        gap = np.flatnonzero(~above[run])
        run = run[: gap[0]] if len(gap) else run
        out.append(float(np.average(centre[run], weights=count[run])))
    return out[0], out[1]


def trace_wires(
    scene: Scene,
    wires: list[FittedWire],
    pts_in_world: F64,
    wire_mask: WireMaskFn,
    azimuth_deg: float,
    options: TraceOptions,
    wires_options: WiresOptions,
    tolerance_px: float,
    num_threads: int = 2,
    margin_px: int = 24,
    detect: DetectOptions | None = None,
    context: list[FittedWire] | None = None,
    min_redundancy: float = 0.0,
    template_length_px: int = 25,
    primitives: F64 | None = None,
    groups: Sequence[int] | None = None,
    evident: Sequence[bool] | None = None,
    limits: Sequence[tuple[float, float]] | None = None,
) -> tuple[list[FittedWire], TracedPoints]:
    """Measure each confirmed wire in every view that sees it (module docstring).

    Args:
        scene: the oriented scene.
        wires: the confirmed wires, fitted to ``pts_in_world``.
        pts_in_world: the measured points the wires index.
        wire_mask: the verification's detector.
        azimuth_deg: the wires' horizontal direction.
        tolerance_px: a view disagreeing with the others by more than this is dropped.
        context: other wires: a place where one of them passes near in a view is not
            measured there (they are not traced).
        min_redundancy: each view kept at a place has at least this redundancy number
            (``MIN_REDUNDANCY`` for wires the support check did not confirm).
        template_length_px: the length of ``wire_mask``'s line template: places closer
            than that along a wire share their image evidence.
        primitives: (M, 3) the pairs' matches, verified or not: the wires are traced as far
            along the line as runs of them continue a wire's curve (:func:`primitive_reach`),
            when that is more than ``MIN_MATCHED_RUN`` farther than the measured wires reach.
        groups: (len(wires),) each wire's look, ≥ 0: wires of different looks are traced
            from the same image reads as if each look were alone (beside each other in a
            view, they do not narrow each other's search); hypotheses that exclude each other
            are looked for so at once. None: one look.
        evident: (len(wires),) wires whose line evidence other than the detector's shows them
            (:mod:`colmap_powerline.faint`): a response peak that stands out counts on them
            from the start, as on a wire the views find, and their share is that of the
            places so found. None: none.
        limits: (len(wires),) how far along the line (plan position along ``azimuth_deg``)
            each wire may be traced, low and high: its span's supports, once they are known.
            None: as far as the measured wires, the matches and the marked supports reach.

    Returns:
        The wires refitted to their measured and traced points (indices past
        ``len(pts_in_world)`` are traced points, in the order returned), and the traced points.
    """
    empty = TracedPoints(
        np.zeros((0, 3)),
        np.zeros(0, np.int64),
        np.zeros(0, np.int32),
        np.zeros(0),
        [],
        np.full(len(wires), np.nan),
    )
    if not options.enabled or not wires:
        return wires, empty
    detect = detect or DetectOptions()
    context = context or []
    t0 = time.perf_counter()
    centres = scene.centers_in_world
    # Place spacing: step_px pixels of the nearest camera at each wire.
    step = np.array(
        [
            options.step_px
            * float(
                np.min(np.linalg.norm(centres - w.points(np.array([np.mean(w.s_range)])), axis=1))
            )
            / scene.images[0].focal_px
            for w in wires
        ]
    )
    ranges = [[w.s_range] for w in wires]
    out_wire: list[I64] = []
    out_views: list[npt.NDArray[np.int32]] = []
    out_sigma: list[F64] = []
    decoded: list[Path] = []
    all_pts = pts_in_world
    # A traced point lies within the wires' inlier distance of its true place with 98 %
    # probability (2.33 standard deviations, one-sided in its worst direction).
    max_sigma = wires_options.inlier_distance / 2.33
    sigma_px: float | None = None
    found: npt.NDArray[np.bool_] | None = None  # the wires the views find (loose peaks count)
    # Neighbouring places share image evidence over the line template's length.
    corr = max(template_length_px / options.step_px, 1.0)
    share = np.full(len(wires), np.nan)
    # The share of the places the views would fix where they found each wire along its
    # confirmed stretch, with the loose peaks where those count: what a round past an end
    # is held to.
    base_share = np.full(len(wires), np.nan)
    # (wire, end: 0 low, 1 high) → the points of a round on probation at that end.
    probation: dict[tuple[int, int], I64] = {}
    # (wire, end) → how far along the wire (s) a round past that end looked where fewer than
    # three views see the wire at all (an area survey's strips see a shield in stretches
    # 5-20 m apart): the next round looks on from there, while the curve still predicts the
    # wire there. Not where views see it but the wires beside it hide it: there the places
    # looked at narrow the search on those wires.
    unfixed: dict[tuple[int, int], float] = {}
    bias: dict[tuple[int, int], float] = {}
    along, _ = plan_axes(azimuth_deg)
    # How far along the line the measured wires reach.
    ends_along = np.concatenate(
        [w.points(np.array(w.s_range))[:, :2] @ along for w in wires + context]
    )
    measured = (float(ends_along.min()), float(ends_along.max()))
    reach = measured
    if primitives is not None and limits is None:
        # Taken where the matches run on farther than a support's in-line hardware would
        # (0.8 m on the package's span across the line, where the verified wires reach the
        # supports; 9.5 m of wire that only one strip sees on the shared cross seed 2, 4.9 m
        # up to tower B on cross seed 8): the rounds past the ends still have to pass the
        # bend and share tests there.
        matched = primitive_reach(wires, primitives, along, wires_options.inlier_distance)
        if matched is not None:
            reach = matched_reach(measured, matched)
    # Where the measured wires stop short of a support the verified points mark beyond them
    # (the pairs see too little of the wire there, or the detector lost it over the ground
    # there), the trace may go on up to it.
    marked = (
        support_reach(wires, pts_in_world, along, options.extend, measured)
        if limits is None
        else (None, None)
    )
    if marked[0] is not None or marked[1] is not None:
        logger.info(
            "trace: the measured wires reach %.1f..%.1f along the line; supports marked "
            "beyond them at %s",
            *measured,
            ", ".join("-" if m is None else f"{m:.1f}" for m in marked),
        )
    reach = (
        min(reach[0], marked[0]) if marked[0] is not None else reach[0],
        max(reach[1], marked[1]) if marked[1] is not None else reach[1],
    )

    # Each wire's vertical plane, continued one extension past the ends of the stretch the
    # views confirmed, leaves its own points by this much: what the bend test past an end
    # allows across the wire beside the statistical errors (measured once, so that what a
    # round took does not loosen the test for the next).
    model_error = [
        _continuation_error(w, pts_in_world[w.point_indices], options.extend) for w in wires
    ]

    def _past_unfixed(
        w: FittedWire, own: F64, k: int, skip: Sequence[bool] = (False, False)
    ) -> list[tuple[float, float]]:
        """The next extensions of wire ``k`` past a stretch of it fewer than three views
        see (``unfixed``), where its curve, continued, still predicts it within
        ``max_sigma`` (where the look lands): beyond, three may see it again."""
        first, last = w.s_at_along(along, limit_of(k))
        out = []
        for j in (0, 1):
            if skip[j] or (k, j) not in unfixed or len(own) == 0:
                continue
            e = unfixed[k, j]
            if j == 0:
                a, b = max(e - options.extend, first), e
            else:
                a, b = e, min(e + options.extend, last)
            if b - a < options.extend / 10:
                continue  # at the limit along the line
            # Where the look lands (the near end of the stretch it takes).
            sig_a, sig_z = _prediction_sigma(w, own, np.array([e]), corr)
            if np.hypot(sig_a[0], sig_z[0]) <= max_sigma:
                out.append((a, b))
        return out

    def limit_of(k: int) -> tuple[float, float]:
        """How far along the line wire ``k`` may be traced."""
        return reach if limits is None else limits[k]

    for round_ in range(options.max_rounds + 1):
        # Past the ends, the wires whose ends have stopped still make the places beside
        # them ambiguous: their whole curves are this round's context, but for where one
        # lies on a wire traced on (within the inlier distance: a piece of that wire).
        idle = [k for k, rs in enumerate(ranges) if not any(hi > lo for lo, hi in rs)]
        places = _places(
            wires,
            ranges,
            step,
            context + [wires[k] for k in idle],
            groups,
            None
            if groups is None
            else np.array([-1] * len(context) + [groups[k] for k in idle], np.int64),
            (len(context), wires_options.inlier_distance) if idle else None,
        )
        if places is None:
            break
        n_idle = len(idle)
        obs, dec = _look(
            scene,
            places,
            wire_mask,
            azimuth_deg,
            options.reach_px,
            num_threads,
            margin_px,
            detect,
            template_length_px,
        )
        decoded += dec
        # Past the ends, on the wires the views find, a peak that stands out will do too
        # (what it takes that is not the wire, the bend test below drops).
        sol = _measure(
            obs,
            places,
            tolerance_px,
            bias,
            np.r_[found, np.zeros(n_idle, bool)][places.wire] if found is not None else None,
        )
        if sigma_px is None:
            sigma_px = _image_noise(sol, tolerance_px)
        good, sigma = _kept(sol, sigma_px, max_sigma, min_redundancy)
        # Where the views would fix the wire (enough of them, crossing enough), had they all
        # found it: from the views' geometry alone, whatever they found.
        measurable = _measurable(sol, sigma_px, max_sigma)
        if round_ == 0:
            # The share of those places where they did (strict detection).
            share = _found_share(good, measurable, places.wire, len(wires))
            if options.loose:
                # On the wires the views find, within the stretch confirmed, a peak that
                # stands out will do.
                shown = np.zeros(len(wires), bool) if evident is None else np.asarray(evident)
                found = np.r_[
                    np.isnan(share) | (share >= MIN_TRACED_SHARE) | shown,
                    np.zeros(len(context), bool),
                ]
                sol = _measure(obs, places, tolerance_px, bias, found[places.wire])
                good, sigma = _kept(sol, sigma_px, max_sigma, min_redundancy)
                if shown.any():
                    share = np.where(
                        shown, _found_share(good, measurable, places.wire, len(wires)), share
                    )
        if min_redundancy <= 0:
            # On confirmed wires (not the second look, which asks every view to be checked
            # by the others), a place two views fix is checked by the wire's curve.
            by_curve, x, sigma = _checked_by_curve(
                sol,
                sigma,
                sigma_px,
                max_sigma,
                places,
                wires,
                all_pts,
                corr,
                model_error,
                wires_options.inlier_distance,
            )
            good |= by_curve
        else:
            x = sol.x
        if round_ == 0:
            base_share = _found_share(good, measurable, places.wire, len(wires))
        n_views = sol.n_views
        pts = places.pts + np.einsum("mi,mij->mj", np.where(good[:, None], x, 0.0), places.across)
        new_wires = list(wires)
        new_ranges: list[list[tuple[float, float]]] = []
        for k, w in enumerate(wires):
            # An end traced this round that the views found too seldom is on probation: its
            # points are kept while the next round finds the wire as it was; a second such
            # round in a row stops that end, and the points of both are dropped (a stretch
            # where the wire is hard to see, a road under it, is let pass once).
            weak: list[tuple[int, npt.NDArray[np.bool_]]] = []
            removed = np.zeros(0, np.int64)
            ends_found = _ends_found(w, k, places, good, measurable) if round_ > 0 else []
            for j, side, found_share in ends_found:
                # Too few places the views would fix (its share unjudged), and fewer than
                # three views see most of them at all (by the images' frames).
                if (
                    side.any()
                    and np.isnan(found_share)
                    and np.median(scene.visibility(places.pts[side]).sum(axis=0)) < MIN_VIEWS
                ):
                    s_side = w.plane_coords(places.pts[side])[0]
                    unfixed[k, j] = float(s_side.min() if j == 0 else s_side.max())
                else:
                    unfixed.pop((k, j), None)
                limit = MIN_EXTEND_SHARE * base_share[k]
                if np.isnan(found_share) or np.isnan(limit):
                    continue  # too few places to judge
                if found_share >= limit:
                    probation.pop((k, j), None)
                    continue
                logger.debug(
                    "trace round %d, wire %d: an end found at %.0f %% of its places (%.0f %% "
                    "along the wire): %s",
                    round_,
                    w.wire_id,
                    100 * found_share,
                    100 * base_share[k],
                    "stops" if (k, j) in probation else "on probation",
                )
                if (k, j) in probation:
                    good = good & ~side
                    removed = np.r_[removed, probation.pop((k, j))]
                else:
                    weak.append((j, side))
            mine = np.flatnonzero(good & (places.wire == k))
            if len(mine) == 0:
                if len(removed):
                    keep = w.point_indices[~np.isin(w.point_indices, removed)]
                    new_wires[k] = refit(w, all_pts, keep, along, wires_options)
                new_ranges.append(
                    _past_unfixed(new_wires[k], all_pts[new_wires[k].point_indices], k)
                    if round_ > 0
                    else []
                )
                continue
            base = len(all_pts)
            all_pts = np.r_[all_pts, pts[mine]]
            out_wire.append(np.full(len(mine), w.wire_id, np.int64))
            out_views.append(n_views[mine])
            out_sigma.append(sigma[mine])
            idx = np.r_[w.point_indices, base + np.arange(len(mine))]
            if round_ > 0:
                # Points past an end that leave the curve continued are not the wire's.
                s_new = w.plane_coords(pts[mine])[0]
                own = all_pts[w.point_indices]
                drop = np.zeros(len(mine), bool)
                for side in (s_new < w.s_range[0], s_new > w.s_range[1]):
                    if side.sum() >= corr and (
                        _leaves_curve(
                            w, own, pts[mine][side], sigma[mine][side], corr, model_error[k]
                        )
                        > MAX_BEND
                    ):
                        drop |= side
                idx = np.r_[w.point_indices, base + np.flatnonzero(~drop)]
                idx = idx[~np.isin(idx, removed)]
                for j, side in weak:
                    probation[k, j] = np.intersect1d(base + np.flatnonzero(side[mine]), idx)
            fit = refit(w, all_pts, idx, along, wires_options)
            lo, hi = fit.s_range
            # An end goes on while the views found the wire over most of the last extension,
            # up to where the measured wires reach along the line (their supports: past
            # them, the insulators, arms and the next span's wires).
            first, last = fit.s_at_along(along, limit_of(k))
            ends = []
            grew = [
                round_ == 0 or lo < w.s_range[0] - options.extend / 2,
                round_ == 0 or hi > w.s_range[1] + options.extend / 2,
            ]
            if grew[0]:
                ends.append((max(lo - options.extend, first), lo))
            if grew[1]:
                ends.append((hi, min(hi + options.extend, last)))
            ends += _past_unfixed(fit, all_pts[idx], k, skip=grew)
            new_ranges.append(ends)
            new_wires[k] = fit
            if round_ > 0 and logger.isEnabledFor(logging.DEBUG):
                logger.debug(
                    "trace round %d, wire %d: %d of %d places measured; s %.1f..%.1f -> "
                    "%.1f..%.1f, next %s",
                    round_,
                    w.wire_id,
                    len(mine),
                    int((places.wire == k).sum()),
                    *w.s_range,
                    lo,
                    hi,
                    [(round(a, 1), round(b, 1)) for a, b in ends],
                )
        logger.info(
            "trace round %d: %d of %d places measured (%d seen by two views or more)",
            round_,
            int(good.sum()),
            len(good),
            int(np.isfinite(x[:, 0]).sum()),
        )
        wires = new_wires
        ranges = new_ranges
        if options.extend == 0:
            break
    # A last round on probation is not followed by one that finds the wire: its points go.
    for k in sorted({k for k, _ in probation}):
        gone = np.concatenate([v for (i, _), v in probation.items() if i == k])
        w = wires[k]
        wires[k] = refit(
            w, all_pts, w.point_indices[~np.isin(w.point_indices, gone)], along, wires_options
        )
    # The traced points are those the refitted wires keep (within their inlier distance of
    # the curve: not a place past a support where another curve goes on), in wire order.
    n0 = len(pts_in_world)
    used = np.unique(np.concatenate([w.point_indices[w.point_indices >= n0] for w in wires]))
    remap = np.full(len(all_pts), -1, np.int64)
    remap[:n0] = np.arange(n0)
    remap[used] = n0 + np.arange(len(used))
    wires = [dataclasses.replace(w, point_indices=remap[w.point_indices]) for w in wires]
    rows = used - n0
    traced = TracedPoints(
        all_pts[used],
        np.concatenate(out_wire)[rows] if out_wire else np.zeros(0, np.int64),
        np.concatenate(out_views)[rows] if out_views else np.zeros(0, np.int32),
        np.concatenate(out_sigma)[rows] if out_sigma else np.zeros(0),
        decoded,
        share,
    )
    logger.info(
        "trace: %d points measured along %d wires in %.1f s; share of the places the views "
        "would fix where they found the wire: %s",
        len(traced),
        len(wires),
        time.perf_counter() - t0,
        np.round(share, 2).tolist(),
    )
    return wires, traced
