#!/usr/bin/env bash
# The external test set's Cornell boxes with their albedo passes, for scorers that take one (unet_fast_albedo):
# OUT/<scene>/ links the renders of ../shared/external/renders/<scene>/ and adds albedo.exr, rendered from the
# scene file the README names (python -m data_gen.albedo_pass --scene-file, 64 spp, 128x128). The other three
# external scenes ship no scene file, so they have no albedo pass. Then, e.g.:
#   nriqa-evaluate OUT --out reports/external_albedo --crossval RUN --pattern "{scene}/{algorithm} - {spp} - {seed}" \
#       --reference "{scene}/reference.exr" --baselines none --no-figures
#
#   bash scripts/external_albedo.sh [OUT=data/external_albedo] [EXTERNAL=../shared/external]
set -euo pipefail
OUT=${1:-data/external_albedo}
EXTERNAL=${2:-../shared/external}
PY=${PY:-python}
for pair in cbox_official:cbox-rgb cbox_indirect:cbox-indirect cbox_glass:cbox-glass; do
  scene=${pair%%:*}
  renders=$(cd "$EXTERNAL/renders/$scene" && pwd)
  mkdir -p "$OUT/$scene"
  for f in "$renders"/*.exr; do ln -sf "$f" "$OUT/$scene/$(basename "$f")"; done
  [ -f "$OUT/$scene/albedo.exr" ] || "$PY" -m data_gen.albedo_pass --scene-file "$EXTERNAL/scenes/cbox/${pair#*:}.xml" \
    --res 128 --out "$OUT/$scene/albedo.exr"
done
