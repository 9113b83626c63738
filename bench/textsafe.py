"""Text from outside the bench (a DUT's output, a recording's metadata) made safe to show.

A DUT may write anything on its standard error: terminal escape sequences, NUL, markup.
The recording and ``results.json`` keep that text raw (JSON escapes it); wherever it is
*shown* it goes through one of these functions first:

* :func:`for_terminal`: control characters (C0, DEL, C1), bidirectional overrides and lone
  surrogates become visible escapes (``ESC`` -> ``\\x1b``, newline -> ``\\n`` unless kept),
  so nothing the DUT wrote can move the cursor, retitle the window or hide text. A
  backslash is left as is: the function is idempotent, not reversible (the raw text is in
  the recording);
* :func:`for_markdown`: safe in a Markdown table cell or list item (``\\ ` | [ ]``
  backslash-escaped, ``& < >`` as entities, a newline as ``<br>``), then as for the terminal;
* :func:`xml_safe`: characters XML 1.0 forbids (NUL, ESC, lone surrogates...) made visible,
  for ElementTree, which escapes markup itself but writes those raw (an unparsable file);
* :func:`for_xml`: :func:`xml_safe` and the markup escaped, for XML written by hand;
* :func:`for_html`: HTML-escaped (quotes too) and control characters made visible.
"""

from __future__ import annotations

import html
import re

__all__ = ["for_terminal", "for_markdown", "xml_safe", "for_xml", "for_html", "visible"]

# C0 and C1 controls, DEL, zero-width and bidirectional formatting, line/paragraph
# separators, the BOM, lone surrogates
_TERMINAL = "\x00-\x1f\x7f-\x9f\u200b-\u200f\u2028-\u202e\u2060-\u2069\ufeff\ud800-\udfff"
_UNSAFE = re.compile(f"[{_TERMINAL}]")
# XML 1.0 Char excludes every C0 control but tab, newline and CR, lone surrogates, U+FFFE and
# U+FFFF; the rest of the terminal set (CR too) is made visible as well, so a report reads
# the same everywhere
_XML_UNSAFE = re.compile(f"[{_TERMINAL}\ufffe\uffff]")
_NAMED = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}
_MARKDOWN = str.maketrans({c: "\\" + c for c in "\\`|[]"} | {"&": "&amp;", "<": "&lt;", ">": "&gt;"})


def visible(ch: str) -> str:
    """The escape shown for one character: ``\\n``, ``\\x1b``, ``\\u202e``, ``\\udc80``."""
    if ch in _NAMED:
        return _NAMED[ch]
    o = ord(ch)
    return f"\\x{o:02x}" if o < 0x100 else f"\\u{o:04x}" if o < 0x10000 else f"\\U{o:08x}"


def _sub(pattern: re.Pattern[str], text: str, keep: str) -> str:
    return pattern.sub(lambda m: m.group() if m.group() in keep else visible(m.group()), text)


def for_terminal(text: object, *, keep: str = "") -> str:
    """``str(text)`` with every control or formatting character made visible, except those
    in ``keep`` (``keep="\\n\\t"`` for multi-line output)."""
    return _sub(_UNSAFE, str(text), keep)


def for_markdown(text: object) -> str:
    """``str(text)`` safe in a Markdown table cell or list item (one line, no markup)."""
    s = str(text).translate(_MARKDOWN).replace("\r\n", "\n").replace("\n", "<br>")
    return _sub(_UNSAFE, s, "")


def xml_safe(text: object, *, keep: str = "\n\t") -> str:
    """``str(text)`` without the characters XML 1.0 cannot hold (made visible); markup is
    left for the XML writer to escape (ElementTree does)."""
    return _sub(_XML_UNSAFE, str(text), keep)


def for_xml(text: object) -> str:
    """``str(text)`` escaped for XML text or a quoted attribute."""
    return html.escape(xml_safe(text), quote=True)


def for_html(text: object) -> str:
    """``str(text)`` escaped for HTML text or a quoted attribute, controls made visible."""
    return html.escape(for_terminal(text, keep="\n\t"), quote=True)
