"""Tests of the scene package, one file per module; `BALL` is the smallest scene they (and the CLI tests) load."""

#: a ground plane and one ball above it
BALL = """
[[plane]]
normal = [0, 0, 1]

[[sphere]]
position = [0, 0, 1]
radius = 0.1
mass = 1.0
"""
