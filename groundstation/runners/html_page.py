"""The pieces every self-contained floe HTML page shares (``gcs report``, the campaign
report): a figure rendered to PNG bytes, the page's style, and a figure embedded as a
``data:image/png;base64`` URI so the page stands alone (no external asset, mailable,
archivable). Also the one axis style every floe figure shares, ``gcs simulate``'s PNGs too:
a log axis labelled in plain text (:func:`plain_log_axis`).
"""

from __future__ import annotations

import base64
import html
import io
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # matplotlib is imported where a figure is drawn (its plot modules)
    from matplotlib.axis import Axis
    from matplotlib.figure import Figure

__all__ = [
    "DPI",
    "PAGE_CSS",
    "FigurePng",
    "decade_label",
    "figure_html",
    "page_start",
    "plain_log_axis",
    "render_png",
]

DPI = 100
"""Resolution of every embedded figure (dots per inch of its ``figsize``)."""

PAGE_CSS = """
body { font-family: sans-serif; margin: 1.5em auto; max-width: 1100px; color: #222; }
h1 { font-size: 1.4em; } h2 { font-size: 1.15em; margin-top: 1.6em; }
table { border-collapse: collapse; font-size: 0.9em; }
td, th { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: left; vertical-align: top; }
th { background: #f0f0f0; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
figure { margin: 1em 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.85em; color: #555; }
.warn { color: #a40; }
"""


@dataclass
class FigurePng:
    """One rendered figure: ``name`` (an id, also the PNG's file name), ``title`` (its
    heading and ``alt`` text), the PNG bytes and what it shows (``info``, for checks)."""

    name: str
    title: str
    png: bytes
    info: dict[str, Any] = field(default_factory=dict)


def render_png(fig: Figure, dpi: int = DPI) -> bytes:
    """The PNG bytes of a matplotlib figure built with the object API (Agg canvas; no
    pyplot, no global state)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def page_start(title: str, heading: str) -> list[str]:
    """The lines that open a page: doctype, ``<title>``, the shared style, ``<h1>``."""
    esc = html.escape
    return [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{esc(title)}</title>",
        f"<style>{PAGE_CSS}</style>",
        "</head><body>",
        f"<h1>{esc(heading)}</h1>",
    ]


def figure_html(fig: FigurePng, attrs: str = "", caption: str = "") -> str:
    """``<h2>`` + ``<figure id="fig-NAME">`` with the PNG inline as a data URI; ``attrs``
    (already escaped, with a leading space) go on the ``<img>``, ``caption`` (plain text)
    under it."""
    esc = html.escape
    b64 = base64.b64encode(fig.png).decode("ascii")
    tail = f"<figcaption>{esc(caption)}</figcaption>" if caption else ""
    return (
        f'<h2>{esc(fig.title)}</h2><figure id="fig-{esc(fig.name)}">'
        f'<img alt="{esc(fig.title)}" src="data:image/png;base64,{b64}"{attrs}>'
        f"{tail}</figure>"
    )


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def decade_label(value: float, _position: int | None = None) -> str:
    """A log axis's tick label in plain text: ``10³`` for 1000, ``10⁻²`` for
    0.01, and ``""`` for a value that is not a power of ten (a minor tick).

    The value is a decade when ``|value / 10**round(log10(value)) - 1| <= 1e-9``."""
    if not (value > 0.0 and math.isfinite(value)):
        return ""
    exponent = round(math.log10(value))
    if not math.isclose(value, 10.0**exponent, rel_tol=1e-9):
        return ""
    return "10" + str(exponent).translate(_SUPERSCRIPT)


def plain_log_axis(axis: Axis) -> None:
    """Label a log-scaled ``axis`` at its decades with :func:`decade_label`, minor ticks
    unlabelled. Matplotlib's own log labels are mathtext (``$\\mathdefault{10^{3}}$``), each
    parsed by its pyparsing grammar; Unicode superscripts, which matplotlib's DejaVu Sans
    draws, give the same label as plain text. Meant for an axis spanning several decades
    (an uncertainty from below 1 m² to the FOV's square), where matplotlib labels no minor
    tick either; an axis that may show less than a decade keeps matplotlib's labels."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    axis.set_major_formatter(FuncFormatter(decade_label))
    axis.set_minor_formatter(NullFormatter())
