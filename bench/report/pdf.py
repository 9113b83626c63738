"""The report as PDF (the one module using WeasyPrint and pypdf).

The page is laid out in parts (the front matter, then one part per case), each on its
own, so the parts can be laid out in worker processes beside the drawing of the figures
(layout is the slow part of the report: about 10 s for the reference suite's tables).
:func:`assemble` joins the parts in order and stamps every page's footer: the report id
on the left, "page n of N" on the right, counted over the whole document.
"""

from __future__ import annotations

import io
import re
from collections.abc import Sequence
from pathlib import Path

import pypdf
import weasyprint

from bench.atomic import atomic_file

__all__ = ["render_part", "assemble"]

#: The footer band: A4 with the margins of report.css, the text in the bottom margin.
_FOOTER_CSS = """
@page { size: A4; margin: 16mm 14mm 18mm 14mm;
  @bottom-left { content: "%s"; font-family: "DejaVu Sans", sans-serif; font-size: 7.5pt; color: #555; }
  @bottom-right { content: "page " counter(page) " of " counter(pages); font-family: "DejaVu Sans", sans-serif;
                  font-size: 7.5pt; color: #555; } }
div { break-before: page; }
div:first-child { break-before: auto; }
"""


def render_part(html: str) -> bytes:
    """One part of the report laid out as PDF (self-contained HTML: no base URL)."""
    return weasyprint.HTML(string=html).write_pdf()


def _footers(pages: int, left: str) -> pypdf.PdfReader:
    text = re.sub(r"[^\w .:/+-]", "", left)  # inside a CSS string inside <style>: plain characters only
    doc = (f"<html><head><style>{_FOOTER_CSS % text}</style></head><body>"
           + "<div>&nbsp;</div>" * pages + "</body></html>")
    return pypdf.PdfReader(io.BytesIO(weasyprint.HTML(string=doc).write_pdf()))


def assemble(parts: Sequence[bytes], path: str | Path, *, footer: str = "") -> Path:
    """Join ``parts`` in order into ``path``, every page stamped with ``footer`` and its
    number out of the total."""
    writer = pypdf.PdfWriter()
    for part in parts:
        writer.append(pypdf.PdfReader(io.BytesIO(part)))
    stamps = _footers(len(writer.pages), footer)
    if len(stamps.pages) != len(writer.pages):
        raise RuntimeError(f"footer pages: {len(stamps.pages)} for {len(writer.pages)} report pages")
    for page, stamp in zip(writer.pages, stamps.pages, strict=True):
        page.merge_page(stamp)
    with atomic_file(path) as fh:  # whole or not at all (bench.atomic)
        writer.write(fh)
    return Path(path)
