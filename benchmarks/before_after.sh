#!/bin/bash
# lego before (REV, checked out in a worktree) and after (this working tree), in one sitting, alternating; seed protocol at
# 200x200; fixed step counts and no time limit (same seed: the same steps), so scores compare step for step.
# Usage: benchmarks/before_after.sh REV   (LEGO, PY, OUT override the data, the interpreter and the scratch folder)
LEGO=${LEGO:-$(dirname "$0")/../../shared/data/nerf_synthetic/lego}
PY=${PY:-python}
BEFORE=${1:?usage: before_after.sh REV (the commit to compare the working tree with)}
OUT=${OUT:-/tmp/nerfkit-before-after}; mkdir -p $OUT
ROOT=$(git -C "$(dirname "$0")" rev-parse --show-toplevel)
rm -rf $OUT/before-tree && git -C $ROOT worktree add --detach $OUT/before-tree $BEFORE >/dev/null
echo "before $(git -C $OUT/before-tree rev-parse HEAD), after $(git -C $ROOT rev-parse HEAD) $(git -C $ROOT status --porcelain --untracked-files=no -- src | grep -q . && echo "(src modified)"), $(date -u), load $(cut -d" " -f1 /proc/loadavg)"
SEED=(--train-split "train,val[0:50]" --val-split "val[50:100]" --target-width 200)
for spec in "ngp 300" "splat 1000"; do
  set -- $spec; preset=$1; steps=$2
  for side in before after; do
    if [ $side = before ]; then export PYTHONPATH=$OUT/before-tree/src; else export PYTHONPATH=$ROOT/src; fi
    run=$OUT/${side}_$preset; rm -rf $run
    t0=$(date +%s.%N)
    $PY -m nerfkit train $LEGO --out $run --preset $preset "${SEED[@]}" --max-steps $steps --no-progress > $run.train.log 2>&1
    t1=$(date +%s.%N)
    $PY -m nerfkit eval $run --split "val[50:100]" > $run.eval.log 2>&1
    echo "$side $preset train_s=$(python3 -c "print(round($t1 - $t0,1))") $(python3 -c "import json,glob;d=json.load(open(glob.glob('$run/eval_val*.json')[0]));print('psnr',round(d['psnr'],4),'ssim',round(d['ssim'],4))" 2>&1) steps=$(tail -1 $run/metrics.jsonl | python3 -c 'import json,sys;print(json.loads(sys.stdin.read())["step"])') loss=$(tail -1 $run/metrics.jsonl | python3 -c 'import json,sys;print(json.loads(sys.stdin.read())["loss"])')"
  done
done
git -C $ROOT worktree remove --force $OUT/before-tree
