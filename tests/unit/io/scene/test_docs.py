"""io/scene/docs.py: the scene reference generated from the schema."""

from __future__ import annotations

from pathlib import Path

from tumble.io import scene as scene_io


def test_docs_reference_matches_the_schema():
    """Keep docs/scenes.md's key reference identical to the schema the validator uses."""
    docs = (Path(__file__).resolve().parents[4] / "docs" / "scenes.md").read_text(encoding="utf-8")
    assert scene_io.reference_markdown() in docs
