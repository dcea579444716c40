"""`python -m tumble.io.scene > reference.md`: the scene reference for docs/scenes.md."""

from .docs import reference_markdown

print(reference_markdown())
