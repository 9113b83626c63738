"""DUT text made safe to show: terminal, Markdown, XML, HTML (bench.textsafe)."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

from hypothesis import given, settings
from hypothesis import strategies as st

from bench.textsafe import for_html, for_markdown, for_terminal, for_xml, visible, xml_safe

HOSTILE = "\x1b[31mred\x1b[0m \x1b]0;pwned\x07 <script>alert(1)</script> ]]> a|b \x00 \x9b2J \u202eevil \udc80 x\ny"
# what a terminal would act on: C0 (tab and newline included), DEL, C1, bidi overrides, lone surrogates
RAW_CONTROL = re.compile("[\x00-\x1f\x7f-\x9f\u202a-\u202e\u2066-\u2069\ud800-\udfff]")
texts = st.text(alphabet=st.characters(codec=None, exclude_categories=()), max_size=60)


def test_terminal_text_shows_control_characters_instead_of_acting_on_them():
    s = for_terminal(HOSTILE)
    assert not RAW_CONTROL.search(s)
    assert "\\x1b[31mred" in s and "\\x00" in s and "\\x9b" in s and "\\u202e" in s and "\\udc80" in s
    assert s.endswith("x\\ny")
    assert for_terminal("a\tb\nc", keep="\n\t") == "a\tb\nc"
    assert for_terminal("plain text, 5 m ≤ 7 m") == "plain text, 5 m ≤ 7 m"
    assert visible("\x1b") == "\\x1b" and visible("\n") == "\\n"


def test_markdown_cells_hold_no_markup_pipes_or_line_breaks():
    s = for_markdown(HOSTILE)
    assert "<script>" not in s and "&lt;script&gt;" in s
    assert "\n" not in s and "x<br>y" in s
    assert re.search(r"(?<!\\)\|", s) is None  # every pipe escaped
    assert not RAW_CONTROL.search(s)
    assert for_markdown("[click](javascript:x)") == "\\[click\\](javascript:x)"
    assert for_markdown("a\\|b") == "a\\\\\\|b"  # a DUT's own backslash cannot unescape the pipe


def test_xml_text_and_attributes_parse_back_with_elementtree():
    root = ET.Element("r", attr=xml_safe(HOSTILE))
    root.text = xml_safe(HOSTILE)
    back = ET.fromstring(ET.tostring(root, encoding="unicode"))
    assert back.text == xml_safe(HOSTILE) and "<script>" in back.text  # markup escaped by the writer, kept
    assert "\\x00" in back.get("attr")
    hand = f'<r a="{for_xml(HOSTILE)}">{for_xml(HOSTILE)}</r>'
    assert ET.fromstring(hand).text == xml_safe(HOSTILE)


def test_html_is_escaped():
    s = for_html(HOSTILE + ' "q" \'s\'')
    assert "<script>" not in s and "&lt;script&gt;" in s and "&quot;q&quot;" in s and "&#x27;s&#x27;" in s
    assert not RAW_CONTROL.search(s.replace("\n", ""))  # only the kept newline


@settings(max_examples=300, deadline=None)
@given(texts)
def test_any_text_is_safe_everywhere(text):
    t = for_terminal(text)
    assert not RAW_CONTROL.search(t)
    assert for_terminal(t) == t  # idempotent
    m = for_markdown(text)
    assert not RAW_CONTROL.search(m) and "<" not in m.replace("<br>", "") and "\n" not in m
    assert re.fullmatch(r"(?:\\.|[^\\|])*", m.replace("<br>", ""), re.S)  # no bare pipe
    root = ET.Element("r", a=xml_safe(text))
    root.text = xml_safe(text)
    data = ET.tostring(root, encoding="utf-8")  # no lone surrogate left to fail the encoder
    assert ET.fromstring(data).get("a") == xml_safe(text)
    assert (ET.fromstring(f"<r>{for_xml(text)}</r>").text or "") == xml_safe(text)
