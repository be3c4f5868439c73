#!/usr/bin/env bash
# The GPU measurements of issue 41, in parts that each fit one 10-minute call on a lent GPU machine (run them
# in order; each writes into RESULTS and prints what it measured):
#
#   part 1 (~7 min): device.txt (the GPU, the driver, jax's version and devices); the rasteriser backends
#          image for image and their times (splat_raster_gpu.py: pallas = Triton vs the numba host kernels,
#          200 px / 50k and 800 px / 50k and 200k Gaussians); then lego 200x200 `--preset splat` for 2 minutes
#          through the CLI (lego_cli.py: nerfkit train + eval, seed protocol; "auto" = the pallas kernels on a
#          GPU, or --backend numba if they failed to compile: splat_raster_gpu.json then holds the error) and
#          that run's 800x800 frame time (render_speed.py)
#   part 2 (~7 min): lego at its shared 400x400 (--target-width 400), --preset splat, 5 minutes
#   part 3 (~8 min): the same with --preset ngp, and that run's 800x800 frame time (the wavefront renderer
#          with all rays in flight on a GPU: 0.57 s in 14 rounds on an H200, gpu_h200/render_speed_ngp.json)
#
#   part all (one call of under 10 minutes, for a lease of 15 minutes of device time): part 1 with the backends
#          at 200 px and 800 px / 50k only and a splat step's parts (splat_step_profile.py), then parts 2
#          and 3 side by side (two processes sharing the GPU, each with 45% of its memory) for as many
#          minutes as are left of BUDGET_S (default 540 s), at most 5
#
#     bash benchmarks/gpu_lego.sh LEGO_DIR RESULTS_DIR [PART=1]
#
# On a lent machine (the device tool; 2026-12-01 on an H200): it has jax with CUDA, Triton, numba, optax, flax,
# scipy, scikit-image, imageio and matplotlib, not tyro and its needs. Here: wheels of tyro, docstring-parser,
# typeguard and typing-extensions into an excluded .whl/ (pip download --python-version 3.12 ...), lego copied
# into an excluded .lego/, both carried; there, in one call:
#   pip install --no-index --no-deps --target /tmp/site .whl/*.whl; export PYTHONPATH=/tmp/site:$PWD/src
#   NERFKIT_COMMIT=<the commit> BUDGET_S=565 timeout 582 bash benchmarks/gpu_lego.sh .lego /tmp/res all
#   then tar /tmp/res into $OUT (it holds more files than come back one by one)
set -euo pipefail
data=$1; results=$2; part=${3:-1}
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$results"
export PYTHONPATH="$here${PYTHONPATH:+:$PYTHONPATH}"

# Part 1's start, and part all's: device.txt, the backends image for image (splat_raster_gpu.py with the given
# arguments), then lego 200 px --preset splat for 2 minutes and its 800x800 frame. "auto" is pallas on a GPU; if
# its kernels failed (the JSON says why), the run trains with numba's instead; $backend keeps the choice.
splat_200() {
  { nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader || true
    python3 -c "import jax; print('jax', jax.__version__, jax.devices())"; } | tee "$results/device.txt"
  python3 "$here/splat_raster_gpu.py" "$@" --out "$results/splat_raster_gpu.json"
  backend=$(python3 -c "import json,sys; r=json.load(open(sys.argv[1]))['rows'][0]; print('numba' if 'error' in r['pallas'] else 'auto')" "$results/splat_raster_gpu.json")
  echo "splat backend for the lego runs: $backend" | tee -a "$results/device.txt"
  python3 "$here/lego_cli.py" --data "$data" --preset splat --minutes 2 --out runs/gpu_lego --results "$results" \
    --train-args "--backend $backend"
  python3 "$here/render_speed.py" runs/gpu_lego/splat_2min --data "$data" --results "$results/render_speed_splat.json"
}

case "$part" in
  1) splat_200 --reps 5 ;;
  2) python3 "$here/lego_cli.py" --data "$data" --preset splat --minutes 5 --target-width 400 --out runs/gpu_lego \
       --results "$results" ;;
  3) python3 "$here/lego_cli.py" --data "$data" --preset ngp --minutes 5 --target-width 400 --out runs/gpu_lego \
       --results "$results"
     python3 "$here/render_speed.py" runs/gpu_lego/ngp_400_5min --data "$data" --results "$results/render_speed_ngp.json" ;;
  all)
    t0=$SECONDS
    splat_200 --reps 3 --configs 200:50000 800:50000
    python3 "$here/splat_step_profile.py" runs/gpu_lego/splat_2min --results "$results/splat_step_profile.json"
    left=$(( ${BUDGET_S:-540} - (SECONDS - t0) ))
    minutes=$(python3 -c "print(f'{round(max(1.0, min(5.0, ($left - 100) / 60)), 1):g}')")
    echo "400x400, both presets side by side: $minutes minutes each ($left s of the budget left)" | tee -a "$results/device.txt"
    export XLA_PYTHON_CLIENT_MEM_FRACTION=0.45
    python3 "$here/lego_cli.py" --data "$data" --preset splat --minutes "$minutes" --target-width 400 \
      --out runs/gpu_lego --results "$results" --train-args "--backend $backend" &
    python3 "$here/lego_cli.py" --data "$data" --preset ngp --minutes "$minutes" --target-width 400 \
      --out runs/gpu_lego --results "$results"
    wait
    python3 "$here/render_speed.py" "runs/gpu_lego/ngp_400_${minutes}min" --data "$data" \
      --results "$results/render_speed_ngp.json" ;;
  *) echo "gpu_lego.sh: PART must be 1, 2, 3 or all (got $part)" >&2; exit 1 ;;
esac
