#!/usr/bin/env bash
# One-step set-up for the README's quick start and for CI: installs s2cl in editable mode with the
# extras named as arguments (e.g. `bash tools/setup.sh test`), then, best effort and only where
# needed, system packages:
#   - libgfortran5, the Fortran runtime of the optional 6S binaries (without it the 6S tests skip);
#   - pocl-opencl-icd, the distribution's PoCL, when the PoCL of the pyopencl wheel (LLVM 14) cannot build
#     the vector width this CPU reports (`s2cl devices` probes it by building): it cannot compile at all on
#     CPUs newer than LLVM 14 (AMD Zen 5: "unknown target CPU 'generic'") and compiles for an AVX2 target on
#     AMD Zen 4, half the AVX-512 width. With the `test` extra it is installed wherever it can be, so that
#     the kernel tests run on both drivers.
# The `test` extra includes `geo` (rasterio with its GDAL wheel, pyproj): GeoTIFF products and --format cog.
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
# "CLEAN REPORTED": the default device's clean float32 width and the widest any PoCL CPU device reports
# (0 0 when no device builds)
widths() {
  python -m s2cl devices --json 2>/dev/null | python -c '
import json, sys
try:
    rows = json.load(sys.stdin)
except ValueError:
    rows = []
pocl = [r for r in rows if "Portable" in r["platform"] and "CPU" in r["kind"]]
default = next((r["clean"]["float32"] for r in rows if r["default"]), 0)
print(default, max((r["reported"]["float32"] for r in pocl), default=0))' || echo "0 0"
}
read -r clean reported <<<"$(widths)"
if [ "$clean" -lt "$reported" ] || [ "$clean" = 0 ] || [ "$extras" = test ]; then
  if ! dpkg -s pocl-opencl-icd >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
      apt_install pocl-opencl-icd
      read -r clean reported <<<"$(widths)"
    elif [ "$clean" -lt "$reported" ]; then
      echo "note: this CPU reports $reported float lanes but the installed OpenCL driver builds $clean cleanly;" \
           "the distribution's PoCL (apt-get install pocl-opencl-icd, needs root) may build all $reported" >&2
    fi
  fi
fi
python -m s2cl devices >/dev/null || { python -m s2cl devices; exit 1; }
