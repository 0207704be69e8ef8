"""The self-contained HTML report (gaitnet/pipeline/html_report.py): parses, holds the
tables and the figures as PNG data URIs, refers to nothing outside itself, escapes what
users supply, and is written atomically."""

from __future__ import annotations

import base64
import os
from html.parser import HTMLParser

import pytest
from test_gait_parameters import hand_walk

from gaitnet.errors import InputError
from gaitnet.pipeline.gait_parameters import PARAMETERS, stride_parameters, summarise
from gaitnet.pipeline.html_report import render_report, write_report
from gaitnet.pipeline.plots import PNG_SIGNATURE, gait_phases_png
from gaitnet.vio.gait import strides_from_stances

NASTY = "<script>alert('x')</script> Ann & \"Bo\" O'Neil"


class Collector(HTMLParser):
    """Tags, attributes and text of a document; fails on unbalanced tables."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tags: list[str] = []
        self.attrs: list[tuple[str, dict[str, str | None]]] = []
        self.text: list[str] = []
        self.open_tables = 0

    def handle_starttag(self, tag, attrs) -> None:
        self.tags.append(tag)
        self.attrs.append((tag, dict(attrs)))
        self.open_tables += tag == "table"

    def handle_endtag(self, tag) -> None:
        self.open_tables -= tag == "table"
        assert self.open_tables >= 0

    def handle_data(self, data) -> None:
        self.text.append(data)


@pytest.fixture(scope="module")
def report_parts():
    stances, contacts = hand_walk()
    rows = stride_parameters(strides_from_stances(stances), contacts)
    figures = [
        ("phases one", gait_phases_png(contacts, 0.0, 6.0)),
        ("phases <two>", gait_phases_png(contacts, 1.0, 5.0)),
    ]
    facts = {"subject": NASTY, "date": "2026-11-24", "duration [s]": 12.25, "frames": 368}
    return facts, summarise(rows), rows, figures


def test_parses_with_tables_and_inline_pngs(report_parts) -> None:
    facts, summary, rows, figures = report_parts
    text = render_report(facts, summary, rows, figures, notes=["a & b"])
    doc = Collector()
    doc.feed(text)
    doc.close()
    assert doc.open_tables == 0
    assert doc.tags.count("table") == 3  # facts, per side, per stride
    assert "details" in doc.tags and "style" in doc.tags and "script" not in doc.tags
    srcs = [a["src"] for tag, a in doc.attrs if tag == "img"]
    assert len(srcs) == len(figures)
    for src, (_, png) in zip(srcs, figures, strict=True):
        prefix = "data:image/png;base64,"
        assert src.startswith(prefix)
        data = base64.b64decode(src[len(prefix) :], validate=True)
        assert data.startswith(PNG_SIGNATURE) and data == png
    words = " ".join(doc.text)
    for _, label, _ in PARAMETERS:
        assert label in words
    assert "60.0 ± 0.0" in words  # stance %, hand walk
    assert "Per-stride table (8 strides)" in words
    assert "a & b" in words


def test_nothing_outside_the_file(report_parts) -> None:
    text = render_report(*report_parts)
    lowered = text.lower()
    assert "http://" not in lowered and "https://" not in lowered
    assert "url(" not in lowered and "@import" not in lowered  # no CSS resources
    doc = Collector()
    doc.feed(text)
    for tag, attrs in doc.attrs:
        assert tag not in ("link", "script", "iframe", "object")
        for key in ("src", "href"):
            value = attrs.get(key)
            assert value is None or value.startswith("data:"), (tag, key, value)


def test_user_strings_are_escaped(report_parts) -> None:
    facts, summary, rows, figures = report_parts
    text = render_report(facts, summary, rows, figures, notes=[NASTY], title=NASTY)
    assert "<script>" not in text and NASTY not in text
    assert "&lt;script&gt;alert(&#x27;x&#x27;)&lt;/script&gt; Ann &amp; &quot;Bo&quot;" in text
    assert 'alt="phases &lt;two&gt;"' in text
    doc = Collector()
    doc.feed(text)
    assert NASTY in "".join(doc.text)  # shown to the reader exactly as given


def test_written_atomically(report_parts, tmp_path) -> None:
    path = write_report(tmp_path / "out" / "report.html", *report_parts)
    assert path.read_text(encoding="utf-8") == render_report(*report_parts)
    assert os.listdir(tmp_path / "out") == ["report.html"]


def test_refuses_figures_that_are_not_png(report_parts) -> None:
    facts, summary, rows, _ = report_parts
    with pytest.raises(InputError, match="report figure 'bad': not PNG bytes"):
        render_report(facts, summary, rows, [("bad", b"<svg/>")])


def test_empty_session_renders() -> None:
    """No strides at all: the tables show dashes, not errors or NaN."""
    text = render_report({}, summarise([]), [])
    assert "nan" not in text.lower() and "Per-stride table (0 strides)" in text
