"""Tables of the bench commands spliced into the docs between a pair of HTML comment markers."""

from __future__ import annotations

from pathlib import Path

__all__ = ["between", "splice"]


def between(text: str, begin: str, end: str) -> str | None:
    """Return the text between the markers ``begin`` and ``end`` (None: a marker is missing)."""
    if begin not in text or end not in text:
        return None
    return text.split(begin, 1)[1].split(end, 1)[0]


def splice(doc: Path, begin: str, end: str, body: str) -> bool:
    """Replace what lies between the markers of ``doc`` by ``body`` (on lines of its own).

    Returns False, writing nothing, if the file or one of its markers is missing.
    """
    text = doc.read_text() if doc.exists() else ""
    if between(text, begin, end) is None:
        return False
    head, rest = text.split(begin, 1)
    tail = rest.split(end, 1)[1]
    doc.write_text(f"{head}{begin}\n{body}\n{end}{tail}")
    return True
