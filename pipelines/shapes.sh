#!/bin/bash
# pipelines/shapes.sh BIN_DIR OUT_DIR (make shapes) — rms PSF-corrected distortion and |e| of real COSMOS/AEGIS stamps
# against shapesim-survey acs-f814w, both measured by shapesim-measure --shear-estimate.
#
# Acceptance being measured: on `shapesim-survey acs-f814w --mag-limit 25` at five seeds, the
# isolated galaxies brighter than I = 25 have rms PSF-corrected distortion per component within
# 10% of the real COSMOS/AEGIS stamps' (each through its own PSF), and |e| KS p > 0.05.
#
# Environment (defaults in brackets):
#   SEEDS ["1 2 3 4 5"]  MAG_CUT [25]  ISO_ARCSEC [1.5]  MATCH_ARCSEC [0.3]  PAD [64]  JOBS [2]
#   ZP [25.94]
#   SHAPESIM_DATA: the shipped data the survey reads (models/, surveys/, psfs/); by default the
#   programs look beside themselves (BIN_DIR/../share/data).
#   REDO_REAL=1: recompute OUT_DIR/real.tsv even if present (it is cached otherwise).
#
# Real side (cached in OUT_DIR/real.tsv): every row of extension_26's and AEGIS's catalogues with
# MAG < MAG_CUT; its stamp (NOISE_MEAN removed, padded by PAD px of white noise of its
# NOISE_VARIANCE) written as a FITS image with a 0.03" TAN WCS and MAGZERO = ZP; its own PSF
# image modelled as the survey's PSF record was (decompose --psf-image … --psf-pixel-scale 0.03
# --pixel-scale 0.03); measure --shear-estimate through it; the detection nearest the centre kept.
# Simulated side: survey → measure --shear-estimate --psf (the survey's PSF record) → kept:
# kind galaxy, Kron mag < MAG_CUT, a truth object within MATCH_ARCSEC (no spurious detections),
# no other detection within ISO_ARCSEC, none of the flags blended/crowded/truncated/
# aperture_truncated, and no shear_failed.
# Both sides: measure's default detection, --gain = the exposure (e-/s images).
set -euo pipefail

if [ $# -ne 2 ]; then echo "usage: $0 BIN_DIR OUT_DIR" >&2; exit 2; fi
BIN=$(cd "$1" && pwd)
OUT=$2
HERE=$(cd "$(dirname "$0")" && pwd)
PY=/usr/bin/python3
SEEDS=${SEEDS:-"1 2 3 4 5"}
MAG_CUT=${MAG_CUT:-25}
ISO_ARCSEC=${ISO_ARCSEC:-1.5}
MATCH_ARCSEC=${MATCH_ARCSEC:-0.3}
PAD=${PAD:-64}
JOBS=${JOBS:-2}
ZP=${ZP:-25.94}
SIM_GAIN=2028   # acs-f814w: exposure 2028 s, image in e-/s
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
LOG="$OUT/commands.log"
: >"$LOG"
for p in shapesim-survey shapesim-measure shapesim-decompose; do
  [ -x "$BIN/$p" ] || { echo "$0: $BIN/$p missing" >&2; exit 1; }
done
run() { echo "$*" >>"$LOG"; "$@"; }
T0=$(date +%s)

# ---- real side ---------------------------------------------------------------------------
if [ ! -s "$OUT/real.tsv" ] || [ "${REDO_REAL:-0}" = 1 ]; then
  SD="$OUT/real-stamps"
  rm -rf "$SD"; mkdir -p "$SD"
  run "$PY" "$HERE/shapes.py" stamps "$SD" "$MAG_CUT" "$ZP" "$PAD" >/dev/null
  # One job per stamp: its PSF record, then the stamp measured through it.
  one_real() {
    local name=$1 image=$2 psf=$3 gain=$4
    "$BIN/shapesim-decompose" -q --psf-image "$psf" --psf-pixel-scale 0.03 --pixel-scale 0.03 \
      -o "$SD/$name.psf.jsonl" 2>"$SD/$name.log" || { echo "psf failed: $name" >>"$SD/$name.log"; return 0; }
    "$BIN/shapesim-measure" "$image" --psf "$SD/$name.psf.jsonl" --shear-estimate --gain "$gain" \
      -o "$SD/$name.morph.jsonl" 2>>"$SD/$name.log" || echo "measure failed: $name" >>"$SD/$name.log"
  }
  export -f one_real; export BIN SD
  awk -F'\t' '{print $1"\t"$5"\t"$6"\t"$7}' "$SD/jobs.tsv" | while IFS=$'\t' read -r n i p g; do
    echo "$BIN/shapesim-decompose -q --psf-image '$p' --psf-pixel-scale 0.03 --pixel-scale 0.03 -o $SD/$n.psf.jsonl" >>"$LOG"
    echo "$BIN/shapesim-measure $i --psf $SD/$n.psf.jsonl --shear-estimate --gain $g -o $SD/$n.morph.jsonl" >>"$LOG"
    printf '%s\0%s\0%s\0%s\0' "$n" "$i" "$p" "$g"
  done | xargs -0 -n 4 -P "$JOBS" bash -c 'one_real "$@"' _
  run "$PY" "$HERE/shapes.py" real "$SD/jobs.tsv" "$SD" "$OUT/real.tsv.tmp"
  mv "$OUT/real.tsv.tmp" "$OUT/real.tsv"
  T1=$(date +%s); echo "real side: $((T1 - T0)) s" >&2
else
  echo "real side: cached $OUT/real.tsv" >&2
fi

# ---- simulated side ----------------------------------------------------------------------
T1=$(date +%s)
PSF_REC=""
for s in $SEEDS; do
  d="$OUT/sim/seed$s"
  rm -rf "$d"; mkdir -p "$OUT/sim"
  run "$BIN/shapesim-survey" acs-f814w --mag-limit "$MAG_CUT" --seed "$s" -j "$JOBS" -q -o "$d"
  # The PSF the survey rendered with (its record, from the image header's PSF card).
  PSF_REC=$("$PY" -c "from astropy.io import fits; import sys; h=fits.open(sys.argv[1]); print(next(x.header['PSF'] for x in h if 'PSF' in x.header))" "$d/image.fits")
  run "$BIN/shapesim-measure" "$d/image.fits" --psf "$PSF_REC" --shear-estimate --gain "$SIM_GAIN" \
    -j "$JOBS" -q -o "$d/morph.jsonl"
  run "$PY" "$HERE/shapes.py" sim "$d" "$s" "$MAG_CUT" "$ISO_ARCSEC" "$MATCH_ARCSEC" "$d/sim.tsv"
  rm -f "$d/image.fits"   # 64 MB each; commands.sh reruns it
done
{ head -n 1 "$OUT/sim/seed${SEEDS%% *}/sim.tsv"; for s in $SEEDS; do tail -n +2 "$OUT/sim/seed$s/sim.tsv"; done; } >"$OUT/sim.tsv"
T2=$(date +%s); echo "simulated side: $((T2 - T1)) s" >&2

# ---- the table ---------------------------------------------------------------------------
{
  echo "# shapes.sh $BIN -> $OUT  ($(date -u +%FT%TZ))"
  echo "# survey PSF: $PSF_REC; seeds: $SEEDS; I < $MAG_CUT; isolation ${ISO_ARCSEC}\"; truth match ${MATCH_ARCSEC}\"; pad $PAD px"
  "$PY" "$HERE/shapes.py" report "$OUT/real.tsv" "$OUT/sim.tsv"
  echo
  echo "KS: two-sample, asymptotic p (Stephens' correction). rms = sqrt(mean e^2) about 0."
  echo "wall time: $(( $(date +%s) - T0 )) s"
} | tee "$OUT/report.md"
