"""Lines and markers of the run's plots, drawn with Pillow (:mod:`.raster` lays the
figures out): solid, dashed, dash-dotted and dotted polylines, held steps, markers, in
pixels of a drawing :data:`SCALE` times the PNG's size."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from PIL import Image, ImageDraw

#: the PNGs' resolution, dots per inch (a point is DPI/72 px)
DPI = 110
#: drawn this many times larger, then reduced: the anti-aliasing
SCALE = 2
#: lines at least this opaque are drawn straight on, their colour blended over white
OPAQUE = 0.85
#: dash patterns in line widths (on, off, ...), as matplotlib's
DASHES = {"dashed": (3.7, 1.6), "dashdot": (6.4, 1.6, 1.0, 1.6), "dotted": (1.0, 1.65)}


class RenderError(ValueError):
    """A spec that cannot be drawn (no panels, an unknown layout, bad limits)."""


def pt_px(pt: float) -> float:
    """Points -> pixels of the drawing (SCALE times the PNG's)."""
    return pt * DPI / 72.0 * SCALE


def _rgb(color: str) -> tuple[int, int, int]:
    color = color.lstrip("#")
    if len(color) != 6:
        raise RenderError(f"colour {color!r}: expected #rrggbb")
    return int(color[0:2], 16), int(color[2:4], 16), int(color[4:6], 16)


def over_white(rgb: tuple[int, int, int], alpha: float) -> tuple[int, int, int]:
    """``rgb`` at ``alpha`` over white."""
    return tuple(round(255 - alpha * (255 - c)) for c in rgb)  # type: ignore[return-value]


def _pieces(x: np.ndarray, y: np.ndarray) -> list[np.ndarray]:
    """The finite runs of a polyline, as (n, 2) arrays of pixel points."""
    ok = np.isfinite(x) & np.isfinite(y)
    pts = np.column_stack([x, y])
    if ok.all():
        return [pts]
    edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(np.int8), [0]])))
    return [pts[a:b] for a, b in zip(edges[::2], edges[1::2], strict=True)]


def _dashes(pts: np.ndarray, pattern: Sequence[float]) -> list[np.ndarray]:
    """The "on" stretches of a polyline (pixels) under a dash pattern (pixels)."""
    seg = np.hypot(*np.diff(pts, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    period = float(sum(pattern))
    if s[-1] <= 0 or period <= 0:
        return [pts]
    starts = np.cumsum([0.0, *pattern[:-1]])
    n = int(s[-1] // period) + 1
    bounds = (np.arange(n)[:, None] * period + starts[None, :]).ravel()
    cuts = np.union1d(s, bounds[bounds < s[-1]])
    xy = np.column_stack([np.interp(cuts, s, pts[:, 0]), np.interp(cuts, s, pts[:, 1])])
    mid = 0.5 * (cuts[:-1] + cuts[1:])
    on = np.searchsorted(starts, np.mod(mid, period), side="right") % 2 == 1
    change = np.flatnonzero(np.diff(np.concatenate([[0], on.astype(np.int8), [0]])))
    return [xy[a : b + 1] for a, b in zip(change[::2], change[1::2], strict=True)]


def _steps(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A held (``where="post"``) step line's corners."""
    xs = np.repeat(x, 2)[1:]
    ys = np.repeat(y, 2)[:-1]
    return xs, ys


def _marker_shape(marker: str, cx: float, cy: float, r: float) -> tuple[str, Any]:
    if marker == "D":
        return "polygon", [(cx, cy - r), (cx + r, cy), (cx, cy + r), (cx - r, cy)]
    if marker == "X":
        a, b = r, r * 0.35
        pts = [
            (-a + b, -a),
            (0, -b * 1.4),
            (a - b, -a),
            (a, -a + b),
            (b * 1.4, 0),
            (a, a - b),
            (a - b, a),
            (0, b * 1.4),
            (-a + b, a),
            (-a, a - b),
            (-b * 1.4, 0),
            (-a, -a + b),
        ]
        return "polygon", [(cx + u, cy + v) for u, v in pts]
    return "ellipse", [cx - r, cy - r, cx + r, cy + r]


class _Layer:
    """Where one line draws. Opaque (alpha at least :data:`OPAQUE`): straight onto the
    panel, in its colour over white. Translucent: into a coverage mask, put on the panel
    once in its colour and alpha (overlaps within a line are not darkened twice), only
    within the mask's bounding box."""

    def __init__(self, onto: Image.Image, rgb: tuple[int, int, int], alpha: float) -> None:
        self.onto, self.rgb, self.alpha = onto, rgb, alpha
        self.opaque = alpha >= OPAQUE
        if self.opaque:
            self.mask = onto
            self.ink: Any = over_white(rgb, alpha)
        else:
            self.mask = Image.new("L", onto.size, 0)
            self.ink = 255
        self.draw = ImageDraw.Draw(self.mask)

    def put(self) -> None:
        if self.opaque:
            return
        box = self.mask.getbbox()
        if box is None:
            return
        mask = self.mask.crop(box).point([round(v * self.alpha) for v in range(256)])
        self.onto.paste(self.rgb, box, mask)


def _stroke(layer: _Layer, pts: np.ndarray, width: float) -> None:
    if len(pts) == 1:
        pts = np.vstack([pts, pts])
    # round joints only where the corners are far apart (a run's lines have a point
    # every fraction of a pixel: there they would cost 40% of the drawing, unseen)
    sparse = width > 2.5 and len(pts) * 4 < np.abs(np.diff(pts, axis=0)).sum()
    layer.draw.line(pts.ravel().tolist(), fill=layer.ink, width=max(1, round(width)),
                    joint="curve" if sparse else None)  # fmt: skip


def draw_line(panel: Image.Image, line: dict[str, Any], x: np.ndarray, y: np.ndarray) -> None:
    """Draw one line spec (``x``/``y`` in the panel's pixels) on ``panel``."""
    rgb = _rgb(line["color"])
    alpha = float(line.get("alpha", 1.0))
    layer = _Layer(panel, rgb, alpha)
    if line.get("step"):
        x, y = _steps(x, y)
    lim = 4.0 * max(panel.size)
    x, y = np.clip(x, -lim, lim), np.clip(y, -lim, lim)
    width = pt_px(float(line.get("width", 1.0)))
    if line.get("lines", True):
        pattern = DASHES.get(line.get("dash", "solid"))
        for piece in _pieces(x, y):
            parts = _dashes(piece, [p * width for p in pattern]) if pattern else [piece]
            for part in parts:
                _stroke(layer, part, width)
    marker = line.get("marker", "")
    if marker:
        r = max(0.75, pt_px(float(line.get("size", 6.0))) / 2)
        ok = np.isfinite(x) & np.isfinite(y)
        if marker == "." and ok.sum() > 50:  # many small dots: stamped with numpy
            _dots(layer, x[ok], y[ok], r)
        else:
            for cx, cy in zip(x[ok], y[ok], strict=True):
                kind, shape = _marker_shape(marker, float(cx), float(cy), r)
                getattr(layer.draw, kind)(shape, fill=layer.ink)
    layer.put()


def _dots(layer: _Layer, x: np.ndarray, y: np.ndarray, r: float) -> None:
    """Round dots of radius ``r`` px at every point, stamped at once with numpy."""
    w, h = layer.mask.size
    mask = np.zeros((h, w), dtype=np.uint8)
    xi, yi = np.rint(x).astype(int), np.rint(y).astype(int)
    reach = math.ceil(r)
    for dy in range(-reach, reach + 1):
        for dx in range(-reach, reach + 1):
            if dx * dx + dy * dy <= r * r + 0.5:
                px, py = xi + dx, yi + dy
                inside = (px >= 0) & (px < w) & (py >= 0) & (py < h)
                mask[py[inside], px[inside]] = 255
    if layer.opaque:
        layer.onto.paste(layer.ink, (0, 0), Image.fromarray(mask, "L"))
    else:
        layer.mask = Image.fromarray(np.maximum(np.asarray(layer.mask), mask), "L")
        layer.draw = ImageDraw.Draw(layer.mask)
