#!/usr/bin/env bash
# Set everything up (idempotent), install the documentation tools (the `docs` extra) when missing,
# and build the site into docs/_build/html with every warning an error. The gallery's examples
# run during the build. Extra arguments go to sphinx-build (e.g. -E to rebuild every page).
#
#   bash scripts/docs.sh            # then open docs/_build/html/index.html
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
py=.venv/bin/python
# setup.sh installs `.[dev]`; the docs extra is installed here, again only when pyproject.toml's
# docs list changed or a package is missing.
want=$("$py" - <<'PY'
import hashlib, re
text = open("pyproject.toml").read()
block = re.search(r"^docs = \[(.*?)\]", text, re.M | re.S).group(1)
print(hashlib.sha256(block.encode()).hexdigest()[:16])
PY
)
stamp=.venv/.o3dheat-docs
if ! { [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] &&
       "$py" -c 'import importlib, sphinx, numpydoc, sphinx_gallery, pydata_sphinx_theme, myst_parser
importlib.import_module("sphinx-mathjax-offline")  # MathJax served by the site (its name has dashes)' 2>/dev/null; }; then
  printf '[docs] installing the docs extra into .venv\n' >&2
  deps=$("$py" - <<'PY'
import re
text = open("pyproject.toml").read()
print(" ".join(re.findall(r'"([^"]+)"', re.search(r"^docs = \[(.*?)\]", text, re.M | re.S).group(1))))
PY
)
  # shellcheck disable=SC2086
  "$py" -m pip install -q $deps
  echo "$want" > "$stamp"
fi
export MPLBACKEND=Agg
exec "$py" -m sphinx -W --keep-going -b html "$@" docs docs/_build/html
