"""Unit tests of tumble.commands, one file per module."""
