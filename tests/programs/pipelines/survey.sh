# pipelines/survey.mk: a 2×2 survey under make -j 2 equals the whole field rendered at once,
# pixel for pixel; the merged truth holds every object once; the index's checksums hold; a
# rerun does nothing; a tile killed mid-run and rerun gives the same bytes; a new seed redraws
# every tile and the old seed brings the old bytes back; peak memory is in every tile's log.
source ../lib.sh
root=$(cd ../../.. && pwd)
cd "$TMPDIR"
hdf_morphology
"$BIN/shapesim-decompose" --psf-image "$HDF_DATA/wfpc2_f814w_tinytim_psf.fits" --like "$HDF_IMAGE" \
  --psf-box 0.0996 0.05 -q >psf.jsonl || fail "PSF fit failed"
field=(--size 0.4 0.3 --pixel-scale 0.03985)
noise=(--noise-like sources.jsonl --gain 865200)
vars=(MODEL=morph.json PSF=psf.jsonl "NOISE=${noise[*]}" "FIELD=${field[*]}" "TILE=320 240" SEED=5 BIN="$BIN")
survey() { make --no-print-directory -f "$root/pipelines/survey.mk" "${vars[@]}" "$@" >log 2>&1 ||
             { tail -n 20 log; fail "survey.mk $* failed"; }; }
survey -j 2 OUT=s
[ "$(wc -l <s/tiles.txt)" -eq 4 ] || fail "expected 4 tiles: $(cat s/tiles.txt)"
grep -q 'peak memory [0-9.]* MiB' s/tiles/tile-000-000.log || fail "no peak memory in the tile log"

# The whole field at once, and its truth.
"$BIN/shapesim-sample" morph.json "${field[@]}" --seed 5 -q >objects.jsonl
"$BIN/shapesim-render" --psf psf.jsonl --galaxy-psf psf.jsonl "${field[@]}" "${noise[@]}" --seed 5 -q \
  -o whole.fits --truth whole.truth.jsonl <objects.jsonl || fail "whole-field render failed"
python3 - <<PY || fail "the tiles are not the whole field"
import json, sys
sys.path.insert(0, "$root/tests/programs/tools")
import fitsdata
_, nx, ny, whole = fitsdata.read("whole.fits")
seen = 0
for line in open("s/tiles.txt"):
    ix, iy, x0, y0, x1, y1 = map(int, line.split())
    cards, tx, ty, rows = fitsdata.read(f"s/tiles/tile-{ix:03d}-{iy:03d}.fits")
    assert (tx, ty) == (x1 - x0 + 1, y1 - y0 + 1), (tx, ty)
    for j in range(ty):
        assert rows[j] == whole[y0 - 1 + j][x0 - 1:x1], ("pixels differ", ix, iy, j)
    seen += tx * ty
assert seen == nx * ny, (seen, nx, ny)
tiles = sorted(open("s/truth.jsonl"))
field = sorted(open("whole.truth.jsonl"))
assert tiles == field, (len(tiles), len(field))
ids = [json.loads(l)["id"] for l in tiles]
assert len(ids) == len(set(ids))
PY

# The index: one line per tile, checksums of the files as they are.
[ "$(wc -l <s/index.jsonl)" -eq 4 ] || fail "index.jsonl: $(cat s/index.jsonl)"
while read -r line; do
  name=$(sed 's/.*"tile":"\([^"]*\)".*/\1/' <<<"$line")
  want=$(sed 's/.*"sha256":"\([0-9a-f]*\)".*/\1/' <<<"$line")
  [ "$(sha256sum <"s/tiles/$name.fits" | cut -d' ' -f1)" = "$want" ] || fail "index checksum of $name"
done <s/index.jsonl
sha256sum s/tiles/*.fits s/truth.jsonl s/index.jsonl >first.sha

# A rerun does nothing.
survey -j 2 OUT=s
grep -q 'bin/shapesim-render ' log && fail "a rerun rendered again"

# A tile killed mid-run leaves no partial tile; run again, it is the same bytes.
rm s/tiles/tile-001-000.fits
setsid make --no-print-directory -f "$root/pipelines/survey.mk" "${vars[@]}" OUT=s task-1 >/dev/null 2>&1 &
pid=$!
sleep 0.1
kill -KILL -- "-$pid" 2>/dev/null || true
wait "$pid" 2>/dev/null || true
if [ -e s/tiles/tile-001-000.fits ]; then
  grep -q "$(sha256sum <s/tiles/tile-001-000.fits | cut -d' ' -f1)" first.sha || fail "a killed tile left a partial image"
fi
survey -j 2 OUT=s
sha256sum -c --quiet first.sha || fail "the rerun tile differs"

# A new seed redraws every tile; the old seed brings the old bytes back.
survey -j 2 OUT=s SEED=6
[ "$(grep -c 'bin/shapesim-render ' log)" -eq 4 ] || fail "SEED=6 did not re-render 4 tiles"
sha256sum -c --quiet first.sha >/dev/null 2>&1 && fail "SEED=6 gave the same tiles"
survey -j 2 OUT=s SEED=5
sha256sum -c --quiet first.sha || fail "SEED=5 again differs"

# A second survey elsewhere, one job at a time: the same bytes (paths in no output).
survey -j 1 OUT=t
diff <(cut -d' ' -f1 first.sha) <(cd t && sha256sum tiles/*.fits truth.jsonl index.jsonl | cut -d' ' -f1) ||
  fail "OUT=t differs from OUT=s"
