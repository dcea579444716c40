"""Unit tests of tumble.viewer, one file per module."""
