#!/usr/bin/env bash
# The habits CI checks before the tests: ruff's linter and formatter over the code, tests and benchmarks,
# and mypy's type check of the package. Fix what ruff reports with `ruff check --fix . && ruff format .`;
# the settings of both are in pyproject.toml.
set -euo pipefail
cd "$(dirname "$0")/.."
# the test extra too: mypy reads the types of the optional libraries (PySide6, moderngl, trimesh, ...)
python -m pip install -q -e ".[dev,test]"
python -m ruff check src tests benchmarks scripts
python -m ruff format --check src tests benchmarks scripts
python -m mypy  # files and settings: pyproject.toml [tool.mypy]
