#!/usr/bin/env bash
# The GPU check of sigmarl, for the first (and any) GPU machine: at most 8 minutes on one GPU.
#
#   bash benchmarks/device_check.sh            (in the repository root, on the GPU machine)
#
# Stages, each time-boxed (and all within 470 s): the GPU (nvidia-smi), the carried wheels'
# install, the imports, the cuda tests (`pytest -m cuda` over the test files that mark any),
# and benchmarks/bench_blocks.py --device cuda (S = 1, 8, 64, 256, eager; a size that would end
# past its time cap is skipped). It ends with one markdown table: the benchmark's, headed by
# the GPU and the test results. It never installs from the internet (the GPU machine is
# offline) and never stops at a failed stage: what ran is reported. Results and logs go to
# $OUT (the device tool's folder that comes back) or ./device_check.out.
#
# What must travel with the working tree (the device tool's `carry`):
# - .whl/  the wheels of the packages the GPU image lacks (torchrl, tensordict, vmas, hydra-core,
#          omegaconf and their small dependencies; not torch, not MLflow), made HERE, on a machine
#          that reaches PyPI, by `bash benchmarks/device_wheels.sh` (about 7 MB; it adds /.whl/ to
#          .git/info/exclude). They are installed with pip --no-index into /tmp/site.
# - or .venv/  a virtual environment made FOR THAT MACHINE (CPython 3.12 x86-64 with a CUDA
#          torch, sigmarl's dependencies in it); used instead of python3 when present. A venv of
#          a CPU machine does not work there (a CPU torch; here also Python 3.11).
# PYTHON=... overrides both. Nothing else: sigmarl itself runs from src/ (PYTHONPATH), the GPU image's python3 brings
# torch with CUDA, numpy, pandas, scipy, matplotlib, joblib and pytest.
# The device tool sends the session's own checkout (not a helper's worktree): run it from the
# checkout that holds this script, e.g. `run` with carry [".whl"] and the command
# `bash benchmarks/device_check.sh`, timeout_s 540.
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1
START=$SECONDS
TOTAL=${DEVICE_CHECK_SECONDS:-470}
DEST=${OUT:-$PWD/device_check.out}
mkdir -p "$DEST"
export PYTHONUNBUFFERED=1 PYTHONDONTWRITEBYTECODE=1 MPLBACKEND=Agg
if [ -n "${PYTHON:-}" ]; then PY=$PYTHON; elif [ -x .venv/bin/python ]; then PY=$PWD/.venv/bin/python; else PY=python3; fi
STATUS=()

left() { echo $((TOTAL - (SECONDS - START))); }

# stage NAME SECONDS CMD...: CMD under `timeout`, capped by what is left of the whole budget
stage() {
  local name=$1 cap=$2 rc t0=$SECONDS
  shift 2
  local budget
  budget=$(left)
  ((budget < cap)) && cap=$budget
  if ((cap < 5)); then
    STATUS+=("$name: not run (out of time)")
    return 1
  fi
  echo "== $name (at most ${cap} s)"
  timeout -k 5 "$cap" "$@" 2>&1 | tee "$DEST/$name.log"
  rc=${PIPESTATUS[0]}
  case $rc in
    0) STATUS+=("$name: ok, $((SECONDS - t0)) s") ;;
    124 | 137) STATUS+=("$name: cut at ${cap} s") ;;
    *) STATUS+=("$name: exit $rc, $((SECONDS - t0)) s") ;;
  esac
  return "$rc"
}

stage gpu 20 nvidia-smi --query-gpu=name,driver_version,memory.total,memory.used,clocks.sm --format=csv,noheader
if [ -d .whl ] && ls .whl/*.whl >/dev/null 2>&1; then
  stage wheels 60 "$PY" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
    --target /tmp/site .whl/*.whl
  export PYTHONPATH=/tmp/site
fi
export PYTHONPATH="$PWD/src${PYTHONPATH:+:$PYTHONPATH}"
stage imports 60 "$PY" -c "
import torch, tensordict, torchrl, vmas, hydra, sigmarl.cli
print('python', __import__('sys').version.split()[0], '| torch', torch.__version__, '| cuda', torch.version.cuda,
      '| available', torch.cuda.is_available(), '| torchrl', torchrl.__version__, '| tensordict', tensordict.__version__)
print(torch.cuda.get_device_name(0) if torch.cuda.is_available() else 'no CUDA device')"
IMPORTS=$?

if ((IMPORTS == 0)); then
  # only the files that mark cuda tests: collecting all would import what the GPU image lacks
  mapfile -t FILES < <(grep -l 'mark.cuda' tests/test_*.py)
  if ((${#FILES[@]})); then
    stage cuda-tests 180 "$PY" -m pytest -m cuda -q -p no:cacheprovider -o addopts="" -rfE "${FILES[@]}"
  else
    STATUS+=("cuda-tests: none found")
  fi
  # the benchmark writes its JSON after every block size, and skips a size that would end past
  # --time-limit (counted from its start, 30 s of imports and set-up kept in hand)
  cap=$(left)
  ((cap > 240)) && cap=240
  stage bench "$cap" "$PY" benchmarks/bench_blocks.py --device cuda --time-limit $((cap - 30)) \
    --json "$DEST/bench_blocks.json"
else
  STATUS+=("cuda-tests: not run (imports failed)" "bench: not run (imports failed)")
fi

echo
echo "## device_check ($(date -u '+%Y-%m-%d %H:%M UTC'), $((SECONDS - START)) s)"
for s in "${STATUS[@]}"; do echo "- $s"; done
tests=$(grep -E '[0-9]+ (passed|failed|errors?|skipped)' "$DEST/cuda-tests.log" 2>/dev/null | tail -1)
echo "- cuda tests: ${tests:-no result}"
echo
if [ -s "$DEST/bench_blocks.json" ]; then
  PYTHONPATH="$PWD/benchmarks:$PYTHONPATH" "$PY" -c "
import json, sys
import bench_blocks as b
r = json.load(open(sys.argv[1]))
print(f\"Seed blocks on {r['device']} ({r['settings']}; torch {r['torch']}; CUDA graphs {r['cuda_graphs']}):\")
print()
print(b.table(r))" "$DEST/bench_blocks.json"
else
  echo "(no benchmark result)"
fi
