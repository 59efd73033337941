#!/usr/bin/env bash
# Set everything up (idempotent), lint, and run the test suite (the default excludes the `slow` marker).
# The lint is ruff with the configuration of pyproject.toml ([tool.ruff]): any finding fails the run,
# with ruff's message, before the tests.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# Debian's chromium: the browser of tests/visualization/test_page.py (driven by playwright from pip, which
# downloads no browser). Here and not in scripts/setup.sh: the demo does not need a browser. Without it
# (not root) those tests are skipped, saying why.
missing=()
if command -v dpkg-query >/dev/null; then
  for p in chromium; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
  done
fi
if [ ${#missing[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    printf '[test] installing system packages: %s\n' "${missing[*]}" >&2
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >/dev/null
    apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  else
    printf '[test] missing system packages (not root): %s; the browser tests of the page will be skipped\n' \
      "${missing[*]}" >&2
    printf '[test]   to install them: sudo apt-get install --no-install-recommends %s\n' "${missing[*]}" >&2
  fi
fi
.venv/bin/ruff check .
exec .venv/bin/python -m pytest "$@"
