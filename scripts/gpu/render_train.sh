#!/usr/bin/env bash
# One short lease of a GPU machine (a bare one: Python 3.12 with PyTorch and Lightning, nothing fetched):
# render a v2-preset training set with Mitsuba's cuda_ad_rgb variant in stages (each stage a complete,
# resumable dataset), gate it (data_gen.convergence --drop-noisy --drop-suspect), then train the runs named on the command
# line side by side on the one GPU until the time is up. Run from the repository root there, with the
# tarball of scripts/gpu/pack_site.sh beside it (SITE):
#
#   OUT=/tmp/out scripts/gpu/render_train.sh 'ft init_from=unet_fast schedule.map.lr=1e-4 seed=33' \
#                                            'scratch schedule.map.lr=1e-3 seed=34'
#
# Each argument is a run: its name, then overrides of `train.py experiment=$EXPERIMENT` (64x64 patches,
# batch 8, the GPU trainer, no validation scene). Its last checkpoint is copied to $OUT/NAME.ckpt.
# Settings (environment, seconds counted from the start of this script):
#   SITE=.dev/site312.tar.xz  SEED=3 (base seed of the scenes)  STAGES="3 8 16 28 40" (cumulative variants)
#   RES=64  TOP=1024 (ladder top; references 16x)  SCENES= (a list such as [cornell,door]; default: the preset's)  RENDER_END=250  END=510 (training stops by then)
#   BACKEND=cuda_ad_rgb (scalar_rgb to try the script on a CPU)  JOBS=14 (render processes sharing the GPU)  WORKERS=7 (patch loaders per run)  EXPERIMENT=unet_fast
#   CHECK_BACKENDS=1: first render one variant per family with cuda_ad_rgb and with scalar_rgb (ladder to 64)
#   and print the true mean SSIM of each rung under both: whether the backends' noise agrees.
# Measured on an H200 (stop 33, docs/cluster.md): 33 images/s at 64x64 with 14 processes; 64 training steps/s
# for each of two unet_fast runs sharing the GPU.
set -u
{ # the whole script is read before it runs: editing this file during a run leaves that run as it was
T0=$(date +%s)
el() { echo $(($(date +%s) - T0)); }
OUT=${OUT:-/tmp/out}
SITE=${SITE-.dev/site312.tar.xz}
RENDER_END=${RENDER_END:-250}
END=${END:-510}
EXPERIMENT=${EXPERIMENT:-unet_fast}
D=${DATA:-/tmp/v2gpu}
mkdir -p "$OUT"
exec > >(tee -a "$OUT/device.log") 2>&1
export PYTHONUNBUFFERED=1
if [ -n "$SITE" ]; then
  tar -xJf "$SITE" -C /tmp && export PYTHONPATH=/tmp/site312:$PWD || { echo "cannot unpack $SITE"; exit 2; }
fi
PY=${PY:-python3}
echo "[$(el)] $(nvidia-smi --query-gpu=name,memory.total --format=csv,noheader 2>/dev/null) $(env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc) cores"
"$PY" -c "import torch, lightning, mitsuba, hydra, OpenEXR, kornia; print('torch', torch.__version__, torch.cuda.is_available())" || exit 2
BACKEND=${BACKEND:-cuda_ad_rgb}
"$PY" -c "import sys; from nriqa.render.backend import probe_variant as p; ok, why = p('$BACKEND', 90); print('probe $BACKEND:', why); sys.exit(not ok)" ||
  { echo "$BACKEND does not work here"; exit 2; }

render() { # OUTDIR VARIANTS BACKEND JOBS LADDER_TOP SECONDS
  timeout "$6" "$PY" -m data_gen preset=v2 out="$1" seed="${SEED:-3}" variants="$2" \
    "resolution=[${RES:-64},${RES:-64}]" ladder_top="$5" reference_factor=16 backend="$3" jobs="$4" ${SCENES:+"scenes=$SCENES"}
}

if [ -n "${CHECK_BACKENDS:-}" ]; then
  for b in cuda_ad_rgb scalar_rgb; do
    j=${JOBS:-14}; [ $b = scalar_rgb ] && j=$(env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc)
    s=$(date +%s)
    render /tmp/check_$b 1 $b "$j" 64 240 >"$OUT/check_$b.log" 2>&1
    echo "[$(el)] check $b rc=$? $(($(date +%s) - s)) s"
  done
  "$PY" - <<'P'
from collections import defaultdict
from pathlib import Path

from data_gen.report import error_rows
from nriqa.io.manifest import read_manifest

def ladder(root):  # (scene, algorithm, spp) -> true mean SSIM, as data_gen.report measures it
    return {(r["scene"], r["algorithm"], r["spp"]): 1 - r["one_minus_ssim"] for r in error_rows(Path(root), read_manifest(root)[0])}

try:
    c, s = ladder("/tmp/check_cuda_ad_rgb"), ladder("/tmp/check_scalar_rgb")
except Exception as exc:  # a check, not the run: say why and go on
    print("backend check failed:", exc)
else:
    by_spp = defaultdict(list)
    for key in c.keys() & s.keys():
        by_spp[key[2]].append((c[key], s[key]))
    print("true mean SSIM per rung: cuda_ad_rgb / scalar_rgb (difference)")
    for spp, pairs in sorted(by_spp.items()):
        dc, ds = (sum(p[i] for p in pairs) / len(pairs) for i in (0, 1))
        print(f"  {spp:5d} spp: {dc:.4f} / {ds:.4f} ({dc - ds:+.4f}) over {len(pairs)} ladders")
P
fi

GOOD=""
for V in ${STAGES:-3 8 16 28 40}; do
  left=$((RENDER_END - $(el)))
  [ $left -lt 20 ] && break
  s=$(date +%s)
  render "$D" "$V" "$BACKEND" "${JOBS:-14}" "${TOP:-1024}" "$left" >"$OUT/render_v$V.log" 2>&1
  rc=$?
  echo "[$(el)] stage variants=$V rc=$rc $(($(date +%s) - s)) s: $(tail -n 1 "$OUT/render_v$V.log")"
  [ $rc -eq 0 ] || break
  cp "$D/manifest.json" /tmp/manifest_complete.json
  GOOD=$V
done
[ -n "$GOOD" ] || { echo "no stage finished"; exit 3; }
cp /tmp/manifest_complete.json "$D/manifest.json" # the stage cut short wrote no manifest; its files stay unused
timeout "${GATE_SECONDS:-45}" "$PY" -m data_gen.convergence "$D" --drop-noisy --drop-suspect >"$OUT/gate.log" 2>&1
echo "[$(el)] gate rc=$? (1: some rung not converged; 124: cut short, manifest unchanged): $(tail -n 1 "$OUT/gate.log")"
cp "$D/manifest.json" "$OUT/manifest.json"
echo "[$(el)] dataset: $GOOD variants, $(du -sh "$D" | cut -f1)"

[ $# -gt 0 ] || { echo "[$(el)] no runs named: done"; exit 0; }
secs=$((END - $(el) - ${LOAD_MARGIN:-60}))
[ $secs -gt 30 ] || { echo "no time left to train ($secs s)"; exit 4; }
mt=$(printf "'00:00:%02d:%02d'" $((secs / 60)) $((secs % 60)))
pids=() names=()
for run in "$@"; do
  name=${run%% *}
  overrides=${run#"$name"}
  names+=("$name")
  # shellcheck disable=SC2086  # the overrides are words on purpose
  "$PY" train.py experiment="$EXPERIMENT" paths.data_dir="$D" data.patch_size=64 data.batch_size=8 trainer=${TRAINER:-gpu} \
    data.num_workers="${WORKERS:-7}" schedule.map.epochs=100000 "+trainer.max_time=$mt" \
    trainer.enable_progress_bar=false $overrides hydra.run.dir="/tmp/runs/$name" >"$OUT/train_$name.log" 2>&1 &
  pids+=($!)
done
echo "[$(el)] ${#pids[@]} runs, $secs s each"
for i in "${!pids[@]}"; do
  name=${names[$i]}
  wait "${pids[$i]}"
  echo "[$(el)] $name rc=$? $(tail -n 1 "$OUT/train_$name.log")"
  cp "/tmp/runs/$name/checkpoints/last.ckpt" "$OUT/$name.ckpt" 2>/dev/null
done
ls -la "$OUT"
exit
}
