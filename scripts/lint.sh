#!/usr/bin/env bash
# The habits CI checks before the tests: ruff's linter and formatter over the code, tests and benchmarks.
# Fix what it reports with `ruff check --fix . && ruff format .`; the settings are in pyproject.toml.
set -euo pipefail
cd "$(dirname "$0")/.."
python -m pip install -q -e ".[dev]"
python -m ruff check src tests benchmarks scripts
python -m ruff format --check src tests benchmarks scripts
