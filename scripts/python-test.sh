#!/usr/bin/env bash
# The Python package's tests (docs/python.md): builds the package into a virtual
# environment under the build cache (maturin, reusing the renderer's cargo build in
# $CARGO_TARGET_DIR) and runs python/tests with pytest. Called by `./lp test`.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/lightpath/target}"
cache="$(dirname "$CARGO_TARGET_DIR")"
venv="$cache/venv-python"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
# (maturin's build backend runs the venv's maturin by name.)
export PATH="$venv/bin:$PATH"
# (Already installed versions are kept: after the first run this needs no network.)
"$venv/bin/python" -m pip install -q --disable-pip-version-check \
  "maturin>=1.5,<2" "numpy>=1.21" "pytest>=7" "matplotlib>=3.5" "pillow>=8"
echo "python: building the lightpath package" >&2
"$venv/bin/python" -m pip install -q --disable-pip-version-check --no-build-isolation \
  --force-reinstall --no-deps "$root/python"
LIGHTPATH_BIN="$CARGO_TARGET_DIR/release/lightpath" \
  "$venv/bin/python" -m pytest -q -p no:cacheprovider "$root/python/tests"
