#!/usr/bin/env bash
# The kernel tests on every OpenCL CPU driver installed here, on this CPU and on an AVX2 target, with one
# line per (target, driver, precision, width) at the end.
#
# The AVX2 target is real: valgrind hides AVX-512 from CPUID, so PoCL compiles for `haswell` there. On it
# every device is made to *report* 16 float lanes ($S2CL_REPORTED_WIDTH=16), as the pyopencl wheel's PoCL does
# on AMD Zen 4 while compiling for an AVX2 target: the width probe must step down to 8, the kernel tests
# must pass with builds that may not warn, and `s2cl simulate -q` (the README's main job, PoCL's kernel
# cache off) must print nothing but its result line. The lines, headed by the CPU's model and family, go to
# bench/results/cpu-check-family<F>-model<M>.txt (one per CPU) and, with every other CPU's, into docs/devices.md
# (between its cpu-check markers).
#   bash tools/cpu_check.sh                   (about 10 minutes on 2 cores; needs valgrind for the AVX2
#                                              part: apt-get install valgrind, else that part is skipped)
set -euo pipefail
cd "$(dirname "$0")/.."
py=$(python -c "import sys; print(sys.executable)")  # the interpreter itself, not a shim script
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}" S2CL_BUILD_WARNINGS=error
unset PYOPENCL_CTX S2CL_TEST_DEVICES S2CL_LANES
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
KERNEL_TESTS=(-m kernel tests)  # every test that runs kernels on the device under test (tests/conftest.py)
# under valgrind (about 30x slower): the vectorised kernels at the widths that matter there (8, and 16, which
# must step down)
AVX2_TESTS=(tests/test_vecmath.py tests/test_indices.py tests/test_noise_kernel.py tests/test_sam.py
  tests/test_resample_kernel.py tests/test_sweep_kernel.py "tests/test_igrm.py::test_lane_width_does_not_change_results")
# hwloc says at start-up that it cannot read the CPU topology under valgrind: not our output
unhwloc() { grep -v -e "hwloc x86 backend" -e "hwloc-gather-cpuid" -e "HWLOC_CPUID_PATH" || true; }
status=0

# run_on LABEL RUNNER...: list the devices as RUNNER sees them, run the kernel tests on each that builds, and
# append one line per (driver, precision, width) to $work/lines
run_on() {
  local label=$1; shift
  # exit status 2 when no device builds: the JSON still lists them, with why (reported below)
  "$@" "$py" -m s2cl devices --json 2> >(unhwloc >&2) > "$work/$label.json" || true
  local specs
  specs=$("$py" -c "import json,sys; print(' '.join(r['spec'] for r in json.load(open(sys.argv[1])) if r['builds']))" \
          "$work/$label.json")
  for spec in $specs; do
    local tests=("${KERNEL_TESTS[@]}") extra=()
    [ "$label" = native ] || { tests=("${AVX2_TESTS[@]}"); extra=(-k "lanes16 or lanes8 or lane_width"); }
    echo "== $label, device $spec: kernel tests" >&2
    if "$@" "$py" -m pytest -q -p no:cacheprovider --device "$spec" "${tests[@]}" "${extra[@]}" \
         > "$work/$label-$spec.log" 2>&1; then
      result="passed ($(grep -Eo '[0-9]+ passed' "$work/$label-$spec.log" | head -1))"
    else
      result="FAILED (log below)"; status=1
      unhwloc < "$work/$label-$spec.log" | tail -40 >&2
    fi
    "$py" - "$work/$label.json" "$spec" "$label" "$result" >> "$work/lines" <<'EOF'
import json, sys
rows, spec, label, result = json.load(open(sys.argv[1])), sys.argv[2], sys.argv[3], sys.argv[4]
row = next(r for r in rows if r["spec"] == spec)
for real_t in ("float32", "float64"):
    checks = [c for c in row["checks"] if c[0] == real_t]
    why = "; ".join(f"{w} {'builds clean' if v == 'clean' else v}" for _, w, v, _ in checks) or "not probed"
    print(f"{label:6} | {spec} {row['platform'][:28]} {row['driver']} ({row['target'] or '?'}) | {real_t}: "
          f"{row['clean'][real_t]} lanes (reported {row['reported'][real_t]}; {why}) | kernel tests {result}")
EOF
  done
  "$py" -c "import json,sys; [print(f\"$label | {r['spec']} {r['platform'][:28]} {r['driver']} ({r['target'] or '?'}) | \"
            f\"cannot compile: {r['why_not']}\") for r in json.load(open(sys.argv[1])) if not r['builds']]" \
    "$work/$label.json" >> "$work/lines"
}

export S2CL_CACHE="$work/cache"  # fresh verdicts: every width is probed again here
run_on native
if command -v valgrind >/dev/null; then
  S2CL_REPORTED_WIDTH=16 run_on avx2 valgrind --tool=none -q --trace-children=yes
  echo "== avx2: s2cl simulate -q (reported 16 lanes, kernel cache off)" >&2
  printed=$(S2CL_REPORTED_WIDTH=16 POCL_KERNEL_CACHE=0 valgrind --tool=none -q --trace-children=yes \
            "$py" -m s2cl simulate -q -o "$work/sim" 2>&1 | unhwloc) || true
  echo "$printed" >&2
  if grep -qiE "warning|generated|error" <<<"$printed" || [ ! -d "$work/sim" ]; then
    echo "avx2   | s2cl simulate -q: FAILED or printed compiler output" >> "$work/lines"; status=1
  else
    echo "avx2   | s2cl simulate -q: quiet, results written" >> "$work/lines"
  fi
else
  echo "avx2   | skipped: valgrind is not installed (apt-get install valgrind)" >> "$work/lines"
fi
"$py" - "$work/lines" <<'EOF'
import datetime, pathlib, platform, re, sys
info = pathlib.Path("/proc/cpuinfo").read_text() if pathlib.Path("/proc/cpuinfo").exists() else ""
def field(name):
    match = re.search(rf"^{name}\s*:\s*(.*)$", info, re.M)
    return match.group(1).strip() if match else "?"
flags = field("flags").split()
simd = "AVX-512" if "avx512f" in flags else "AVX2" if "avx2" in flags else "no AVX2"
head = (f"# bash tools/cpu_check.sh, {datetime.date.today().isoformat()}: {field('model name')} "
        f"(CPU family {field('cpu family')}, model {field('model')}, {simd}), {platform.machine()}")
text = head + "\n" + pathlib.Path(sys.argv[1]).read_text()
# one file per CPU (family and model), so that the page keeps every CPU this check has run on
slug = re.sub(r"[^0-9a-z]+", "", field("cpu family")) + "-model" + re.sub(r"[^0-9a-z]+", "", field("model"))
pathlib.Path(f"bench/results/cpu-check-family{slug}.txt").write_text(text)
everything = "\n".join(p.read_text() for p in sorted(pathlib.Path("bench/results").glob("cpu-check-*.txt")))
docs = pathlib.Path("docs/devices.md")
page = docs.read_text(encoding="utf-8")
start, end = "<!-- cpu-check: written by tools/cpu_check.sh -->", "<!-- /cpu-check -->"
if start in page and end in page:
    before, rest = page.split(start, 1)
    docs.write_text(before + start + "\n```\n" + everything + "```\n" + end + rest.split(end, 1)[1],
                    encoding="utf-8")
print("\n" + text, end="")
EOF
exit $status
