#!/usr/bin/env bash
# The device check of issue 25 (part 5), as one prepared command for a lent GPU machine:
#   run(command="bash benchmarks/gpu_run.sh", carry=[".whl"], timeout_s=540)
# It uses the machine's own JAX (CUDA) and, only if jaxclear fails on its diffrax/equinox, the
# pure-Python wheels of this project's versions carried in .whl/ (pip download --no-deps
# diffrax==0.7.2 equinox==0.13.8 lineax==0.1.1 optimistix==0.1.0 jaxtyping wadler-lindig -d .whl).
# Results: $OUT/gpu.jsonl (one JSON line per measurement, written as they come) and $OUT/log.txt.
export PYTHONUNBUFFERED=1 PYTHONPATH=$PWD
OUT=${OUT:-/tmp/gpu-out}; mkdir -p "$OUT"
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader; nproc
python3 -c "import jax,diffrax,equinox,lineax,optimistix;print('versions',jax.__version__,diffrax.__version__,equinox.__version__,lineax.__version__,optimistix.__version__)"
SMOKE="import jaxclear,numpy as np;from jaxclear.mechanisms import slider_crank as s;t=jaxclear.simulate(s(rpm=5000.0,clearance_joints='B'),2e-4,num_points=2);print('smoke ok',np.asarray(t.q[-1,6]))"
JAX_PLATFORMS=cpu timeout 120 python3 -c "$SMOKE" 2>&1 | tail -3 | tee "$OUT/smoke.txt"
if ! grep -q "smoke ok" "$OUT/smoke.txt" && ls .whl/*.whl >/dev/null 2>&1; then
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl
  export PYTHONPATH=/tmp/site:$PWD
  JAX_PLATFORMS=cpu timeout 120 python3 -c "$SMOKE" 2>&1 | tail -3
fi
timeout 430 python3 benchmarks/gpu_ensemble.py --json "$OUT/gpu.jsonl" "$@" 2>&1 | tee "$OUT/log.txt"
