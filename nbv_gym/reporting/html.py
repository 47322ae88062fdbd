"""The report as one self-contained HTML page, and figures saved for papers (PNG and SVG).

:func:`write_html` turns whatever ``report.md`` holds (headings, paragraphs, GFM tables, images)
into ``report.html`` beside it: the Markdown rendered by markdown-it-py, every figure embedded as
a ``data:`` URI — its SVG twin when there is one (sharp at any zoom), else the PNG — so the file
opens in any browser, mails and archives alone. :func:`save_figure` writes a matplotlib figure as
PNG (150 dpi) and SVG (vector, text kept as text) side by side.
"""

from __future__ import annotations

import base64
import html
import re
from pathlib import Path

PNG_DPI = 150
STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; margin: 0 auto;
       max-width: 1200px; padding: 1.5rem 2rem 4rem; color: #1d1d1f; line-height: 1.5; }
h1 { border-bottom: 2px solid #ddd; padding-bottom: .3rem; }
h2 { margin-top: 2.2rem; border-bottom: 1px solid #eee; padding-bottom: .2rem; }
table { border-collapse: collapse; margin: .8rem 0; font-size: .86rem; max-width: 100%; }
th, td { border: 1px solid #d0d7de; padding: .25rem .6rem; text-align: right;
         overflow-wrap: break-word; }
th { background: #f3f5f7; } td:first-child, th:first-child { text-align: left; }
tr:nth-child(even) td { background: #fafbfc; }
figure { margin: .6rem 0; }
img { max-width: 100%; height: auto; display: block; }
figcaption { font-size: .8rem; color: #57606a; }
figcaption a { color: inherit; }
code { background: #f3f5f7; padding: 0 .25rem; border-radius: 3px; font-size: .9em; }
@page { size: A4; margin: 14mm 12mm; }
@media print {
  body { max-width: none; padding: 0; font-size: 9.5pt; line-height: 1.35; }
  h1, h2, h3 { break-after: avoid; }
  table { font-size: 7.5pt; break-inside: auto; }
  thead { display: table-header-group; }
  tr, figure, img { break-inside: avoid; }
  th, td { padding: .1rem .3rem; }
  tr:nth-child(even) td, th, code { -webkit-print-color-adjust: exact; print-color-adjust: exact; }
  figcaption { display: none; }
}
"""
#: Points each figure's "SVG" link at the SVG embedded in its image, so the link works when the
#: page travels alone (without JavaScript it points at the SVG file beside the page).
SCRIPT = """
document.querySelectorAll("a[data-svg]").forEach(function (link) {
  var image = link.closest("figure").querySelector("img");
  if (image.src.startsWith("data:image/svg+xml")) link.href = image.src;
});
"""
_IMAGE = re.compile(r'<img src="([^"]+)" alt="([^"]*)"( /)?>')


def save_figure(figure, path: str | Path) -> Path:
    """Write ``figure`` (a matplotlib Figure) to ``path`` (``.png``, 150 dpi) and its vector twin
    ``path.with_suffix(".svg")``; the PNG's path."""
    path = Path(path).with_suffix(".png")
    figure.savefig(path, dpi=PNG_DPI)
    figure.savefig(path.with_suffix(".svg"), metadata={"Date": None})  # reproducible bytes
    return path


def write_html(markdown_path: str | Path, out: str | Path | None = None) -> Path:
    """Render ``report.md`` into a self-contained HTML file (default: ``report.html`` beside it),
    its local images embedded; the HTML file's path."""
    markdown_path = Path(markdown_path)
    out = Path(out) if out else markdown_path.with_suffix(".html")
    text = markdown_path.read_text(encoding="utf-8")
    body = _IMAGE.sub(lambda m: _embedded(markdown_path.parent, m), _render(text))
    body = body.replace("<p><figure>", "<figure>").replace("</figure></p>", "</figure>")
    title = next((line[2:] for line in text.splitlines() if line.startswith("# ")), "report")
    page = (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f"<title>{html.escape(title.replace('`', ''))}</title>\n<style>{STYLE}</style>\n"
        f"</head>\n<body>\n{body}<script>{SCRIPT}</script>\n</body>\n</html>\n"
    )
    out.write_text(page, encoding="utf-8")
    return out


def _render(text: str) -> str:
    from markdown_it import MarkdownIt

    return MarkdownIt("commonmark", {"html": False}).enable("table").render(text)


def _embedded(folder: Path, match: re.Match) -> str:
    """The ``<img>`` of ``match`` with a local figure inlined as a data URI (its SVG twin
    preferred), in a ``<figure>`` whose caption links the SVG and PNG files for download;
    remote or missing files are left as they are."""
    source, alt = html.unescape(match.group(1)), match.group(2)
    path = folder / source
    if "://" in source or not path.is_file():
        return match.group(0)
    svg = path.with_suffix(".svg")
    shown, mime = (
        (svg, "image/svg+xml")
        if svg.is_file()
        else (path, _MIME.get(path.suffix.lower(), "application/octet-stream"))
    )
    data = base64.b64encode(shown.read_bytes()).decode("ascii")
    links = [f'<a href="{html.escape(path.name)}" download>{path.suffix[1:].upper()}</a>']
    if svg.is_file():
        name = html.escape(svg.name)
        links.insert(0, f'<a href="{name}" download="{name}" data-svg>SVG</a>')
    return (
        f'<figure><img src="data:{mime};base64,{data}" alt="{alt}">'
        f"<figcaption>{alt} · download {' · '.join(links)}</figcaption></figure>"
    )


_MIME = {".png": "image/png", ".jpg": "image/jpeg", ".gif": "image/gif"}
