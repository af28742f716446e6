#!/usr/bin/env bash
# One-step set-up for the README's quick start and for CI: installs s2cl in editable mode with the
# extras named as arguments (e.g. `bash tools/setup.sh test`), then, best effort and only where
# needed, two system libraries:
#   - libgfortran5, the Fortran runtime of the optional 6S binaries (without it the 6S tests skip);
#   - pocl-opencl-icd, the distribution's PoCL, when the PoCL of the pyopencl wheel (LLVM 14) cannot
#     compile for this CPU (CPU models newer than LLVM 14, e.g. AMD Zen 5: "unknown target CPU 'generic'").
set -euo pipefail
cd "$(dirname "$0")/.."
extras="${1:-}"
python -m pip install -q -e ".${extras:+[$extras]}"

apt_install() {
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    (apt-get update -qq && apt-get install -y -qq "$@") >/dev/null 2>&1 || echo "note: could not install $*" >&2
  else
    echo "note: $* missing; install it with your package manager (needs root)" >&2
  fi
}

if [ "$extras" = test ] || [ "$extras" = sixs ]; then
  ldconfig -p 2>/dev/null | grep -q 'libgfortran\.so\.5' || apt_install libgfortran5
fi
if ! python -m s2cl devices -q >/dev/null 2>&1; then
  apt_install pocl-opencl-icd
  python -m s2cl devices >/dev/null || { python -m s2cl devices; exit 1; }
fi
