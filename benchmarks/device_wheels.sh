#!/usr/bin/env bash
# Prepare .whl/: the wheels benchmarks/device_check.sh installs on a GPU machine that is offline.
#
# Run HERE (a machine that reaches PyPI), in the repository root:  bash benchmarks/device_wheels.sh
# It downloads, without dependencies, the packages sigmarl needs that the GPU image lacks (its
# python3 has a CUDA torch, numpy, pandas, scipy, matplotlib, joblib, pytest, PyYAML, tqdm,
# filelock, imageio, cloudpickle, six, packaging, zipp), at the versions installed in this
# machine's environment (what the tests here pass with), as CPython 3.12 x86-64 wheels; the few
# that PyPI has only as source (vmas, antlr4-python3-runtime, gym) are pure Python and are built
# into wheels here. torch is not among them: the GPU's own CUDA build is used. MLflow is not
# needed: the cuda tests and the benchmark run with tracking off. About 7 MB.
# .whl/ is added to .git/info/exclude (it travels with the device tool's `carry: [".whl"]`).
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-/work/venv/bin/python}
[ -x "$PY" ] || PY=python3
NAMES="torchrl tensordict pyvers hoptorch orjson importlib_metadata vmas pyglet gym gym-notices
hydra-core omegaconf antlr4-python3-runtime hydra-joblib-launcher"
mkdir -p .whl
exclude="$(git rev-parse --git-common-dir)/info/exclude"
grep -qx '/.whl/' "$exclude" 2>/dev/null || echo '/.whl/' >>"$exclude"
for name in $NAMES; do
  version=$("$PY" -c "import importlib.metadata as m, sys; print(m.version(sys.argv[1]))" "$name")
  if ! "$PY" -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
      --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \
      --platform manylinux2014_x86_64 --platform manylinux1_x86_64 -d .whl "$name==$version" 2>/dev/null; then
    "$PY" -m pip wheel -q --no-deps -w .whl "$name==$version"  # pure Python, only a source release
  fi
  echo "$name $version"
done
du -sh .whl
