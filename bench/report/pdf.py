"""The report as PDF (the one module using WeasyPrint): the same HTML page, laid out on
A4 pages with the report id and page numbers in the footer."""

from __future__ import annotations

from pathlib import Path

import weasyprint

__all__ = ["write_pdf"]


def write_pdf(html: str, path: str | Path) -> Path:
    """Render ``html`` (self-contained: no base URL is needed) to ``path``."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    weasyprint.HTML(string=html).write_pdf(p)
    return p
