#!/usr/bin/env bash
# A 16384² image (2.7·10⁸ pixels, 1 GiB of float pixels) detected and measured in bounded memory
# (issue 39): by default an image of more than 4096² pixels is read and detected in tiles of
# 2048², each measured and written before the next, so shapesim-measure and shapesim-detect
# must peak under 2 GiB (the whole image at once needs about 10 GiB). Every tile is reported as
# it is done, and the catalogue covers the whole field.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
models=$(cd ../../../share/data/models && pwd)
cd "$TMPDIR"
field=(--pixels 16384 --pixel-scale 0.03 --ra 150 --dec 2)
"$BIN/shapesim-sample" -q "$models/merged.json" "${field[@]}" --zero-point 25.94 --mag-limit 28 \
  --seed 1 -o objects.jsonl || fail "sample failed"
"$BIN/shapesim-render" -q objects.jsonl --psf-analytic gaussian:0.1 "${field[@]}" \
  --noise-rms 0.003 -j 2 -o image.fits || fail "render failed"
rm objects.jsonl
peak_of() { sed -n 's/.*(peak memory \([0-9]*\) MiB).*/\1/p' "$1"; }

"$BIN/shapesim-measure" image.fits --zero-point 25.94 --mag-limit 27 -j 2 >morph.jsonl 2>err ||
  fail "measure failed: $(tail -n 3 err)"
grep -q "the 16384×16384 image in 64 tiles of 2048² pixels" err || fail "not tiled: $(head -n 2 err)"
[ "$(grep -c '^shapesim-measure: tile [0-9]* of 64 ' err)" -eq 64 ] || fail "not every tile reported"
summary=$(tail -n 1 err)
peak=$(peak_of err)
echo "measure: $summary"
[ -n "$peak" ] && [ "$peak" -le 2048 ] || fail "measure peaked at ${peak:-?} MiB (limit 2048)"

"$BIN/shapesim-detect" image.fits --zero-point 25.94 >sources.jsonl 2>err || fail "detect failed"
peak=$(peak_of err)
echo "detect: $(tail -n 1 err)"
[ -n "$peak" ] && [ "$peak" -le 2048 ] || fail "detect peaked at ${peak:-?} MiB (limit 2048)"

python3 - <<'PY' || fail "the catalogues do not cover the field"
import json
morph = [json.loads(l) for l in open("morph.jsonl")]
sources = [json.loads(l) for l in open("sources.jsonl")]
ids = [r["id"] for r in sources]
assert len(set(ids)) == len(ids), "ids repeat"
# Objects in every tile, positions in the image's pixels.
cells = {(int((r["x"] - 0.5) // 2048), int((r["y"] - 0.5) // 2048)) for r in sources}
assert cells == {(i, j) for i in range(8) for j in range(8)}, sorted(cells)
assert all(0.5 <= r["x"] < 16384.5 and 0.5 <= r["y"] < 16384.5 for r in sources)
assert len(morph) > 3000 and len(sources) > 8000, (len(morph), len(sources))
print(f"{len(sources)} galaxies detected, {len(morph)} measured to I = 27, in all 64 tiles")
PY
