#!/usr/bin/env bash
# --like on an image whose header has no usable WCS (none at all, as the shipped XDF cutout,
# or a blank CTYPE with CDELT 1): smooth, sample and render take --pixel-scale (and --ra/--dec)
# as detect does, and give the field the header's size; without it, one line naming the file
# (issue 15).
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
xdf=$(cd ../../../share/data/xdf && pwd)/f814w_sci.fits
tools=$(cd ../tools && pwd)
cd "$TMPDIR"
# A 300 × 200 image with a blank CTYPE1/2 and CDELT 1 (as some pipelines write).
python3 - <<'PY'
import struct
cards = ["SIMPLE  =                    T", "BITPIX  =                  -32", "NAXIS   =                    2",
         "NAXIS1  =                  300", "NAXIS2  =                  200", "CTYPE1  = '        '",
         "CTYPE2  = '        '", "CDELT1  =                  1.0", "CDELT2  =                  1.0", "END"]
header = "".join(c.ljust(80) for c in cards)
header += " " * (-len(header) % 2880)
data = struct.pack(">60000f", *([0.0] * 60000))
data += b"\0" * (-len(data) % 2880)
open("blank.fits", "wb").write(header.encode() + data)
PY
"$BIN/shapesim-detect" "$xdf" --pixel-scale 0.06 --zero-point 25.959 --stamps stamps.fits -q >sources.jsonl ||
  fail "detect on the XDF cutout failed"
"$BIN/shapesim-decompose" -q -j 2 <sources.jsonl >shapelets.jsonl || fail "decompose failed"
"$BIN/shapesim-smooth" -q --like "$xdf" --pixel-scale 0.06 <shapelets.jsonl >morph.json ||
  fail "smooth --like a headerless image with --pixel-scale failed"
grep -q '"area_arcmin2":0.25' morph.json || fail "the field's area is not (500 × 0.06″)² = 0.25 arcmin²"
"$BIN/shapesim-sample" -q morph.json --like "$xdf" --pixel-scale 0.06 --seed 2 >objects.jsonl ||
  fail "sample --like a headerless image with --pixel-scale failed"
python3 -c 'import json
rows = [json.loads(l) for l in open("objects.jsonl")]
assert rows and all(0.5 <= r["x"] <= 500.5 and 0.5 <= r["y"] <= 500.5 for r in rows)
assert all(abs(r["pixel_scale"] - 0.06) < 1e-12 for r in rows)' || fail "the sampled field is not the cutout's"
"$BIN/shapesim-render" -q --like blank.fits --pixel-scale 0.04 --ra 150 --dec 2 --noise-rms 1 --seed 1 \
  -o blank_sim.fits </dev/null || fail "render --like an image with a blank CTYPE failed"
python3 "$tools/fitsdata.py" blank_sim.fits sum |
  grep -q '^300 200 ' || fail "the rendered field is not 300 × 200"
for prog in shapesim-smooth shapesim-sample; do
  rc=0; "$BIN/$prog" --like "$xdf" <shapelets.jsonl >out 2>err || rc=$?
  [ $prog = shapesim-sample ] && { rc=0; "$BIN/$prog" morph.json --like "$xdf" >out 2>err || rc=$?; }
  expect_error "$rc" 1 'f814w_sci.fits: no WCS in the header: give --pixel-scale'
  [ ! -s out ] || fail "$prog wrote output without a field"
done
exit 0
