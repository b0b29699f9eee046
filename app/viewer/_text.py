"""User text in the viewer's markdown: shown as the characters it holds, never as markup.

viser renders ``gui.add_markdown`` as Markdown *with raw HTML* (its client turns tags into DOM
nodes, scripts and event handlers included), so a robot's name, a recording's file name or an
error message that holds ``<img src=x onerror=...>`` would run in the viewer's page. Every
string the viewer did not write itself goes into markdown through :func:`markdown_text`.
Scene labels, folder, button and dropdown labels are drawn as text by viser (no HTML) and
take names as they are.
"""

from __future__ import annotations

import html
import re

from app.errors import without_paths

__all__ = ["markdown_text", "without_paths"]  # without_paths: app.errors', kept here for the viewer

#: ASCII punctuation Markdown can give a meaning to (CommonMark escapes any of it with a
#: backslash), except ``&`` and ``;``, which the HTML entities use, and ``#`` (see ``_HASH``).
_MARKDOWN = re.compile(r"([\\`*_{}\[\]()<>+\-.!|~=:\"'$%^,/?@])")
#: ``#`` that is not the ``&#`` of an entity (``html.escape`` writes ``'`` as ``&#x27;``).
_HASH = re.compile(r"(?<!&)#")
#: Control characters and Unicode line breaks: a new line could start a new block.
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029]+")


def markdown_text(text: object) -> str:
    """``text`` as literal characters inside viser's markdown, on one line.

    Control characters and line breaks become one space (no new block can start); HTML's
    ``< > & " '`` become entities (:func:`html.escape`); then every other character Markdown
    gives a meaning to is backslash-escaped, so ``*``, ``[a](javascript:...)``, a ``#``
    heading or a backtick stay text.
    """
    entities = html.escape(_CONTROL.sub(" ", str(text)), quote=True)
    return _HASH.sub(r"\\#", _MARKDOWN.sub(r"\\\1", entities))
