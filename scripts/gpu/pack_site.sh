#!/usr/bin/env bash
# Pack what a bare GPU machine lacks to render and train (Python 3.12, PyTorch and Lightning there):
# mitsuba (only the scalar_rgb and cuda_ad_rgb variants and the plugins the scenes use), drjit, hydra-core,
# omegaconf, antlr4, OpenEXR, kornia; the versions installed here. Writes OUT (default .dev/site312.tar.xz,
# about 28 MB) for scripts/gpu/render_train.sh. Run from the repository root after `make` (.venv exists).
# TRAIN_ONLY=1 leaves mitsuba and drjit out: enough to train and evaluate (scripts/gpu/loso.sh), a few MB,
# which leaves the carry's room to the dataset.
set -euo pipefail
OUT=${1:-.dev/site312.tar.xz}
PY=${PY:-.venv/bin/python}
ver() { "$PY" -m pip show "$1" 2>/dev/null | sed -n 's/^Version: //p'; }
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
mkdir -p "$work/whl" "$work/site312" "$(dirname "$OUT")"
pkgs=()
names=(hydra-core omegaconf OpenEXR kornia kornia_rs)
[ "${TRAIN_ONLY:-0}" = 1 ] || names=(mitsuba drjit "${names[@]}")
for p in "${names[@]}"; do
  v=$(ver "$p"); [ -n "$v" ] || { echo "pack_site: $p is not installed in $PY; run make first" >&2; exit 1; }
  pkgs+=("$p==$v")
done
"$PY" -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
  --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \
  --platform manylinux2014_x86_64 -d "$work/whl" "${pkgs[@]}"
for w in "$work"/whl/*.whl; do unzip -q -o "$w" -d "$work/site312"; done
# antlr4 (hydra's parser runtime) is pure Python and ships as an sdist only: take the installed copy.
cp -r "$("$PY" -c 'import antlr4, os; print(os.path.dirname(antlr4.__file__))')" "$work/site312/"
m="$work/site312/mitsuba"
if [ -d "$m" ]; then
  rm -f "$m"/*mono* "$m"/*spectral* "$m"/llvm_ad_rgb*
  rm -rf "$m"/include "$m"/cmake "$m"/pkgconfig "$m"/mitsuba_stubs "$m"/data/srgb.coeff "$m"/data/sunsky \
    "$work"/site312/drjit/include "$work"/site312/drjit/cmake
  for p in ellipsoids ellipsoidsmesh volpathmis bsplinecurve sdfgrid sunsky timed_sunsky hair measured_polarized \
           measured linearcurve pplastic aov batch; do rm -f "$m/plugins/$p.so"; done
fi
tar -cJf "$OUT.tmp" -C "$work" site312 && mv "$OUT.tmp" "$OUT"
echo "wrote $OUT ($(du -h "$OUT" | cut -f1))"
