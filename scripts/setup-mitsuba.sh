#!/usr/bin/env bash
# Installs what `lightpath bench --mitsuba` (scripts/mitsuba_bench.py) needs, only when
# missing:
#   - Mitsuba 3 (and Dr.Jit, numpy) from PyPI, for the CPU variant `llvm_ad_rgb`;
#   - Debian's libllvm19: Dr.Jit's LLVM JIT fails with bookworm's default LLVM 15, so
#     mitsuba_bench.py points DRJIT_LIBLLVM_PATH at libllvm19's shared library.
set -euo pipefail

SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
PY=${PYTHON:-python3}

if ! "$PY" -c 'import mitsuba, drjit, numpy' >/dev/null 2>&1; then
  echo "setup-mitsuba: pip install mitsuba"
  "$PY" -m pip install -q mitsuba numpy
fi

if ! dpkg -s libllvm19 >/dev/null 2>&1; then
  export DEBIAN_FRONTEND=noninteractive
  # Try with the current package lists first; refresh them only if that fails.
  if ! $SUDO apt-get install -y -qq --no-install-recommends libllvm19; then
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq --no-install-recommends libllvm19
  fi
fi

lib=$(dpkg -L libllvm19 | grep -E 'libLLVM.*\.so' | head -n 1)
echo "setup-mitsuba: mitsuba $("$PY" -c 'import mitsuba; print(mitsuba.__version__)'), LLVM library $lib"
