#!/usr/bin/env bash
# Leave-one-scene-out of a from-scratch recipe on a lent GPU machine: one nriqa-crossval process per scene
# family, PARALLEL at a time, each fold cut at FOLD_TIME; then every scene scored by its own fold's last
# checkpoint (nriqa-evaluate --crossval) and the results packed for the trip back. Run from the repository
# root there, with the dataset carried or rendered (scripts/gpu/render_train.sh without runs renders one):
#
#   OUT=$OUT DATA=data/slice scripts/gpu/loso.sh
#
# Settings (environment):
#   DATA=data/loso2629 (a dataset root: manifest.json)  OUT=/tmp/out  WORK=/tmp/loso (fold runs)
#   EXPERIMENT=unet_fast  EPOCHS=60 (x 200 batches of 8 patches of 64x64: stop 24's 12000-step recipe)
#   SEED=12345  FOLD_TIME=00:00:06:00 (Lightning max_time per fold)  PARALLEL=17 (folds at once)
#   TRAINER=gpu  DEVICE= (data.device: empty, patches made on the CPU, one core per fold; cuda: on the GPU, which
#   is slower with many folds sharing it: measured in stop 45 on one H100, 17 folds at once, 165 ms a step against
#   stop 37's 68 with CPU patches. A fold that fails within RETRY_WITHIN=180 seconds with them on DEVICE runs
#   again with them on the CPU)
#   STACKED= (1: every fold in one process, side by side: crossval.stacked, nriqa.training.stacked; one GPU
#   step serves all folds, WORKERS=nproc-1 loader processes make the patches on the CPU; PARALLEL, DEVICE and
#   RETRY_WITHIN do not apply, and FOLD_TIME cuts the run of all folds; BENCH=cuda first times a stacked step
#   against the folds one after another there, benchmarks/stacked_step.py, into the log. Where that benchmark
#   fails, or the stacked run fails within RETRY_WITHIN seconds, the folds run as processes instead, as without
#   STACKED, so a lease still ends in a result)
#   RENDER= (1: where DATA holds no dataset, render one there first with scripts/gpu/render_train.sh and no runs:
#   its settings SEED, STAGES, RES, TOP, BACKEND, JOBS, RENDER_END apply, RENDER_SCENES=[a,b] its scenes; the
#   full SITE, mitsuba included; its logs and manifest go into the pack)
#   SCENES= (space-separated families; default every family of DATA)  EXTRA= (more overrides for every fold)
#   SITE= (a tarball of scripts/gpu/pack_site.sh to unpack)  WHEELS= (a folder of wheels to install instead)
#   PY=python3
# Writes OUT/loso.log (machine, per-fold lines, the evaluation's tables) and OUT/loso_runs.tgz: eval/
# (nriqa-evaluate's tables), each fold's last checkpoint without optimiser state, its logs and result.json.
# The lent machine sends back at most 8 files of at most 16 MiB: a larger pack is cut into 15 MiB parts,
# OUT/loso_runs.tgz.part00, part01, ... (`cat loso_runs.tgz.part* | tar -xz` unpacks them).
set -u
{ # the whole script is read before it runs: editing this file during a run leaves that run as it was
T0=$(date +%s)
el() { echo $(($(date +%s) - T0)); }
cores() { env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc; } # nproc alone answers OMP_NUM_THREADS, set to 1 below
why() { grep -v -e '^\s*$' -e 'HYDRA_FULL_ERROR' "$1" | tail -1; } # FILE: the last line that says what went wrong
OUT=${OUT:-/tmp/out}
W=${WORK:-/tmp/loso}
DATA=${DATA:-data/loso2629}
PY=${PY:-python3}
mkdir -p "$OUT"
exec > >(tee -a "$OUT/loso.log") 2>&1
export PYTHONUNBUFFERED=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 PROJECT_ROOT=$PWD
if [ -n "${SITE:-}" ]; then
  tar -xJf "$SITE" -C /tmp && export PYTHONPATH=/tmp/site312:$PWD || { echo "cannot unpack $SITE"; exit 2; }
elif [ -n "${WHEELS:-}" ]; then
  "$PY" -m pip install -q --no-index --no-deps --no-compile --target /tmp/site "$WHEELS"/*.whl &&
    export PYTHONPATH=/tmp/site:$PWD || { echo "cannot install the wheels of $WHEELS"; exit 2; }
else
  export PYTHONPATH=$PWD${PYTHONPATH:+:$PYTHONPATH}
fi
if [ -n "${RENDER:-}" ] && [ ! -f "$DATA/manifest.json" ]; then
  # Render the slice here first: scripts/gpu/render_train.sh without runs (its settings: SEED, STAGES, RES, TOP,
  # BACKEND, JOBS, RENDER_END; RENDER_SCENES for its scenes). Its logs go into the pack, not into OUT.
  echo "[$(el)] rendering $DATA (scripts/gpu/render_train.sh)"
  rm -rf "${W}_render"
  OUT=${W}_render DATA=$DATA SITE='' PY=$PY SCENES=${RENDER_SCENES:-} bash scripts/gpu/render_train.sh >/dev/null 2>&1
  echo "[$(el)] render rc=$?: $(grep -h 'stage variants\|gate rc\|dataset:' "${W}_render/device.log" 2>/dev/null | tr '\n' ';')"
fi
[ -f "$DATA/manifest.json" ] || { echo "no dataset at $DATA (manifest.json missing): carry one or render it first"; exit 2; }
echo "[$(el)] $(nvidia-smi --query-gpu=name,memory.total --format=csv,noheader 2>/dev/null) $(cores) cores"
"$PY" -c "import torch, lightning, hydra, OpenEXR, kornia; print('torch', torch.__version__, 'cuda', torch.cuda.is_available())" ||
  { echo "the packages are missing: give SITE or WHEELS"; exit 2; }
SCENES=${SCENES:-$("$PY" -c "import json, sys; print(*sorted({r['scene'] for r in json.load(open(sys.argv[1]))['records']}))" "$DATA/manifest.json")}
rm -rf "$W" && mkdir -p "$W/all/folds" "$W/logs"
if [ -d "${W}_render" ]; then mv "${W}_render" "$W/render"; fi
DEV=${DEVICE:-}
echo "[$(el)] folds: $SCENES; ${PARALLEL:-all} at a time"
recipe() { # OVERRIDES...: nriqa-crossval with the recipe's settings, the OVERRIDES, then EXTRA
  # shellcheck disable=SC2086  # EXTRA is a list of overrides
  "$PY" -m nriqa.cli.crossval experiment="${EXPERIMENT:-unet_fast}" trainer="${TRAINER:-gpu}" "paths.data_dir=[$DATA]" \
    data.patch_size=64 data.batch_size=8 schedule.map.epochs="${EPOCHS:-60}" seed="${SEED:-12345}" \
    trainer.enable_progress_bar=false +trainer.max_time="${FOLD_TIME:-00:00:06:00}" "$@" ${EXTRA:-}
}
train_fold() { # SCENE DEVICE: one fold, patches made on DEVICE (empty: on the CPU)
  rm -rf "${W:?}/cv/$1"
  recipe ${2:+data.device=$2} "crossval.scenes=[$1]" crossval.out_dir="$W/cv/$1" >"$W/logs/fold_$1.txt" 2>&1
}
fold() { # SCENE
  local t0 rc
  t0=$(date +%s)
  train_fold "$1" "$DEV"
  rc=$?
  # A fold that fails early with its patches on the accelerator is run again with them on the CPU (slower,
  # but a result); one that fails late is not, so the lease still ends in time.
  if [ $rc -ne 0 ] && [ -n "$DEV" ] && [ $(($(date +%s) - t0)) -lt "${RETRY_WITHIN:-180}" ]; then
    echo "[$(el)] fold $1 failed with data.device=$DEV: $(why "$W/logs/fold_$1.txt"); again with patches on the CPU"
    train_fold "$1" ""
    rc=$?
  fi
  echo "[$(el)] fold $1 rc=$rc $(grep -h "fold $1:" "$W/logs/fold_$1.txt" | tail -1)"
}
stacked() { # every fold in this one process, side by side (crossval.stacked); WORKERS loader processes make patches
  local rc
  # shellcheck disable=SC2086  # SCENES is a list
  recipe "crossval.scenes=[$(echo $SCENES | tr ' ' ,)]" crossval.out_dir="$W/cv/stacked" crossval.stacked=true \
    data.num_workers="${WORKERS:-$(($(cores) > 2 ? $(cores) - 1 : 1))}" >"$W/logs/stacked.txt" 2>&1
  rc=$?
  echo "[$(el)] stacked rc=$rc $(grep -h '^stacked: epoch' "$W/logs/stacked.txt" | tail -1)"
  grep -h "^fold .*steps" "$W/logs/stacked.txt"
  return $rc
}
processes() { # one process per fold, PARALLEL at a time
  local pids=()  # a bare `wait` would also wait for the tee above
  for s in $SCENES; do
    fold "$s" &
    pids+=($!)
    if [ -n "${PARALLEL:-}" ] && [ ${#pids[@]} -ge "$PARALLEL" ]; then wait "${pids[@]}"; pids=(); fi
  done
  [ ${#pids[@]} -eq 0 ] || wait "${pids[@]}"
}
if [ -n "${STACKED:-}" ]; then
  if [ -n "${BENCH:-}" ]; then # what a stacked step costs here, before the run
    "$PY" benchmarks/stacked_step.py --folds "$(echo $SCENES | wc -w)" --device "$BENCH" --repeats 20 \
      >"$W/logs/bench.txt" 2>&1
    rc=$?
    tail -6 "$W/logs/bench.txt"
    if [ $rc -ne 0 ]; then
      echo "[$(el)] the stacked step failed on $BENCH (rc=$rc): the folds as processes instead"
      STACKED=
    fi
  fi
fi
if [ -n "${STACKED:-}" ]; then
  t0=$(date +%s)
  stacked
  rc=$?
  if [ $rc -ne 0 ] && [ $(($(date +%s) - t0)) -lt "${RETRY_WITHIN:-180}" ]; then
    echo "[$(el)] stacked failed early: $(why "$W/logs/stacked.txt"); the folds as processes instead"
    STACKED=
    processes
  fi
else
  processes
fi
for s in $SCENES; do
  run=$W/cv/$s/folds/$s
  [ -n "${STACKED:-}" ] && run=$W/cv/stacked/folds/$s
  if [ -d "$run" ]; then ln -s "$run" "$W/all/folds/$s"; else
    echo "fold $s left no run"; tail -3 "$W/logs/fold_$s.txt" "$W/logs/stacked.txt" 2>/dev/null; fi
done
echo "[$(el)] folds done"
# shellcheck disable=SC2086  # SCENES is a list
"$PY" -m nriqa.evaluate "$DATA" --out "$W/eval" --crossval "$W/all" --window 64 --baselines none --no-figures \
  --scenes $SCENES >"$W/logs/eval.txt" 2>&1
rc=$?
echo "[$(el)] evaluate rc=$rc"
cat "$W/eval/comparison.md" "$W/eval/per_scene.md" 2>/dev/null || tail -5 "$W/logs/eval.txt"
"$PY" - "$W" <<'P'
import pathlib, sys, torch
for p in pathlib.Path(sys.argv[1]).glob("cv/*/folds/*/checkpoints/*.ckpt"):
    if p.name != "last.ckpt":
        p.unlink()
        continue
    c = torch.load(p, map_location="cpu", weights_only=True)
    torch.save({k: c[k] for k in ("state_dict", "hyper_parameters", "epoch", "global_step", "pytorch-lightning_version") if k in c}, p)
P
pack=$W/loso_runs.tgz
tar -C "$W" --exclude='*/tensorboard/*' --exclude='*/stacked_state.pt' -czf "$pack" cv logs $([ -d "$W/eval" ] && echo eval) \
  $([ -d "$W/render" ] && echo render)
if [ "$(stat -c %s "$pack")" -gt $((15 * 1048576)) ]; then split -b 15M -d "$pack" "$OUT/loso_runs.tgz.part"; else cp "$pack" "$OUT/"; fi
echo "[$(el)] packed $(du -h "$pack" | cut -f1): $(cd "$OUT" && echo loso_runs.tgz*)"
exit
}
