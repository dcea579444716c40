"""Implementations of the `tumble` subcommands (see `tumble.cli`)."""
