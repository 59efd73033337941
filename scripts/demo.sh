#!/usr/bin/env bash
# Set everything up (idempotent) and run the demo on the embedded bunny.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/o3dheat demo "$@"
