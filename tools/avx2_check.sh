#!/usr/bin/env bash
# Check the AVX2 code path on a machine with AVX-512 (or any x86 CPU): valgrind hides AVX-512 from
# CPUID, so PoCL under valgrind targets an AVX2 CPU ("pthread-haswell", 8 float lanes) for real.
# Runs the vectorised kernels' tests with kernel builds that must be warning-free, then
# `s2cl simulate -q` with PoCL's kernel cache off, which must print nothing but its "wrote" line.
# Slow (valgrind): about 3 minutes for the tests and 5 for the simulation on 2 cores.
#   bash tools/avx2_check.sh            (needs valgrind: apt-get install valgrind)
set -euo pipefail
cd "$(dirname "$0")/.."
command -v valgrind >/dev/null || { echo "valgrind is not installed (apt-get install valgrind)" >&2; exit 2; }
py=$(python -c "import sys; print(sys.executable)")  # the interpreter itself, not a shim script
vg=(valgrind --tool=none -q)
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}" POCL_KERNEL_CACHE=0 S2CL_BUILD_WARNINGS=error
# hwloc says at start-up that it cannot read the CPU topology under valgrind: not our output
unhwloc() { grep -v -e "hwloc x86 backend" -e "hwloc-gather-cpuid" -e "HWLOC_CPUID_PATH" || true; }

"${vg[@]}" "$py" -m s2cl -v devices 2>&1 | unhwloc | grep -E "DEBUG: OpenCL device|^\*"
"${vg[@]}" "$py" -m pytest -q -p no:cacheprovider tests/test_runtime.py tests/test_vecmath.py tests/test_indices.py tests/test_noise_kernel.py \
  tests/test_sam.py tests/test_resample_kernel.py tests/test_sweep_kernel.py \
  "tests/test_igrm.py::test_lane_width_does_not_change_results"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
printed=$("${vg[@]}" "$py" -m s2cl simulate -q -o "$out/sim" 2>&1 | unhwloc)
echo "$printed"
if grep -qiE "warning|generated" <<<"$printed"; then
  echo "FAIL: s2cl simulate printed compiler output on the AVX2 target" >&2
  exit 1
fi
echo "OK: AVX2 target quiet and correct"
