#!/usr/bin/env bash
# s2cl on a GPU, in one go, for a machine with an NVIDIA GPU and no network: Python 3.12 with numpy, scipy,
# xarray, pyarrow, h5py, matplotlib, rich, pandas and click; NVIDIA's driver libraries mounted read-only;
# an OpenCL vendor file perhaps registered, perhaps not. Under 10 minutes.
#
#   bash tools/gpu_wheels.sh            # beforehand, on a machine with network: the wheels into .whl/
#   bash tools/gpu_check.sh OUTDIR      # on the GPU machine, from the repository root, .whl/ beside it
#
# It installs the wheels s2cl lacks there (into OUTDIR/site, nothing system-wide), points the OpenCL ICD
# loader at NVIDIA's OpenCL library (a vendors folder of its own, $OCL_ICD_VENDORS), lists the devices
# with their widths, and says in one line if no GPU device appears; else it runs the kernel tests on the
# GPU (`pytest -m kernel --device GPU`) and `python -m bench --quick` on the GPU and on the CPU (PoCL), each
# with a time limit so that the whole ends within about 560 s. Logs, JSON and summary.txt go under OUTDIR.
#
# Environment: S2CL_WHEELS (wheel folder, default .whl); S2CL_GPU=SPEC treats that device as the GPU (a
# rehearsal on a machine without one: S2CL_GPU=0:0 lets PoCL stand in); PYTHON (default python3).
set -uo pipefail
cd "$(dirname "$0")/.."
[ $# -eq 1 ] || { echo "usage: bash tools/gpu_check.sh OUTDIR" >&2; exit 2; }
out=$(mkdir -p "$1" && cd "$1" && pwd) || { echo "gpu_check: cannot create $1" >&2; exit 2; }
py="${PYTHON:-python3}"
wheels="${S2CL_WHEELS:-.whl}"
t0=$(date +%s)
log="$out/gpu_check.log"
: > "$log"
say() { echo "gpu_check: $*" | tee -a "$log"; }
elapsed() { echo $(( $(date +%s) - t0 )); }
# run LIMIT_S NAME CMD...: run with a time limit, output to OUTDIR/NAME.log, one line in the summary
run() {
  local limit=$1 name=$2; shift 2
  local start rc
  start=$(date +%s)
  PYTHONUNBUFFERED=1 timeout -k 10 "$limit" "$@" > "$out/$name.log" 2>&1
  rc=$?
  local took=$(( $(date +%s) - start ))
  local tail_line
  tail_line=$(grep -E "passed|failed|error|\[bench\] total" "$out/$name.log" | tail -1)
  [ $rc -eq 124 ] && tail_line="stopped at its ${limit} s limit"
  say "$name: rc $rc in ${took} s${tail_line:+ — $tail_line}"
  return $rc
}

# 1. the wheels s2cl lacks here (absent, or older than the carried one), into OUTDIR/site
[ -d "$wheels" ] || { say "no wheel folder $wheels (make it with tools/gpu_wheels.sh where there is network)"; exit 2; }
site="$out/site"
missing=$("$py" - "$wheels" <<'EOF'
import importlib.metadata as md, pathlib, re, sys
try:
    from packaging.version import Version
except ImportError:  # compare as text where packaging is absent
    Version = str
for whl in sorted(pathlib.Path(sys.argv[1]).glob("*.whl")):
    name, version = whl.name.split("-")[:2]
    try:
        have = md.version(name)
    except md.PackageNotFoundError:
        have = None
    try:
        older = have is not None and Version(have) < Version(version)
    except Exception:
        older = False
    if have is None or older:
        print(whl)
EOF
)
if [ -n "$missing" ]; then
  # shellcheck disable=SC2086
  "$py" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target "$site" $missing \
    >> "$log" 2>&1 || { say "pip could not install the carried wheels (see $log)"; exit 2; }
  say "installed $(echo "$missing" | wc -l) wheels into $site: $(echo "$missing" | xargs -n1 basename | cut -d- -f1 | tr '\n' ' ')"
fi
export PYTHONPATH="$site:$PWD${PYTHONPATH:+:$PYTHONPATH}"
export S2CL_CACHE="$out/cache"
unset PYOPENCL_CTX S2CL_TEST_DEVICES S2CL_LANES

# 2. the OpenCL vendors: those registered system-wide, plus NVIDIA's library when no file names it
vendors="$out/vendors"
mkdir -p "$vendors"
cp /etc/OpenCL/vendors/*.icd "$vendors/" 2>/dev/null
nvlib=$( (ldconfig -p 2>/dev/null | awk '/libnvidia-opencl\.so\.1/ {print $NF; exit}') )
if [ -z "$nvlib" ]; then
  nvlib=$(find /usr/local/nvidia /usr/lib/x86_64-linux-gnu /usr/lib64 /usr/lib /usr/local/cuda -maxdepth 3 \
          -name 'libnvidia-opencl.so.1' 2>/dev/null | head -1)
fi
if [ -n "$nvlib" ] && ! grep -qs "libnvidia-opencl" "$vendors"/*.icd; then
  echo "$nvlib" > "$vendors/nvidia.icd"
fi
export OCL_ICD_VENDORS="$vendors"
say "NVIDIA OpenCL library: ${nvlib:-not found}; vendor files: $(ls "$vendors" | tr '\n' ' ')"
timeout 30 nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader >> "$log" 2>&1

# 3. the devices, their widths, and the GPU
if ! timeout 60 "$py" -c "import s2cl, pyopencl" >> "$log" 2>&1; then
  say "s2cl or pyopencl does not import with the carried wheels (see $log)"
  exit 2
fi
# the first listing probes every device's widths (a child per device, at most 120 s each)
timeout 300 "$py" -m s2cl devices > "$out/devices.txt" 2>&1
timeout 60 "$py" -m s2cl devices --json > "$out/devices.json" 2>> "$log"
cat "$out/devices.txt" >> "$log"
read -r gpu cpu <<<"$("$py" - "$out/devices.json" "${S2CL_GPU:-}" <<'EOF'
import json, sys
try:
    rows = json.load(open(sys.argv[1]))
except (OSError, ValueError):
    rows = []
forced = sys.argv[2]
gpus = [r["spec"] for r in rows if r["builds"] and (r["spec"] == forced if forced else "GPU" in r["kind"])]
cpus = [r["spec"] for r in rows if r["builds"] and "CPU" in r["kind"]]
print(gpus[0] if gpus else "-", cpus[0] if cpus else "-")
EOF
)"
if [ "$gpu" = "-" ]; then
  say "no GPU OpenCL device appeared (NVIDIA OpenCL library: ${nvlib:-not found}); devices: $(grep -E '^[* ] [0-9]' "$out/devices.txt" | tr '\n' ';')"
  exit 3
fi
say "GPU device $gpu$([ -n "${S2CL_GPU:-}" ] && echo " (stand-in named by S2CL_GPU)"); CPU device $cpu"
sed -n "/^[* ] $gpu /,/^[* ] [0-9]/p" "$out/devices.txt" | head -3 | tee -a "$log"

# 4. the kernel tests on the GPU, then the quick benchmarks on the GPU and the CPU
status=0
# a kernel build that warns fails the tests (as in CI); the benchmarks only log it
S2CL_BUILD_WARNINGS=error run 270 kernel-tests-gpu "$py" -m pytest -q -p no:cacheprovider -m kernel \
  --device "$gpu" --junitxml "$out/kernel-tests-gpu.xml" tests || status=1
left=$(( 510 - $(elapsed) ))
share=$(( left / 2 ))
if [ "$share" -gt 30 ]; then
  PYOPENCL_CTX="$gpu" run "$share" bench-gpu "$py" -m bench --quick --out "$out/bench-gpu" || status=1
else
  say "bench-gpu: skipped (no time left)"; status=1
fi
if [ "$cpu" != "-" ] && [ "$(( 540 - $(elapsed) ))" -gt 30 ]; then
  PYOPENCL_CTX="$cpu" run $(( 540 - $(elapsed) )) bench-cpu "$py" -m bench --quick --out "$out/bench-cpu" || status=1
else
  say "bench-cpu: skipped (no CPU device, or no time left)"
fi

# 5. the summary: one line per step (above) and the benchmark figures side by side
"$py" - "$out" <<'EOF' | tee -a "$log" > "$out/summary.txt"
import json, pathlib, sys
out = pathlib.Path(sys.argv[1])
for line in (out / "gpu_check.log").read_text().splitlines():
    if line.startswith("gpu_check: "):
        print(line)
for side in ("gpu", "cpu"):
    for path in sorted((out / f"bench-{side}").glob("*.json")):
        r = json.loads(path.read_text())
        m = r.get("machine", {})
        print(f"bench {side}: {m.get('opencl_device')} (driver {m.get('opencl_driver')}, lanes {m.get('lanes')}): "
              f"{r.get('seconds_total', 0):.0f} s, {path.name}")
EOF
say "done in $(elapsed) s; rc $status; everything is under $out"
exit $status
