"""The bench commands' tables spliced into docs between markers (fem_runout.bench.markers)."""

from fem_runout.bench.markers import between, splice

B, E = "<!-- t -->", "<!-- /t -->"


def test_splice_replaces_only_the_text_between_the_markers(tmp_path):
    doc = tmp_path / "doc.md"
    doc.write_text(f"head\n{B}\nold\nrows\n{E}\ntail <!-- other -->\n")
    assert splice(doc, B, E, "| a |\n| b |")
    assert doc.read_text() == f"head\n{B}\n| a |\n| b |\n{E}\ntail <!-- other -->\n"
    assert between(doc.read_text(), B, E) == "\n| a |\n| b |\n"
    assert splice(doc, B, E, "new")  # again: idempotent in form
    assert doc.read_text() == f"head\n{B}\nnew\n{E}\ntail <!-- other -->\n"


def test_a_missing_file_or_marker_writes_nothing(tmp_path):
    doc = tmp_path / "doc.md"
    assert not splice(doc, B, E, "x") and not doc.exists()
    doc.write_text(f"only {B} here\n")
    assert not splice(doc, B, E, "x")
    assert doc.read_text() == f"only {B} here\n"
    assert between(doc.read_text(), B, E) is None
