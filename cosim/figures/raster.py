"""A run's PNG plots drawn from their specs with Pillow, without matplotlib.

A spec (:mod:`.spec`) says what a figure shows: its panels, each with its limits,
labels and lines (series, equilibrium and event lines, markers), in data units; the
same spec is what ``plots.html`` draws (:mod:`.pages`). :func:`render_png` lays it out
as the run's matplotlib figures were (DejaVu Sans, 110 dpi, the same margins, ticks,
grid, legends and line styles) and draws it at twice the size, then halves it: the
halving is the anti-aliasing.

Why not matplotlib: importing it takes 0.55-0.63 s on our 2-core machine, more than a
whole native run without plots (0.43 s), so a run with plots could not stay within
1.5x of one without (issue 31). Pillow imports in 0.13-0.17 s and draws a figure here
in a few milliseconds.
"""

from __future__ import annotations

import functools
import importlib.util
import math
import struct
import zlib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from .spec import figure, line, panel
from .strokes import DASHES, DPI, SCALE, RenderError, draw_line, over_white, pt_px

__all__ = ["DPI", "RenderError", "font", "layout", "nice_ticks", "png_bytes", "render",
           "render_png", "tick_labels", "warm"]  # fmt: skip

#: zlib level of the PNGs: 1 writes in a third of the time of the default 6
PNG_COMPRESS_LEVEL = 1
#: font sizes, points: tick labels and axis labels, axes titles, legends, subtitles
FONT_PT, TITLE_PT = 10.0, 12.0
_GRID = (0xB0, 0xB0, 0xB0)
_TICK_PT, _TICK_PAD_PT, _LABEL_PAD_PT, _TITLE_PAD_PT = 3.5, 3.5, 4.0, 6.0
_MINUS = "\N{MINUS SIGN}"


@functools.cache
def font(size_pt: float) -> Any:
    """DejaVu Sans (matplotlib's font, read from its installed data; matplotlib is not
    imported) at ``size_pt`` for the drawing; Pillow's own font if it is missing."""
    size = max(1, round(pt_px(size_pt)))
    spec = importlib.util.find_spec("matplotlib")
    for folder in spec.submodule_search_locations or () if spec else ():
        path = Path(folder) / "mpl-data" / "fonts" / "ttf" / "DejaVuSans.ttf"
        if path.is_file():
            return ImageFont.truetype(str(path), size)
    return ImageFont.load_default(size)


def warm() -> None:
    """Draw a figure the size of the largest plot with every kind of line, marker, legend
    and text the plots use, each character at each font size, and encode it (the drawing
    process, while the run runs): a process's first plot took 15-35 ms longer than the
    next ones (the allocator then mapped fresh memory for the images, and first calls),
    and a partner forked afterwards inherits what this warmed."""
    t = np.linspace(0.0, 1.0, 50)
    y = np.sin(6.0 * t)
    lines = [line(t, y, "a", dash=dash, width=1.4, step=dash == "dashed")
             for dash in ("solid", *DASHES)]  # fmt: skip
    lines += [line(t, y, "b", marker=m, alpha=a, size=7.0)
              for m, a in ((".", 0.3), ("o", 1.0), ("D", 1.0), ("X", 1.0))]  # fmt: skip
    lines.append(line([0.5], [0.0], "c", color="k", dash="dotted", alpha=0.3, span="x"))
    spec = figure("pair", [panel(lines, title="(0)", ylabel="y"),
                           panel(lines, xlabel="x", ylabel="y", row=1)], "s")  # fmt: skip
    png_bytes(render(spec), {"k": "v"})
    scratch = ImageDraw.Draw(Image.new("L", (8, 8)))
    chars = "".join(map(chr, range(32, 127))) + _MINUS
    for size in (FONT_PT, TITLE_PT, 7.0, 7.5):
        scratch.text((0, 0), chars, font=font(size), anchor="lt")


# ------------------------------------------------------------------ ticks and labels
def nice_ticks(lo: float, hi: float, nbins: int) -> np.ndarray:
    """At most ``nbins + 1`` ticks at a multiple of 1, 2, 2.5 or 5 times a power of ten
    within ``[lo, hi]`` (matplotlib's ``MaxNLocator`` steps)."""
    if not math.isfinite(hi - lo) or hi <= lo:  # (lo or hi not finite, or too far apart)
        raise RenderError(f"axis limits [{lo}, {hi}]: expected finite, increasing limits")
    raw = (hi - lo) / max(1, nbins)
    scale = 10.0 ** math.floor(math.log10(raw))
    for step in (1.0, 2.0, 2.5, 5.0, 10.0, 20.0):
        step *= scale
        first = math.ceil(lo / step - 1e-9)
        last = math.floor(hi / step + 1e-9)
        if last - first <= nbins:
            return np.arange(first, last + 1) * step
    return np.array([lo, hi])  # not reached: 20 * scale > (hi - lo) / nbins * 2


def tick_labels(ticks: np.ndarray) -> list[str]:
    """Labels with as many decimals as tell the ticks apart (all the same count), a
    minus sign, and an exponent for very large or small values."""
    if not len(ticks):
        return []
    step = float(np.min(np.diff(ticks))) if len(ticks) > 1 else abs(float(ticks[0])) or 1.0
    big = float(np.max(np.abs(ticks)))
    if big >= 1e5 or 0 < big < 1e-3:
        apart = (d for d in range(1, 17) if len({f"{v:.{d}e}" for v in ticks}) == len(ticks))
        digits = next(apart, 16)
        text = [f"{v:.{digits}e}" for v in ticks]
    else:
        exact = (d for d in range(16) if np.all(np.abs(np.round(ticks, d) - ticks) < step * 1e-6))
        decimals = next(exact, 15)
        text = [f"{0.0 if abs(v) < step * 1e-9 else v:.{decimals}f}" for v in ticks]
    return [s.replace("-", _MINUS) for s in text]


# ------------------------------------------------------------------ layout and text
def _text(draw: Any, xy: tuple[float, float], text: str, size_pt: float, anchor: str,
          fill: tuple[int, int, int] = (0, 0, 0)) -> None:  # fmt: skip
    draw.text(xy, text, font=font(size_pt), fill=fill, anchor=anchor)


def _text_width(text: str, size_pt: float) -> float:
    return float(font(size_pt).getlength(text))


def _vertical_text(im: Image.Image, text: str, size_pt: float, right: float, middle: float) -> None:
    """``text`` turned a quarter left, its right edge at ``right``, centred on ``middle``."""
    f = font(size_pt)
    left, top, r, bottom = f.getbbox(text, anchor="ls")
    strip = Image.new("L", (math.ceil(r - left) + 2, math.ceil(bottom - top) + 2), 0)
    ImageDraw.Draw(strip).text((1 - left, 1 - top), text, font=f, fill=255, anchor="ls")
    strip = strip.transpose(Image.Transpose.ROTATE_90)
    im.paste((0, 0, 0), (round(right - strip.width), round(middle - strip.height / 2)), strip)


def _panel_boxes(spec: dict[str, Any], size: tuple[int, int], left: float) -> list[tuple]:
    """Each panel's box ``(x0, y0, x1, y1)`` in the drawing's pixels."""
    w, h = size
    m = spec["margins"]
    x0, x1 = left * w, m["right"] * w
    top, bottom = (1 - m["top"]) * h, (1 - m["bottom"]) * h
    ratios = [float(r) for r in spec.get("height_ratios") or [1.0] * len(spec["panels"])]
    n = len(ratios)
    if n != len(spec["panels"]):
        raise RenderError(f"{n} height ratios for {len(spec['panels'])} panels")
    cell = (bottom - top) / (n + m.get("hspace", 0.0) * (n - 1))
    gap = m.get("hspace", 0.0) * cell
    boxes, y = [], top
    for r in ratios:
        height = n * cell * r / sum(ratios)
        boxes.append((x0, y, x1, y + height))
        y += height + gap
    return boxes


def _left_margin(spec: dict[str, Any], width: float, labels: list[list[str]]) -> float:
    """The left margin (figure fraction) wide enough for the widest y tick label, the
    ticks and the y label."""
    widest = max((_text_width(s, FONT_PT) for ls in labels for s in ls), default=0.0)
    need = (
        widest + pt_px(_TICK_PT + _TICK_PAD_PT + _LABEL_PAD_PT) + pt_px(FONT_PT) * 1.2 + 8 * SCALE
    )
    return max(spec["margins"]["left"], min(0.3, need / width))


def _nbins(length_px: float, per_tick_pt: float) -> int:
    return max(3, min(9, int(length_px / pt_px(per_tick_pt))))


def _ticks(lim: Sequence[float], nbins: int) -> np.ndarray:
    return nice_ticks(float(lim[0]), float(lim[1]), nbins)


def _y_ticks(p: dict[str, Any], height_px: float) -> np.ndarray:
    """A panel's y ticks for its box's height: one rule for the margin (:func:`layout`)
    and the drawing (:func:`_draw_panel`), so the margin fits the labels drawn."""
    return _ticks(p["ylim"], _nbins(round(height_px), 2 * FONT_PT))


def _to_px(v: np.ndarray, lim: Sequence[float], length: float, flip: bool) -> np.ndarray:
    lo, hi = lim
    f = (np.asarray(v, dtype=float) - lo) / (hi - lo)
    return (1.0 - f if flip else f) * length


# ------------------------------------------------------------------ legend
def _legend_entries(panel: dict[str, Any]) -> list[dict[str, Any]]:
    return [ln for ln in panel["lines"] if ln.get("legend")]


def _legend_box(
    entries: list[dict[str, Any]], box: tuple, size_pt: float, points: list[np.ndarray]
) -> tuple[float, float, float, float]:
    """Where the legend goes: of matplotlib's places ("best"), the first covering the
    fewest data points; ``points`` are the panel's in drawing pixels."""
    em = pt_px(size_pt)
    width = max(_text_width(e["name"], size_pt) for e in entries) + 2.0 * em + 0.8 * em + 0.8 * em
    height = len(entries) * 1.3 * em + 0.6 * em
    x0, y0, x1, y1 = box
    pad = 0.5 * em
    xs = {"l": x0 + pad, "c": (x0 + x1 - width) / 2, "r": x1 - pad - width}
    ys = {"u": y0 + pad, "c": (y0 + y1 - height) / 2, "d": y1 - pad - height}
    order = ("ur", "ul", "dl", "dr", "cr", "cl", "dc", "uc", "cc")
    best, where = None, (xs["r"], ys["u"])
    for place in order:
        lx, ly = xs[place[1]], ys[place[0]]
        covered = sum(int(np.count_nonzero((p[:, 0] >= lx) & (p[:, 0] <= lx + width)
                                           & (p[:, 1] >= ly) & (p[:, 1] <= ly + height)))
                      for p in points)  # fmt: skip
        if best is None or covered < best:
            best, where = covered, (lx, ly)
        if covered == 0:
            break
    return where[0], where[1], width, height


#: how opaque a legend's background is (matplotlib's ``framealpha``): what it covers shows
LEGEND_ALPHA = 0.8


def _draw_legend(im: Image.Image, entries: list[dict[str, Any]], at: tuple, size_pt: float) -> None:
    lx, ly, width, height = at
    em = pt_px(size_pt)
    box = (round(lx), round(ly), round(lx + width) + 1, round(ly + height) + 1)
    white = Image.new("RGB", (box[2] - box[0], box[3] - box[1]), (255, 255, 255))
    legend = Image.blend(im.crop(box), white, LEGEND_ALPHA)
    draw = ImageDraw.Draw(legend)
    draw.rounded_rectangle([0, 0, legend.width - 1, legend.height - 1], radius=0.2 * em,
                           outline=(0xCC, 0xCC, 0xCC), width=max(1, round(pt_px(0.8))))  # fmt: skip
    for k, e in enumerate(entries):
        cy = 0.3 * em + (k + 0.5) * 1.3 * em
        spot = (round(0.4 * em), round(cy - 0.65 * em), round(2.4 * em) + 2, round(cy + 0.65 * em))
        handle = legend.crop(spot)
        hy = handle.height / 2
        sample = {**e, "step": False}
        if e.get("lines", True):
            draw_line(handle, sample, np.array([1.0, handle.width - 1.0]), np.array([hy, hy]))
        if e.get("marker"):  # markerscale 4 for tiny dots, as the run's legends had
            scale = 4.0 if e["marker"] == "." else 1.0
            mark = {**sample, "lines": False, "size": float(e.get("size", 6.0)) * scale,
                    "alpha": max(0.6, float(e.get("alpha", 1.0)))}  # fmt: skip
            draw_line(handle, mark, np.array([handle.width / 2]), np.array([hy]))
        legend.paste(handle, spot[:2])
        _text(draw, (3.2 * em, cy), e["name"], size_pt, "lm")
    im.paste(legend, box[:2])


# ------------------------------------------------------------------ the figure
def layout(spec: dict[str, Any]) -> tuple[tuple[int, int], list[tuple[float, ...]]]:
    """The drawing's size and each panel's box ``(x0, y0, x1, y1)``, in pixels of the
    drawing (:data:`SCALE` times the PNG's). The left margin follows the widest y tick
    label; the panels' heights do not depend on it."""
    panels = spec.get("panels") or []
    if not panels:
        raise RenderError(f"figure {spec.get('title', '')!r}: no panels; expected at least one")
    w_in, h_in = spec["size_in"]
    size = (round(w_in * DPI) * SCALE, round(h_in * DPI) * SCALE)
    heights = [b[3] - b[1] for b in _panel_boxes(spec, size, spec["margins"]["left"])]
    labels = [tick_labels(_y_ticks(p, h)) for p, h in zip(panels, heights, strict=True)]
    return size, _panel_boxes(spec, size, _left_margin(spec, size[0], labels))


def render(spec: dict[str, Any]) -> Image.Image:
    """The figure of ``spec`` (:mod:`.spec`), an RGB image at :data:`DPI`."""
    size, boxes = layout(spec)
    im = Image.new("RGB", size, (255, 255, 255))
    draw = ImageDraw.Draw(im)
    panels = spec["panels"]
    for k, (p, box) in enumerate(zip(panels, boxes, strict=True)):
        _draw_panel(im, draw, p, box, last=k == len(panels) - 1)
    if spec.get("suptitle"):
        _text(draw, (size[0] / 2, 0.02 * size[1]), spec["suptitle"], 7.5, "mt", (77, 77, 77))
    return im.reduce(SCALE)


def _draw_panel(im: Image.Image, draw: Any, p: dict[str, Any], box: tuple, last: bool) -> None:
    x0, y0, x1, y1 = box
    aw, ah = round(x1 - x0), round(y1 - y0)
    panel = Image.new("RGB", (aw, ah), (255, 255, 255))
    flip_y = not p.get("inverted", False)
    xt = _ticks(p["xlim"], _nbins(aw, 3 * FONT_PT))
    yt = _y_ticks(p, ah)
    xpx = _to_px(xt, p["xlim"], aw, False)
    ypx = _to_px(yt, p["ylim"], ah, flip_y)
    pd = ImageDraw.Draw(panel)
    grid = over_white(_GRID, 0.3)
    gw = max(1, round(pt_px(0.8)))
    for v in xpx:
        pd.line([v, 0, v, ah], fill=grid, width=gw)
    for v in ypx:
        pd.line([0, v, aw, v], fill=grid, width=gw)
    points = []
    for ln in p["lines"]:
        lx = _to_px(ln["x"], p["xlim"], aw, False)
        ly = _to_px(ln["y"], p["ylim"], ah, flip_y)
        draw_line(panel, ln, lx, ly)
        if ln.get("span"):  # an event or equilibrium line: a point every 2 px of it, as
            # dense as a series (the legend then keeps off it as off the data)
            n = max(2, int(abs(lx[-1] - lx[0]) + abs(ly[-1] - ly[0])) // (2 * SCALE))
            points.append(np.column_stack([np.linspace(lx[0], lx[-1], n),
                                           np.linspace(ly[0], ly[-1], n)]) + (x0, y0))  # fmt: skip
        else:
            points.append(np.column_stack([lx, ly])[:: max(1, len(lx) // 1000)] + (x0, y0))
    im.paste(panel, (round(x0), round(y0)))
    lw = max(1, round(pt_px(0.8)))
    draw.rectangle([round(x0) - lw // 2, round(y0) - lw // 2, round(x0) + aw, round(y0) + ah],
                   outline=(0, 0, 0), width=lw)  # fmt: skip
    tick = pt_px(_TICK_PT)
    pad = pt_px(_TICK_PAD_PT)
    em = pt_px(FONT_PT)
    for v, text in zip(xpx, tick_labels(xt), strict=True):
        draw.line([x0 + v, y1, x0 + v, y1 + tick], fill=(0, 0, 0), width=lw)
        if last:
            _text(draw, (x0 + v, y1 + tick + pad), text, FONT_PT, "mt")
    widest = 0.0
    for v, text in zip(ypx, tick_labels(yt), strict=True):
        draw.line([x0 - tick, y0 + v, x0, y0 + v], fill=(0, 0, 0), width=lw)
        _text(draw, (x0 - tick - pad, y0 + v), text, FONT_PT, "rm")
        widest = max(widest, _text_width(text, FONT_PT))
    if p.get("ylabel"):
        _vertical_text(im, p["ylabel"], FONT_PT, x0 - tick - pad - widest - pt_px(_LABEL_PAD_PT),
                       (y0 + y1) / 2)  # fmt: skip
    if last and p.get("xlabel"):
        _text(draw, ((x0 + x1) / 2, y1 + tick + pad + 1.2 * em + pt_px(_LABEL_PAD_PT)),
              p["xlabel"], FONT_PT, "mt")  # fmt: skip
    if p.get("title"):
        _text(draw, ((x0 + x1) / 2, y0 - pt_px(_TITLE_PAD_PT)), p["title"], TITLE_PT, "md")
    entries = _legend_entries(p)
    if entries:
        size_pt = float(p.get("legend_pt", 7.0))
        _draw_legend(im, entries, _legend_box(entries, box, size_pt, points), size_pt)


def png_bytes(image: Image.Image, metadata: dict[str, str]) -> bytes:
    """``image`` (RGB) as a PNG: its rows unfiltered, deflated at
    :data:`PNG_COMPRESS_LEVEL`, its resolution (:data:`DPI`) and ``metadata`` as iTXt
    chunks. Half the time of Pillow's encoder, which tries every row filter (3 against
    7 ms a two-panel plot here); the files are about a fifth larger."""
    if image.mode != "RGB":
        raise RenderError(f"image mode {image.mode!r}: expected 'RGB'")
    pixels = np.asarray(image)
    h, w = pixels.shape[:2]
    rows = np.zeros((h, 1 + 3 * w), dtype=np.uint8)  # filter byte 0 (none) on each row
    rows[:, 1:] = pixels.reshape(h, 3 * w)
    per_metre = round(DPI / 0.0254)
    chunks = [(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)),
              (b"pHYs", struct.pack(">IIB", per_metre, per_metre, 1))]  # fmt: skip
    for key, value in metadata.items():  # keyword, no compression, no language
        chunks.append((b"iTXt", key.encode("latin-1") + b"\0\0\0\0\0" + value.encode("utf-8")))
    chunks += [(b"IDAT", zlib.compress(rows.tobytes(), PNG_COMPRESS_LEVEL)), (b"IEND", b"")]
    out = [b"\x89PNG\r\n\x1a\n"]
    for kind, data in chunks:
        crc = zlib.crc32(kind + data)
        out += [struct.pack(">I", len(data)), kind, data, struct.pack(">I", crc)]
    return b"".join(out)


def render_png(spec: dict[str, Any], path: Path, metadata: dict[str, str]) -> Path:
    """Draw ``spec`` into the PNG ``path`` with ``metadata`` as its text chunks; the file
    is complete or absent (written beside it, then renamed)."""
    data = png_bytes(render(spec), metadata)
    part = path.with_name(path.name + ".part")
    try:
        part.write_bytes(data)
        part.replace(path)
    finally:
        part.unlink(missing_ok=True)
    return path
