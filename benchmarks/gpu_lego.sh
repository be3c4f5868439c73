#!/usr/bin/env bash
# Lego on a GPU through the CLI, as a user runs it: ngp then splat at M minutes (benchmarks/lego_cli.py:
# nerfkit train + nerfkit eval, seed protocol, 200x200), then each run's 800x800 frame time
# (benchmarks/render_speed.py). The splat rasteriser's numba tile kernels run on the host CPU (the rest of a
# step on the GPU); benchmarks/results/gpu_h200/ was measured before that, with the pure-JAX reference.
# Writes into RESULTS: lego_cli_{ngp,splat}.json + .png, render_speed_{ngp,splat}.json and device.txt
# (the GPU, the driver, jax's version and devices).
#
#     bash benchmarks/gpu_lego.sh LEGO_DIR RESULTS_DIR [MINUTES=2]
set -euo pipefail
data=$1; results=$2; minutes=${3:-2}
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$results"
{ nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader || true
  python3 -c "import jax; print('jax', jax.__version__, jax.devices())"; } | tee "$results/device.txt"
for preset in ngp splat; do
  python3 "$here/lego_cli.py" --data "$data" --preset "$preset" --minutes "$minutes" --out runs/gpu_lego \
    --results "$results"
  python3 "$here/render_speed.py" "runs/gpu_lego/${preset}_${minutes}min" --data "$data" \
    --results "$results/render_speed_$preset.json"
done
