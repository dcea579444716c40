"""Unit tests of tumble.render, one file per module."""
