"""User text reaches the viewer's markdown (which viser renders with raw HTML) as text only.

A recording's file name, the URDF's robot name and an error's text carry an HTML payload that
would run script in the viewer's page; every markdown string the viewer sends must hold it as
entities and escapes, with no tag and no server folder.
"""

from __future__ import annotations

import dataclasses
import re
from contextlib import nullcontext
from pathlib import Path
from typing import Any

import pytest

from app.errors import without_paths
from app.viewer._text import markdown_text
from app.viewer.access import Grant
from app.viewer.comparison import Comparison
from app.viewer.scene import ComparisonScene, PreparedComparison
from app.viewer.server import ViewerServer, _add_gui
from tests.viewer._fakes import FakeTarget

PAYLOAD = "<iframe srcdoc='<img src=x onerror=alert(document.domain)>'>"
FILE_NAME = f"curl{PAYLOAD}.csv"
ROBOT = f"arm{PAYLOAD}\n# heading *bold* [link](javascript:alert(1))"


class FakeGui:
    """Records each markdown text the viewer sends; every other element is a plain handle."""

    def __init__(self) -> None:
        self.markdown: list[str] = []

    def add_markdown(self, content: str, **_: Any) -> Any:
        self.markdown.append(content)
        return _Handle(content=content)

    def add_folder(self, *_: Any, **__: Any) -> Any:
        return nullcontext()

    def __getattr__(self, name: str) -> Any:
        if not name.startswith("add_"):
            raise AttributeError(name)
        return lambda *args, **kwargs: _Handle(args=args, **kwargs)


class _Handle:
    def __init__(self, **props: Any) -> None:
        self.__dict__.update(props)
        self.value = props.get("initial_value")


def _no_markup(text: str) -> None:
    assert "<" not in text and ">" not in text, text
    assert not re.search(r"(?<!\\)\[", text), text  # no link can open
    assert "\n#" not in text and "\n" not in text.replace("  \n", ""), text


def test_markdown_text_keeps_html_and_markdown_as_characters() -> None:
    out = markdown_text(ROBOT)
    _no_markup(out)
    assert "&lt;iframe" in out and "&#x27;" in out  # entities, not tags
    assert r"\*bold\*" in out and r"\[link\]\(javascript" in out and r"\# heading" in out
    assert markdown_text("a_b & c") == r"a\_b &amp; c"


def test_without_paths_keeps_only_the_file_name(tmp_path: Path) -> None:
    text = without_paths(f"robot file {tmp_path}/data/robots/ab12/arm.urdf is gone (rad/s)")
    assert text == "robot file arm.urdf is gone (rad/s)"


def test_title_and_human_note_reach_markdown_escaped(plan_comparison: Comparison) -> None:
    note = f"recorded human from analysis #3: lift 1 of {FILE_NAME} (0.10-1.20 s)"
    c = dataclasses.replace(plan_comparison, robot=ROBOT, human_note=note)
    assert PAYLOAD in c.title  # the title is plain text; the viewer escapes it
    scene = ComparisonScene(FakeTarget(), PreparedComparison(c))
    gui = FakeGui()
    _add_gui(gui, scene, autoplay=False)
    assert len(gui.markdown) == 4  # title, phase of the moment, whose human, safety
    for text in gui.markdown:
        _no_markup(text)
    assert any("&lt;iframe srcdoc" in t for t in gui.markdown)
    assert any("curl&lt;iframe" in t for t in gui.markdown)


@pytest.mark.parametrize("error", [LookupError, RuntimeError])
def test_an_error_is_shown_escaped_and_without_server_folders(
    plan_comparison: Comparison, tmp_path: Path, error: type[Exception]
) -> None:
    def prepare(kind: str, result_id: int) -> Any:
        raise error(f"recording {tmp_path}/data/files/{FILE_NAME} is gone")

    viewer = ViewerServer(prepare)
    client = _Handle(client_id=1, gui=FakeGui())
    viewer._grants[1] = Grant(kind="plan", id=7, methods=None, token="t")
    viewer._on_connect(client)
    (text,) = client.gui.markdown
    _no_markup(text)
    assert str(tmp_path) not in text and "/data/" not in text
    if error is LookupError:
        assert "curl&lt;iframe" in text  # the file's name, as text
