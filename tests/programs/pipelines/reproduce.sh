# pipelines/reproduce.mk on the shipped HDF cut, with a small "large" simulation (0.2 arcmin²):
# every output is made; the Table's numbers are the measured catalogues' own; the log names the
# inputs' SHA-256; a rerun does nothing; a new seed redraws, re-renders and re-measures the
# simulations but leaves detection, the fits and the morphology model alone.
source ../lib.sh
root=$(cd ../../.. && pwd)
out=$TMPDIR/r
run() { (cd "$root" && make --no-print-directory -f pipelines/reproduce.mk OUT="$out" AREA=0.2 \
          BIN="$BIN" EXAMPLES="$EXAMPLES" "$@") >"$TMPDIR/log" 2>&1 || { tail -n 30 "$TMPDIR/log"; fail "make $* failed"; }; }
run

for f in report.md table.md sim.fits delta.fits sim6.fits sources.jsonl shapelets.jsonl psf.jsonl \
         morphology.json delta.json hdf.morph.jsonl sim.morph.jsonl delta.morph.jsonl sim6.morph.jsonl \
         sim.truth.jsonl compare/distances.md compare/counts.png compare/c_a.png \
         figures/hdf_delta_sim.png figures/sim6.png figures/perturbations.png pipeline.log \
         xdf/psf.jsonl xdf/intrinsic.jsonl intrinsic.jsonl merged.json merged6.fits merged6.morph.jsonl \
         merged.shares.txt; do
  [ -s "$out/$f" ] || fail "no $f"
done
ls "$out" | grep -q '\.tmp' && fail "temporary files left: $(ls "$out")"

# Every image the report shows exists.
grep -o '](\([^)]*\.png\))' "$out/report.md" | sed 's/^](//; s/)$//' | while read -r png; do
  [ -s "$out/$png" ] || fail "report.md shows $png, which is missing"
done

# The log names the inputs' checksums, computed here independently.
sum=$(sha256sum "$HDF_IMAGE" | cut -d' ' -f1)
grep -q "$sum .*hdfn_f814w_v2.fits" "$out/pipeline.log" || fail "pipeline.log lacks the image's SHA-256"
grep -q "^==== done in" "$out/pipeline.log" || fail "pipeline.log has no total time"

# The Table is filled from the measured catalogues: recompute <C> and N of two rows here.
python3 - "$out" <<'PY' || fail "table.md does not match the catalogues"
import json, sys
out = sys.argv[1]
rows = {}
for line in open(out + "/table.md"):
    cells = [c.strip() for c in line.strip().strip("|").split("|")]
    if len(cells) == 11: rows[cells[0]] = cells
for name in ("hdf", "sim", "sim6", "delta", "merged6", "paper: HDF-N", "paper: full simulation"):
    assert name in rows, ("no row", name)
assert rows["paper: HDF-N"][2] == "3.110", rows["paper: HDF-N"]
for name in ("hdf", "sim"):
    recs = [json.loads(l) for l in open(f"{out}/{name}.morph.jsonl")]
    gal = [r for r in recs if r.get("kind", "galaxy") == "galaxy" and r.get("mag") is not None]
    n = sum(1 for r in gal if r["mag"] <= 29)
    cs = [r["c"] for r in gal if r["mag"] <= 26 and r.get("c") is not None]
    assert int(rows[name][1]) == n, (name, rows[name][1], n)
    mean = sum(cs) / len(cs)
    assert abs(float(rows[name][2].split("±")[0]) - mean) < 6e-4, (name, rows[name][2], mean)
PY

# The simulations draw the real field's density: as many galaxies as the HDF has brighter
# than I = 29 within Poisson scatter.
real=$(python3 -c "import json;print(sum(1 for l in open('$out/shapelets.jsonl') if json.loads(l).get('mag', 99) <= 29))")
drawn=$(wc -l <"$out/sim.truth.jsonl")
python3 -c "import math,sys; sys.exit(abs($drawn - $real) > 4 * math.sqrt($real))" ||
  fail "simulated $drawn galaxies, the HDF has $real brighter than I = 29"

# The merged model: both fields, intrinsic models, the XDF's star kept out, the report's
# parent-share table filled.
python3 - "$out" <<'PY' || fail "the merged run is wrong"
import json, sys
out = sys.argv[1]
m = json.load(open(out + "/merged.json"))
assert m.get("frame") == "intrinsic", m.get("frame")
images = {f["image"] for f in m["source_fields"]}
assert len(images) == 2 and any("xdf" in i for i in images), images
assert sum(1 for l in open(out + "/xdf/stars.jsonl")) >= 1  # the bright star, by its own PSF
xdf = [json.loads(l) for l in open(out + "/xdf/intrinsic.jsonl")]
assert all(r["frame"] == "intrinsic" for r in xdf)
objects = [json.loads(l) for l in open(out + "/merged6.objects.jsonl")]
assert objects and all(o.get("frame") == "intrinsic" for o in objects if o["kind"] == "galaxy")
PY
grep -q '^| I = 24 | .* | .* from ' "$out/report.md" || fail "report.md lacks the parent shares"
[ "$(cut -d' ' -f1 "$out/merged.shares.txt" | tr '\n' ' ')" = "7 8 9 10 11 12 13 14 15 16 " ] ||
  fail "merged.shares.txt is not ten seeds from 7: $(cat "$out/merged.shares.txt")"
grep -q '^- brighter than I = 24: .*; at most 10% in [0-9]* of 10;$' "$out/report.md" ||
  fail "report.md lacks the shares over ten seeds"
# The δ simulations at five seeds: one row per statistic, each seed a KS p, and the count.
for field in hdf xdf; do
  grep -q "^| $field: statistic | seed 7 | seed 8 | seed 9 | seed 10 | seed 11 | pooled | above 0.05 |$" "$out/seeds.md" ||
    fail "seeds.md lacks the $field table: $(cat "$out/seeds.md")"
  grep -q "^| KS p, gini | [0-9.e-]* | [0-9.e-]* | [0-9.e-]* | [0-9.e-]* | [0-9.e-]* | [0-9.e-]* | [0-6] of 6 |$" "$out/seeds.md" ||
    fail "seeds.md lacks the Gini row"
  grep -q "^| FWHM median, ″ ($field: [0-9.]* ± [0-9.]*) | .* | [0-6] of 6 within 3% |$" "$out/seeds.md" ||
    fail "seeds.md lacks the FWHM median row"
done
grep -q '^| hdf: statistic | seed 7' "$out/report.md" || fail "report.md lacks the seeds table"
# Their skies: the seeds' mean rms and 1st, 5th, 95th and 99th percentiles within 1% of the real
# sky's on both fields (issue 36's sky criterion), every seed within 2.5%.
python3 - "$out/seeds/sky.md" <<'PY' || fail "the seeds' skies are not the real ones: $(cat "$out/seeds/sky.md")"
import sys
tables = open(sys.argv[1]).read().strip().split("\n\n")
assert len(tables) == 2, len(tables)
for table in tables:
    rows = [[c.strip() for c in l.split("|")[1:-1]] for l in table.splitlines()[3:]]
    assert [r[0] for r in rows] == ["seed7", "seed8", "seed9", "seed10", "seed11", "mean of the seeds"], rows
    for r in rows:
        for k, name in zip(range(12, 17), ("rms", "P1", "P5", "P95", "P99")):
            limit = 0.01 if r[0].startswith("mean") else 0.025
            assert abs(float(r[k]) - 1) <= limit, f"{r[0]}: {name} ratio {r[k]}"
PY
grep -q '^| mean of the seeds |' "$out/report.md" || fail "report.md lacks the seeds' skies"
# The fits where they were: each field's real galaxies paired with five replays of its fits.
for field in hdf xdf; do
  grep -q "^| I | galaxies ($field) | found in 5 replays (within 0.1\") | FWHM ratio, geometric mean |" \
    "$out/replays/$field.md" || fail "replays/$field.md lacks the paired table: $(cat "$out/replays/$field.md")"
  grep -q "^| I | galaxies ($field) | found in 5 replays" "$out/report.md" || fail "report.md lacks $field's replays"
done
# The HDF's bright half comes back in most replays, at its size within 10% (geometric mean).
python3 - "$out/replays/hdf.md" <<'PY' || fail "the HDF's replays are not its galaxies: $(cat "$out/replays/hdf.md")"
import sys
rows = [l.split("|")[1:-1] for l in open(sys.argv[1]) if l.startswith("| ") and "–" in l]
assert len(rows) == 5, rows
for r in rows[:2]:
    n, d = r[2].split()[0].split("/")
    assert int(n) / int(d) >= 0.7 and abs(float(r[3].split("±")[0]) - 1) < 0.1, r
PY
# The light the renderer clipped, per simulation; mixtures of non-negative parents lose < 1%.
for sim in sim sim6; do
  grep -q "^| $sim | 0 of [0-9]* (0.0%); at most " "$out/report.md" ||
    fail "report.md: $sim's galaxies lose 1% of their light to the clip: $(grep "^| $sim |" "$out/report.md")"
done
# The merged model's round parents lend their mixtures an ellipticity projected to 10⁻³ of the
# norm (3% of the light, docs/algorithms.md#ellipticity): its rings, clipped, cost at most 3%,
# and more than 1% to at most 1% of the galaxies.
python3 - "$out/report.md" <<'PY' || fail "report.md: merged6's clip: $(grep "^| merged6 | [0-9]* of" "$out/report.md")"
import re, sys
for line in open(sys.argv[1]):
    m = re.match(r"\| merged6 \| (\d+) of (\d+) \(([\d.]+)%\); at most ([\d.e-]+) of", line)
    if m:
        assert float(m.group(3)) <= 1.0 and float(m.group(4)) <= 0.03, line
        break
else:
    sys.exit("no merged6 clip row")
PY
grep -q '^| delta (the real fits) | [0-9]* of [0-9]* ' "$out/report.md" || fail "report.md lacks the δ's clipped light"
grep -q 'I-band count law (`--counts law`: [0-9.]* per arcmin² over I = 16–29, COSMOS2020 i-band counts' \
  "$out/report.md" || fail "report.md lacks the count law: $(grep -a 'galaxy counts' "$out/pipeline.log")"

# Nothing changed: nothing runs.
run
grep -q 'bin/shapesim-[a-z]* ' "$TMPDIR/log" && fail "a rerun ran programs: $(grep shapesim- "$TMPDIR/log" | head -3)"

# A new seed: sample, render, measure again, and nothing upstream.
before=$(stat -c %y "$out/shapelets.jsonl" "$out/morphology.json" "$out/psf.jsonl" "$out/hdf.morph.jsonl" | md5sum)
sim_before=$(sha256sum <"$out/sim.fits")
sleep 1
run SEED=8
for p in shapesim-sample shapesim-render shapesim-measure; do
  grep -q "^[^ ]*bin/$p " "$TMPDIR/log" || fail "SEED=8 did not run $p"
done
for p in shapesim-decompose; do
  grep -q "^[^ ]*bin/$p " "$TMPDIR/log" && fail "SEED=8 reran $p"
done
grep -q "^[^ ]*bin/shapesim-smooth " "$TMPDIR/log" && fail "SEED=8 reran shapesim-smooth"
grep -q "shapesim-smooth -v" "$TMPDIR/log" && fail "SEED=8 reran the merged smooth"
# detect runs again only on the new simulations (their skies), never on the real image.
grep -q "^[^ ]*bin/shapesim-detect [^ ]*hdfn_f814w_v2.fits" "$TMPDIR/log" && fail "SEED=8 reran detect on the HDF"
grep -q "^[^ ]*bin/shapesim-detect [^ ]*/sim.fits " "$TMPDIR/log" || fail "SEED=8 did not measure the new sky"
grep -q "^| delta " "$out/sky.md" || fail "sky.md lost its rows"
[ "$(stat -c %y "$out/shapelets.jsonl" "$out/morphology.json" "$out/psf.jsonl" "$out/hdf.morph.jsonl" | md5sum)" = "$before" ] ||
  fail "SEED=8 touched the real image's products"
[ "$(sha256sum <"$out/sim.fits")" != "$sim_before" ] || fail "SEED=8 gave the same simulation"
grep -q "^| sim " "$out/table.md" || fail "table.md lost its rows"

# And back: the seed-7 image comes back bit for bit.
run SEED=7
[ "$(sha256sum <"$out/sim.fits")" = "$sim_before" ] || fail "SEED=7 again did not give the same bytes"
