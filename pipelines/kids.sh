#!/bin/bash
# pipelines/kids.sh BIN_DIR OUT_DIR (make kids) — a real ground-based frame through the whole
# chain, as a new user would run it: the KiDS r frame (share/data/kids/README.md: 2600² at
# 0.339″, 0.87″ seeing, in maggies) detected, fitted through its own PSF, replayed where it
# was fitted and simulated (δ: the fits drawn at new places), each measured as the frame is.
#
# What it reports (OUT_DIR/report.md), the acceptance of issue 49 §6:
# - the fits: how many converged, the ten brightest galaxies' χ²_r with their flags;
# - the fits replayed at their own places (sample --replay) at SEEDS, paired galaxy by galaxy
#   with the frame (measure --compare-paired): each model, convolved again, measures as its
#   galaxy did;
# - the δ simulation at SEEDS against the frame (measure --compare): FWHM median, rms e, and the
#   KS p of magnitude, FWHM and e, per seed and pooled.
#
# Environment (defaults in brackets):
#   KIDS_DATA [the shipped share/data/kids]  BAND [r]  JOBS [2]  SEEDS ["1 2 3"]
#   STAR ["1778 262"]: an isolated unsaturated star (r = 17.0), its 33² cutout the PSF image.
#   SATURATION [2.5e-8]: the frame has no SATURATE card; the brightest stars' cores are flat at
#     2.8e-8 to 6e-8 maggies (read off the image), no galaxy's peak comes near.
set -euo pipefail

if [ $# -ne 2 ]; then echo "usage: $0 BIN_DIR OUT_DIR" >&2; exit 2; fi
BIN=$(cd "$1" && pwd)
OUT=$2
HERE=$(cd "$(dirname "$0")" && pwd)
DATA=$(cd "${KIDS_DATA:-$HERE/../share/data/kids}" && pwd)
BAND=${BAND:-r}
JOBS=${JOBS:-2}
SEEDS=${SEEDS:-"1 2 3"}
STAR=${STAR:-"1778 262"}
SATURATION=${SATURATION:-2.5e-8}
SCALE=0.339   # inferred: the header has none (share/data/kids/README.md)
IMAGE=$DATA/$BAND.fits
[ -r "$IMAGE" ] || { echo "$0: $IMAGE: not readable" >&2; exit 1; }
for p in detect decompose smooth sample render measure; do
  [ -x "$BIN/shapesim-$p" ] || { echo "$0: $BIN/shapesim-$p missing" >&2; exit 1; }
done
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
LOG="$OUT/commands.log"
: >"$LOG"
run() { echo "$*" >>"$LOG"; "$@"; }
T0=$(date +%s)
cd "$OUT"
rm -f delta_*.morph.jsonl replay_*.morph.jsonl   # a run with other SEEDS leaves none behind

# The PSF: the star's 33² cutout, modelled at the frame's pixel scale.
read -r sx sy <<<"$STAR"
run "$BIN/shapesim-decompose" -q --psf-image "$IMAGE[1][$((sx - 16)):$((sx + 16)),$((sy - 16)):$((sy + 16))]" \
  --psf-pixel-scale $SCALE --pixel-scale $SCALE -o psf.jsonl
GEOMETRY=(--like "$IMAGE" --pixel-scale $SCALE)
MEASURE=(--pixel-scale $SCALE --zero-point 0 --psf psf.jsonl -j "$JOBS" -q)
run "$BIN/shapesim-detect" -q "$IMAGE" --pixel-scale $SCALE --zero-point 0 --psf psf.jsonl \
  --saturation "$SATURATION" --stamps stamps.fits --stars stars.jsonl --noise-model noise.jsonl \
  -o sources.jsonl
run "$BIN/shapesim-decompose" -q -j "$JOBS" --psf psf.jsonl --stars stars.jsonl \
  --noise-model noise.jsonl -o intrinsic.jsonl <sources.jsonl
run "$BIN/shapesim-measure" "$IMAGE" "${MEASURE[@]}" -o real.morph.jsonl
T1=$(date +%s); echo "fits: $((T1 - T0)) s" >&2

# Replayed where they were fitted, at each seed; paired with the frame.
run "$BIN/shapesim-sample" -q --replay intrinsic.jsonl "${GEOMETRY[@]}" -o replay.objects.jsonl
paired=()
for s in $SEEDS; do
  run "$BIN/shapesim-render" -q --psf psf.jsonl --noise-model noise.jsonl "${GEOMETRY[@]}" \
    --saturation "$SATURATION" --seed "$s" -o replay_$s.fits <replay.objects.jsonl
  run "$BIN/shapesim-measure" replay_$s.fits "${MEASURE[@]}" -o replay_$s.morph.jsonl
  rm -f replay_$s.fits   # 27 MB each
  paired+=("replay$s=replay_$s.morph.jsonl")
done
run "$BIN/shapesim-measure" --compare-paired real=real.morph.jsonl "${paired[@]}" >paired.md

# The δ simulation at each seed, measured alike; compared per seed and pooled.
run "$BIN/shapesim-smooth" -q --delta --stars stars.jsonl "${GEOMETRY[@]}" -o delta.json <intrinsic.jsonl
compared=() pooled=()
read -r first _ <<<"$SEEDS"
for s in $SEEDS; do
  run "$BIN/shapesim-sample" -q delta.json "${GEOMETRY[@]}" --seed "$s" -o delta_$s.objects.jsonl
  run "$BIN/shapesim-render" -q --psf psf.jsonl --noise-model noise.jsonl "${GEOMETRY[@]}" \
    --saturation "$SATURATION" --seed "$s" -o delta_$s.fits <delta_$s.objects.jsonl
  run "$BIN/shapesim-measure" delta_$s.fits "${MEASURE[@]}" -o delta_$s.morph.jsonl
  [ "$s" = "$first" ] || rm -f delta_$s.fits   # the first kept to look at
  compared+=("delta$s=delta_$s.morph.jsonl")
  pooled+=("delta_$s.morph.jsonl")
done
cat "${pooled[@]}" >delta_pooled.morph.jsonl
run "$BIN/shapesim-measure" -q --compare real=real.morph.jsonl "${compared[@]}" \
  pooled=delta_pooled.morph.jsonl -o compare >/dev/null
T2=$(date +%s); echo "replays and δ simulations: $((T2 - T1)) s" >&2

{
  echo "# make kids: the KiDS $BAND frame ($IMAGE) through detect → decompose → replay / δ → measure"
  echo
  echo "PSF: the star at $STAR (33² cutout, $SCALE\"/px); saturation $SATURATION maggies; seeds: $SEEDS."
  echo
  python3 "$HERE/kids.py" intrinsic.jsonl sources.jsonl stars.jsonl
  echo
  echo "## Each fit replayed where it was fitted, paired with its galaxy"
  echo
  cat paired.md
  echo
  echo "## The δ simulation against the frame"
  echo
  cat compare/table.md
  echo
  cat compare/distances.md
  echo
  python3 "$HERE/kids.py" --bins real.morph.jsonl delta_pooled.morph.jsonl
  echo
  echo "wall time: $(($(date +%s) - T0)) s"
} >report.md
cat report.md
