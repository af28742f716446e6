#!/usr/bin/env bash
# Companion of tools/gpu_check.sh: downloads, here (network), the Python 3.12 wheels that s2cl's kernel
# tests and `python -m bench --quick` need beyond what a lent GPU machine has (numpy, scipy, xarray, pyarrow,
# h5py, matplotlib, rich, pandas, click), into FOLDER (default .whl, kept out of git). About 64 MB: the PoCL
# wheel, the CPU driver the GPU is compared with, is 58 MB of it.
#   bash tools/gpu_wheels.sh [FOLDER]
set -euo pipefail
cd "$(dirname "$0")/.."
dest="${1:-.whl}"
mkdir -p "$dest"
if [ "$dest" = .whl ] && [ -d .git ] && ! grep -qx "/.whl/" .git/info/exclude 2>/dev/null; then
  echo "/.whl/" >> .git/info/exclude
fi
# s2cl's own needs (pyproject.toml) and the tests', each with what it needs in turn, minus what the GPU
# machine brings; one version of each
WHEELS=(
  pyopencl pytools platformdirs typing-extensions siphash24 pocl-binary-distribution
  pydantic annotated-types typing-inspection
  mako markupsafe
  h5netcdf packaging spectral filelock psutil
  pytest pluggy iniconfig hypothesis sortedcontainers attrs pytest-benchmark py-cpuinfo
)
platforms=()
for p in manylinux_2_28_x86_64 manylinux_2_27_x86_64 manylinux_2_17_x86_64 manylinux2014_x86_64 manylinux1_x86_64; do
  platforms+=(--platform "$p")
done
python -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
  "${platforms[@]}" -d "$dest" "${WHEELS[@]}"
# pydantic pins its core exactly: take the version its metadata names, not the newest
core=$(python - "$dest" <<'EOF'
import pathlib, re, sys, zipfile
wheel = max(pathlib.Path(sys.argv[1]).glob("pydantic-[0-9]*.whl"))
meta = next(n for n in zipfile.ZipFile(wheel).namelist() if n.endswith(".dist-info/METADATA"))
text = zipfile.ZipFile(wheel).read(meta).decode()
print(re.search(r"^Requires-Dist: pydantic-core\s*\(?==\s*([^\s;)]+)", text, re.M).group(1))
EOF
)
rm -f "$dest"/pydantic_core-*.whl
python -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
  "${platforms[@]}" -d "$dest" "pydantic-core==$core"
# the versions the pyproject asks for, checked here rather than on a machine that cannot fetch another
python - "$dest" <<'EOF'
import pathlib, re, sys
have = {re.split(r"-\d", w.name, maxsplit=1)[0].lower().replace("_", "-") for w in pathlib.Path(sys.argv[1]).glob("*.whl")}
need = {"pyopencl", "pocl-binary-distribution", "pydantic", "pydantic-core", "mako", "h5netcdf", "spectral",
        "filelock", "psutil", "pytest", "hypothesis"}
missing = sorted(need - have)
if missing:
    sys.exit(f"gpu_wheels: not downloaded: {', '.join(missing)}")
EOF
du -sh "$dest" | awk '{print "gpu_wheels: " $1 " in " $2}'
ls "$dest"
