#!/usr/bin/env bash
# The montage example: detect and decompose a corner of the HDF, then draw data | model |
# residual of two objects into a PGM of the expected size.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
data=$(cd ../../../share/data/hdfn && pwd)
cd "$TMPDIR"
"$BIN/shapesim-detect" "$data/hdfn_f814w_v2.fits[1:128,1:128]" \
  --weight "$data/hdfn_f814w_v2_weight.fits[1:128,1:128]" --stamps stamps.fits -q >src.jsonl ||
  fail "detect failed"
"$BIN/shapesim-decompose" --models models.fits -q <src.jsonl >shp.jsonl || fail "decompose failed"
ids=$(head -2 shp.jsonl | grep -o '"id":"[^"]*"' | cut -d'"' -f4 | paste -sd,)
[ -n "$ids" ] || fail "no decomposed objects"
"$EXAMPLES/montage" models.fits "$ids" fig.pgm 2 || fail "montage failed"
[ "$(head -c 2 fig.pgm)" = "P5" ] || fail "not a PGM"
# A wrong id is one error line and no output file.
rc=0
"$EXAMPLES/montage" models.fits nosuch bad.pgm 2>err || rc=$?
[ "$rc" -ne 0 ] && [ "$(wc -l <err)" -eq 1 ] && [ ! -e bad.pgm ] || fail "bad id: rc $rc, $(cat err)"
exit 0
