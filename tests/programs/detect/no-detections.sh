#!/usr/bin/env bash
# Nothing above the threshold (--detect-thresh 1000 on the HDF) is not an error: exit 0, empty
# stdout and --stars, a valid --stamps file with no stamp HDU, and an all-zero segmentation.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-detect
data=$(cd ../../../share/data/hdfn && pwd)

cd "$TMPDIR"
rc=0
"$BIN/$prog" "$data/hdfn_f814w_v2.fits" --weight "$data/hdfn_f814w_v2_weight.fits" \
  --zero-point 22.08 --detect-thresh 1000 --stamps stamps.fits --stars stars.jsonl \
  --segmentation seg.fits >out.jsonl 2>err || rc=$?
[ "$rc" -eq 0 ] || fail "exit $rc: $(cat err)"
[ ! -s out.jsonl ] || fail "stdout not empty: $(head -c 300 out.jsonl)"
grep -q "^$prog: 0 objects above 1000" err || fail "stderr does not say 0 objects: $(cat err)"
[ -f stars.jsonl ] && [ ! -s stars.jsonl ] || fail "--stars is missing or not empty"
for f in stamps.fits seg.fits; do
  [ -f "$f" ] || fail "$f not written"
  [ "$(head -c 30 "$f")" = "SIMPLE  =                    T" ] || fail "$f: not a FITS file"
  [ $(( $(wc -c <"$f") % 2880 )) -eq 0 ] || fail "$f: size is not a multiple of 2880 bytes"
done
! LC_ALL=C grep -a -q "EXTNAME =" stamps.fits || fail "stamps.fits has stamp HDUs"
[ "$(LC_ALL=C grep -a -o "EXTNAME = '[^']*'" seg.fits)" = "EXTNAME = 'SEGMENTATION'" ] ||
  fail "seg.fits: no SEGMENTATION HDU"
# BITPIX 32 labels, 512×512: the data are the last 512·512·4 bytes before the block padding;
# every one is zero.
header=$(( $(wc -c <seg.fits) - (512 * 512 * 4 + 2879) / 2880 * 2880 ))
[ "$(tail -c +$(( header + 1 )) seg.fits | tr -d '\0' | wc -c)" -eq 0 ] ||
  fail "seg.fits: non-zero labels"
