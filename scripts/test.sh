#!/usr/bin/env bash
# Set everything up (idempotent), lint, and run the test suite (the default excludes the `slow` marker).
# The lint is ruff with the configuration of pyproject.toml ([tool.ruff]): any finding fails the run,
# with ruff's message, before the tests.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/ruff check .
exec .venv/bin/python -m pytest "$@"
