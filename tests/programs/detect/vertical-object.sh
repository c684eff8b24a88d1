#!/usr/bin/env bash
# An object elongated exactly along y (a bad column, a bleed trail) is measured like any other:
# exit 0, THETA_IMAGE in (−90°, 90°]. So are the HDF with each of SExtractor's own filters
# (/usr/share/source-extractor/*.conv, when installed).
# (libsep returns θ as a float, and float(π/2) > π/2 in double, which its own aperture
# functions reject: detect.cpp clamps it.)
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-detect
data=$(cd ../../../share/data/hdfn && pwd)

# check_theta FILE: every record's theta in (−90, 90].
check_theta() {
  local bad
  bad=$(grep -o '"theta":[-0-9.e+]*' "$1" | cut -d: -f2 |
        awk '!($1 > -90 && $1 <= 90) { print; exit }')
  [ -z "$bad" ] || fail "$1: theta $bad outside (-90, 90]"
}

cd "$TMPDIR"
# 32×32 BITPIX -32 zeros with a 1×11 bar of 100 at x = 16, y = 10…20, weight 1 everywhere.
zeros() { [ "$1" -le 0 ] || printf '\0\0\0\0%.0s' $(seq "$1"); }
{
  printf '%-80s' 'SIMPLE  =                    T' 'BITPIX  =                  -32' \
    'NAXIS   =                    2' 'NAXIS1  =                   32' \
    'NAXIS2  =                   32' 'END'
  head -c $(( 2880 - 6 * 80 )) /dev/zero | tr '\0' ' '
  for y in $(seq 32); do
    if [ "$y" -ge 10 ] && [ "$y" -le 20 ]; then zeros 15; printf '\x42\xc8\x00\x00'; zeros 16
    else zeros 32; fi
  done
  head -c $(( 2880 - 4096 % 2880 )) /dev/zero
} >bar.fits
{ head -c 2880 bar.fits; printf '\x3f\x80\x00\x00%.0s' $(seq 1024); head -c $(( 2880 - 4096 % 2880 )) /dev/zero; } >ones.fits

rc=0
"$BIN/$prog" bar.fits --pixel-scale 0.04 --weight ones.fits -q >bar.jsonl 2>err || rc=$?
[ "$rc" -eq 0 ] || { fail "vertical bar: exit $rc: $(cat err)"; }
[ "$(wc -l <bar.jsonl)" -eq 1 ] || fail "vertical bar: expected one object, got $(wc -l <bar.jsonl)"
check_theta bar.jsonl

shopt -s nullglob
for conv in /usr/share/source-extractor/*.conv; do
  rc=0
  "$BIN/$prog" "$data/hdfn_f814w_v2.fits" --weight "$data/hdfn_f814w_v2_weight.fits" -q \
    --filter "$conv" >out.jsonl 2>err || rc=$?
  [ "$rc" -eq 0 ] || { fail "--filter $conv: exit $rc: $(cat err)"; }
  [ -s out.jsonl ] || fail "--filter $conv: no objects"
  check_theta out.jsonl
done
