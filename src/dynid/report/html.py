"""A self-contained HTML report: HTML tables (sortable by a few lines of inline script), paragraphs and PNG
figures embedded as base64, one file with no external asset; a print style sheet.

Any screen, 390 CSS px (a phone) to a desktop: the page is never wider than the window. The contents line wraps;
a table wider than the page scrolls sideways inside its own box, its first column (the name) and its pinned ones
(the estimate; a car's corner and quantity) kept in view; a figure is shown at its drawn size (its PNG's
resolution, 96 CSS px an inch), shrunk to the page down to 85 % of it, and scrolls sideways in its own box on a
narrower screen rather than shrinking until its text cannot be read."""

from __future__ import annotations

import base64
import html
import struct
from collections.abc import Sequence
from dataclasses import dataclass, field


@dataclass(frozen=True)
class Cell:
    """A table cell: its text, the number it sorts by (None: sorted as text), a tooltip and a CSS class."""

    text: str
    sort: float | None = None
    title: str = ""
    cls: str = ""


@dataclass(frozen=True)
class Table:
    """A table: column heads (with a tooltip each, optional), rows of cells or plain strings, a caption."""

    head: Sequence[str]
    rows: Sequence[Sequence[Cell | str]]
    caption: str = ""
    tips: Sequence[str] = ()
    cls: str = ""
    sortable: bool = True
    # the heads of the columns kept in view beside the first when the table scrolls sideways (absent ones ignored)
    pin: Sequence[str] = ("estimate",)


@dataclass(frozen=True)
class Section:
    """A heading with paragraphs of text (blank-line separated; each line of a paragraph kept), ready HTML
    (tables...), and figures (PNG bytes with captions)."""

    heading: str
    text: str = ""
    figures: Sequence[tuple[str, bytes]] = ()
    html: str = ""
    tables: Sequence[Table] = field(default_factory=tuple)
    anchor: str = ""


_CSS = """
:root{--fg:#1d1d1f;--muted:#5a5a5f;--line:#d7d7db;--band:#f5f6f8;--warn:#b3261e;--warnbg:#fdecea;--ok:#1e6b35}
*{box-sizing:border-box}
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;color:var(--fg);max-width:1180px;
 margin:1.5em auto;padding:0 1.2em}
h1{font-size:1.6em;margin:.2em 0 .3em}h2{font-size:1.25em;margin:1.6em 0 .5em;padding-bottom:.2em;
 border-bottom:2px solid var(--line)}h3{font-size:1.05em;margin:1.2em 0 .4em}
p{margin:.4em 0 .7em;max-width:75em}.muted{color:var(--muted)}
nav{font-size:.92em;margin:.5em 0 1em;display:flex;flex-wrap:wrap;gap:.25em 1.1em}nav a{white-space:nowrap}
.tablewrap{overflow-x:auto;max-width:100%}
.tablewrap th:first-child,.tablewrap td:first-child{position:sticky;left:0;z-index:2;background:#fff;
 box-shadow:inset -1px 0 var(--line)}
.tablewrap th.pin,.tablewrap td.pin{position:sticky;left:0;right:0;z-index:1;background:#fff;
 box-shadow:inset 1px 0 var(--line),inset -1px 0 var(--line)}
.tablewrap th:first-child,.tablewrap th.pin{background:var(--band)}
.tablewrap tr:hover td:first-child,.tablewrap tr:hover td.pin{background:#fafbff}
table{border-collapse:collapse;margin:.3em 0 1.2em;font-size:13px;font-variant-numeric:tabular-nums}
caption{text-align:left;font-weight:600;padding:.3em 0;caption-side:top}
th,td{padding:3px 7px;border-bottom:1px solid var(--line);text-align:right;vertical-align:top}
th{background:var(--band);font-weight:600;position:relative;white-space:nowrap}
td.t,th.t{text-align:left}td.nowrap{white-space:nowrap}
table.sortable th{cursor:pointer;user-select:none}
table.sortable th::after{content:" \\2195";color:#aaa;font-size:.8em}
table.sortable th[aria-sort=ascending]::after{content:" \\2191";color:var(--fg)}
table.sortable th[aria-sort=descending]::after{content:" \\2193";color:var(--fg)}
tr:hover td{background:#fafbff}
td.flag-uncertain,td.flag-misfit{color:var(--warn);font-weight:600;background:var(--warnbg)}
td.flag-known{color:var(--muted)}
.verdict-ok{color:var(--ok);font-weight:600}.verdict-bad{color:var(--warn);font-weight:600}
dl.legend{display:grid;grid-template-columns:max-content 1fr;gap:.2em 1em;font-size:13px;margin:.4em 0 1em}
dl.legend dt{font-weight:600}dl.legend dd{margin:0}
figure{margin:.8em 0 1.4em}.figwrap{overflow-x:auto;max-width:100%}
figure img{display:block;width:100%;height:auto;max-width:var(--w,100%);min-width:calc(.85 * var(--w,0px));
 border:1px solid var(--line)}
figcaption{font-size:13px;color:var(--muted)}
details{margin:.5em 0}summary{cursor:pointer;color:var(--muted)}
@media (max-width:600px){body{margin:.8em auto;padding:0 .7em}h1{font-size:1.35em}
 dl.legend{grid-template-columns:1fr}dl.legend dd{margin:0 0 .4em}}
pre.config{background:var(--band);padding:.8em;font-size:12px;white-space:pre-wrap;word-break:break-all}
code{font-size:12px;word-break:break-all}
@media print{
 body{max-width:none;margin:0;padding:0;font-size:10pt}nav,.noprint{display:none}
 table{font-size:8.5pt;page-break-inside:auto}tr,figure{break-inside:avoid}
 h2{break-after:avoid}table.sortable th::after{content:""}
 details>*{display:block}a{color:inherit;text-decoration:none}
 figure img{max-height:23cm;border:0;min-width:0}.tablewrap th,.tablewrap td{position:static}
}
"""

# sort a table by a clicked head: numbers by data-sort (or the text), text otherwise; click again to reverse;
# the pinned columns stick side by side right of the first (the name) when the table scrolls sideways: each
# one's left and right offsets are the widths of the sticky columns before and after it
_JS = """
function pin(){document.querySelectorAll("table").forEach(function(t){
 var hs=t.tHead?Array.from(t.tHead.rows[0].cells):[],ks=[],w=function(k){return hs[k].getBoundingClientRect().width};
 hs.forEach(function(h,k){if(h.classList.contains("pin"))ks.push(k)});if(!ks.length)return;
 var left=w(0),right=ks.reduce(function(a,k){return a+w(k)},0);
 ks.forEach(function(k){right-=w(k);Array.from(t.rows).forEach(function(r){var c=r.cells[k];
  if(c){c.style.left=left+"px";c.style.right=right+"px";}});left+=w(k);});});}
pin();window.addEventListener("load",pin);window.addEventListener("resize",pin);
document.querySelectorAll("table.sortable").forEach(function(t){
 t.querySelectorAll("thead th").forEach(function(th,i){th.addEventListener("click",function(){
  var asc=th.getAttribute("aria-sort")!=="ascending",b=t.tBodies[0],rows=Array.from(b.rows);
  function k(r){var c=r.cells[i];if(!c)return"";var s=c.getAttribute("data-sort");
   if(s!==null&&s!=="")return parseFloat(s);var n=parseFloat(c.textContent);return isNaN(n)?c.textContent:n;}
  rows.sort(function(x,y){var a=k(x),c=k(y);if(typeof a!==typeof c)return typeof a==="number"?-1:1;
   return(a<c?-1:a>c?1:0)*(asc?1:-1);});
  t.querySelectorAll("thead th").forEach(function(h){h.removeAttribute("aria-sort")});
  th.setAttribute("aria-sort",asc?"ascending":"descending");rows.forEach(function(r){b.appendChild(r)});
 });});
});
"""


def esc(text: str) -> str:
    return html.escape(str(text), quote=True)


def paragraphs(text: str) -> str:
    """Plain text as paragraphs: blank lines separate them, single line breaks are kept."""
    out = []
    for block in (b.strip("\n") for b in text.split("\n\n")):
        if block.strip():
            out.append("<p>" + "<br>".join(esc(line) for line in block.split("\n")) + "</p>")
    return "\n".join(out)


def table_html(t: Table) -> str:
    cls = " ".join(c for c in ("sortable" if t.sortable else "", t.cls) if c)
    parts = [f'<div class="tablewrap"><table{f" class={chr(34)}{cls}{chr(34)}" if cls else ""}>']
    if t.caption:
        parts.append(f"<caption>{esc(t.caption)}</caption>")
    tips = list(t.tips) + [""] * (len(t.head) - len(t.tips))
    first = t.rows[0] if t.rows else []
    pinned = {k for k, h in enumerate(t.head) if k > 0 and h in t.pin}
    heads = []
    for k, (h, tip) in enumerate(zip(t.head, tips, strict=True)):
        left = (k < len(first) and isinstance(first[k], Cell) and "t" in first[k].cls.split()) or k == 0
        cls = " ".join(c for c in ("t" if left else "", "pin" if k in pinned else "") if c)
        title = f' title="{esc(tip)}"' if tip else ""
        heads.append(f'<th scope="col"{f" class={chr(34)}{cls}{chr(34)}" if cls else ""}{title}>{esc(h)}</th>')
    parts.append("<thead><tr>" + "".join(heads) + "</tr></thead><tbody>")
    for row in t.rows:
        cells = []
        for k, c in enumerate(row):
            c = c if isinstance(c, Cell) else Cell(str(c), cls="t" if k == 0 else "")
            cls = f"{c.cls} pin".strip() if k in pinned else c.cls
            attrs = ""
            if cls:
                attrs += f' class="{esc(cls)}"'
            if c.sort is not None and c.sort == c.sort:  # not NaN
                attrs += f' data-sort="{c.sort!r}"'
            if c.title:
                attrs += f' title="{esc(c.title)}"'
            cells.append(f"<td{attrs}>{esc(c.text)}</td>")
        parts.append("<tr>" + "".join(cells) + "</tr>")
    parts.append("</tbody></table></div>")
    return "".join(parts)


CSS_PX_PER_INCH = 96.0


def png_css_size(png: bytes) -> tuple[float, float] | None:
    """A PNG's drawn size in CSS pixels: its pixels (IHDR) at its resolution (pHYs, pixels per metre) at 96 CSS
    px an inch; its pixels when it states no resolution; None when it is not a PNG."""
    if png[:8] != b"\x89PNG\r\n\x1a\n" or png[12:16] != b"IHDR":
        return None
    w, h = struct.unpack(">II", png[16:24])
    at = 8
    while at + 8 <= len(png):  # the chunks before the image data: length, type, data, CRC
        n, kind = struct.unpack(">I4s", png[at:at + 8])
        if kind == b"pHYs" and n == 9:
            px, py, unit = struct.unpack(">IIB", png[at + 8:at + 17])
            if unit == 1 and px > 0 and py > 0:  # pixels per metre
                return w / (px * 0.0254) * CSS_PX_PER_INCH, h / (py * 0.0254) * CSS_PX_PER_INCH
        if kind in (b"IDAT", b"IEND"):
            break
        at += 12 + n
    return float(w), float(h)


def figure_html(caption: str, png: bytes) -> str:
    """A figure at its drawn size (`png_css_size`): shrinks with the page down to 85 % of it, then scrolls
    sideways in its own box; width and height attributes keep its place while it loads."""
    data = base64.b64encode(png).decode("ascii")
    size = png_css_size(png)
    dims = (f' width="{size[0]:.0f}" height="{size[1]:.0f}" style="--w:{size[0]:.0f}px"' if size else "")
    return (f'<figure><div class="figwrap"><img alt="{esc(caption)}"{dims} src="data:image/png;base64,{data}">'
            f"</div><figcaption>{esc(caption)}</figcaption></figure>")


def _anchor(s: Section, k: int) -> str:
    return s.anchor or f"s{k}"


def render_html(title: str, sections: Sequence[Section], subtitle: str = "") -> str:
    """One self-contained page: a contents line, then each section's text, tables, HTML and figures."""
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{esc(title)}</title>",
        f"<style>{_CSS}</style>",
        f"</head><body><h1>{esc(title)}</h1>",
    ]
    if subtitle:
        parts.append(f'<p class="muted">{esc(subtitle)}</p>')
    parts.append("<nav>" + "".join(f'<a href="#{_anchor(s, k)}">{esc(s.heading)}</a>'
                                   for k, s in enumerate(sections)) + "</nav>")
    for k, s in enumerate(sections):
        parts.append(f'<section id="{_anchor(s, k)}"><h2>{esc(s.heading)}</h2>')
        if s.text:
            parts.append(paragraphs(s.text))
        parts += [table_html(t) for t in s.tables]
        if s.html:
            parts.append(s.html)
        parts += [figure_html(caption, png) for caption, png in s.figures]
        parts.append("</section>")
    parts.append(f"<script>{_JS}</script></body></html>")
    return "\n".join(parts)


__all__ = ["Cell", "Section", "Table", "esc", "figure_html", "paragraphs", "png_css_size", "render_html",
           "table_html"]
