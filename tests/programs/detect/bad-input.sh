#!/usr/bin/env bash
# Bad inputs: exit 1, exactly one stderr line "shapesim-detect: …" saying what is wrong,
# nothing on stdout, and no output file (--stamps, --stars, --segmentation) left behind.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-detect
data=$(cd ../../../share/data/hdfn && pwd)
image=$data/hdfn_f814w_v2.fits
weight=$data/hdfn_f814w_v2_weight.fits

# fits_image FILE NX NY FILL [X Y VALUE]: a BITPIX -32 image written byte by byte (80-char
# header cards, 2880-byte blocks, big-endian data), every pixel FILL (4 bytes as printf
# escapes, e.g. '\x7f\xc0\x00\x00' = NaN) but FITS pixel (X, Y), which is VALUE. No WCS.
fits_image() {
  local file=$1 nx=$2 ny=$3 fill=$4 k=-1 n
  [ $# -eq 7 ] && k=$(( ($6 - 1) * nx + $5 - 1 ))
  n=$(( nx * ny ))
  repeat() { [ "$2" -le 0 ] || printf "$1%.0s" $(seq "$2"); }
  {
    printf '%-80s' 'SIMPLE  =                    T' 'BITPIX  =                  -32' \
      'NAXIS   =                    2' "$(printf 'NAXIS1  = %20d' "$nx")" \
      "$(printf 'NAXIS2  = %20d' "$ny")" 'END'
    head -c $(( 2880 - 6 * 80 )) /dev/zero | tr '\0' ' '
    if [ "$k" -ge 0 ]; then
      repeat "$fill" "$k"; printf "$7"; repeat "$fill" $(( n - k - 1 ))
    else
      repeat "$fill" "$n"
    fi
    head -c $(( (2880 - 4 * n % 2880) % 2880 )) /dev/zero
  } >"$file"
}

mkdir "$TMPDIR/out"
cd "$TMPDIR"
# bad WANT_REGEX ARGS...: the run fails as above.
bad() {
  local want=$1 rc=0
  shift
  "$BIN/$prog" "$@" --zero-point 22.08 --stamps out/stamps.fits --stars out/stars.jsonl \
    --segmentation out/seg.fits >out.jsonl 2>err || rc=$?
  expect_error "$rc" 1 "^$prog: $want"
  [ ! -s out.jsonl ] || fail "$*: wrote to stdout"
  [ -z "$(ls -A out)" ] || fail "$*: left files behind: $(ls -A out)"
}

bad "no-such\.fits: .*No such file" no-such.fits
echo "SIMPLE = T, but this is text" >text.fits
bad "text\.fits: .*not a FITS file" text.fits
head -c 10000 "$image" >truncated.fits
bad "truncated\.fits: .*truncated" truncated.fits
bad ".*weight.*: weight map is 100×100 pixels, the image 512×512" \
  "$image" --weight "$weight[1:100,1:100]"
fits_image nan.fits 16 16 '\x7f\xc0\x00\x00'
bad "no usable pixel" nan.fits --pixel-scale 0.04
bad "no usable pixel" "$image[1:16,1:16]" --weight nan.fits --weight-type rms
# Weights 1, one of them -1 at FITS pixel (5, 3): named in the message.
fits_image negative.fits 16 16 '\x3f\x80\x00\x00' 5 3 '\xbf\x80\x00\x00'
bad "negative\.fits: negative weight -1 at pixel (5, 3)" \
  "$image[1:16,1:16]" --weight negative.fits --weight-type weight
bad "negative\.fits: .*negative" "$image[1:16,1:16]" --weight negative.fits --weight-type rms
bad "negative\.fits: .*negative" "$image[1:16,1:16]" --weight negative.fits --weight-type variance
# A constant image has no noise to set a threshold.
fits_image zero.fits 64 64 '\x00\x00\x00\x00'
bad "background rms is zero" zero.fits --pixel-scale 0.04
