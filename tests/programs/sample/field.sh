#!/usr/bin/env bash
# shapesim-sample on the HDF morphology (detect → decompose → smooth → sample): --like gives the
# HDF's geometry and a Poisson count about 700 per arcmin²; the same seed gives the same bytes,
# another seed other objects; a 3×3 tiling reproduces the whole field record for record; the
# δ model returns real models; stars follow --star-count; bad input fails with one line.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-sample
data=$(cd ../../../share/data/hdfn && pwd)
hdf=$data/hdfn_f814w_v2.fits

cd "$TMPDIR"
hdf_morphology
"$BIN/shapesim-smooth" -q --delta <shapelets.jsonl >delta.json || fail "shapesim-smooth --delta failed"

# A 4× larger field than the cut (its pixel scale and a 1024² square) for the statistics.
"$BIN/$prog" morph.json --size 0.6797 --pixel-scale 0.03985 --seed 7 --star-count 5 --density 700 \
  >a.jsonl 2>err || fail "exit $?: $(cat err)"
"$BIN/$prog" morph.json --size 0.6797 --pixel-scale 0.03985 --seed 7 --star-count 5 --density 700 -q >b.jsonl ||
  fail "second run failed"
cmp -s a.jsonl b.jsonl || fail "the same seed gave different output"
"$BIN/$prog" morph.json --size 0.6797 --pixel-scale 0.03985 --seed 8 --density 700 -q >c.jsonl || fail "seed 8 failed"
! cmp -s a.jsonl c.jsonl || fail "seeds 7 and 8 gave the same output"
python3 - <<'PY' || fail "the records break the checks"
import json, math
rows = [json.loads(l) for l in open("a.jsonl")]
gal = [r for r in rows if r["kind"] == "galaxy"]
stars = [r for r in rows if r["kind"] == "star"]
area = (1024 * 0.03985 / 60) ** 2
assert abs(len(gal) - 700 * area) < 5 * math.sqrt(700 * area), (len(gal), 700 * area)
assert len(stars) == 5, len(stars)
parents = {p["id"] for p in json.load(open("morph.json"))["points"]}
for r in gal:
    assert r["schema"] == "shapesim.object/1" and r["mag"] <= 29, r["id"]
    assert r["parent"] in parents, r["parent"]
    assert 0.5 <= r["x"] <= 1024.5 and 0.5 <= r["y"] <= 1024.5, r["id"]
    n = r["n_max"]
    assert len(r["coeffs"]) == ((n + 2) // 2) * ((n + 3) // 2), r["id"]
    # flux = 2√π β_pix Σ_{n even} a_{n,0}
    beta_pix = r["beta"] / r["pixel_scale"]
    s, k = 0.0, 0
    for nn in range(n + 1):
        for m in range(nn % 2, nn + 1, 2):
            if m == 0: s += r["coeffs"][k][0]
            k += 1
    f = 2 * math.sqrt(math.pi) * beta_pix * s
    assert abs(f - r["flux"]) < 1e-9 * r["flux"], (r["id"], f, r["flux"])
    assert abs(r["flux"] - 10 ** (-0.4 * (r["mag"] - 22.08))) < 1e-12 * r["flux"]
PY

# Tiles: 3×3 over the 1024² field (tiles of 342, 342 and 340 pixels).
: >tiles.jsonl
for y in "1 342" "343 684" "685 1024"; do
  for x in "1 342" "343 684" "685 1024"; do
    set -- $x $y
    "$BIN/$prog" morph.json --size 0.6797 --pixel-scale 0.03985 --seed 7 --star-count 5 -q \
      --density 700 --tile "$1" "$3" "$2" "$4" >>tiles.jsonl || fail "tile $x $y failed"
  done
done
sort -u tiles.jsonl >tiles_union
sort a.jsonl >whole_sorted
cmp -s tiles_union whole_sorted ||
  fail "the union of the tiles differs from the whole field: $(diff tiles_union whole_sorted | head -3 | cut -c1-200)"
[ "$(wc -l <tiles.jsonl)" -gt "$(wc -l <a.jsonl)" ] || fail "no object straddles a tile edge"

# --like: the cut's geometry.
"$BIN/$prog" morph.json --like "$hdf" --seed 1 -q >like.jsonl || fail "--like failed"
python3 -c 'import json
rows = [json.loads(l) for l in open("like.jsonl")]
assert rows and all(0.5 <= r["x"] <= 512.5 and 0.5 <= r["y"] <= 512.5 for r in rows)
assert all(abs(r["ra"] - 189.2) < 0.05 and abs(r["dec"] - 62.2) < 0.05 for r in rows), rows[0]' ||
  fail "--like: positions or sky coordinates off the HDF cut"

# δ model: every galaxy's coefficient moduli are its parent's times a_00 (rotation and flip
# change phases only), and its β is the parent's.
"$BIN/$prog" delta.json --like "$hdf" --seed 1 -q --count 200 >delta.jsonl || fail "δ sample failed"
python3 - <<'PY' || fail "δ-sampled galaxies are not their parents"
import json, math
pts = {p["id"]: p for p in json.load(open("delta.json"))["points"]}
for r in map(json.loads, open("delta.jsonl")):
    if r["kind"] != "galaxy": continue
    p = pts[r["parent"]]
    assert r["beta"] == p["beta"] and abs(r["mag"] - p["mag"]) < 1e-12, r["id"]
    a00 = r["coeffs"][0][0]
    for (re, im), (pr, pi) in zip(r["coeffs"], p["shape"]):
        assert abs(math.hypot(re, im) - a00 * math.hypot(pr, pi)) <= 1e-12 * a00, r["id"]
PY

# The real field's density: smooth --like records the HDF's area and every galaxy's magnitude;
# sample then draws as many galaxies per arcmin² as the HDF has brighter than --mag-limit
# (--counts fit: the power law fitted to them, or the parents' magnitudes).
"$BIN/shapesim-smooth" -q --like "$hdf" <shapelets.jsonl >dense.json || fail "smooth --like failed"
"$BIN/$prog" dense.json --size 0.6797 --pixel-scale 0.03985 --seed 7 --counts fit >d.jsonl 2>err || fail "exit $?: $(cat err)"
python3 - <<'PY' || fail "the drawn density is not the HDF's"
import json, math
f = json.load(open("dense.json"))["source_field"]
real = sum(1 for l in open("shapelets.jsonl") if json.loads(l).get("mag", 99) <= 29)
assert abs(f["area_arcmin2"] - (512 * 0.03985001130010063 / 60) ** 2) < 1e-6, f["area_arcmin2"]
assert sum(1 for m in f["mags"] if m <= 29) == real, real
density = real / f["area_arcmin2"]
n = sum(1 for l in open("d.jsonl"))
expect = density * (1024 * 0.03985 / 60) ** 2
assert abs(n - expect) < 5 * math.sqrt(expect), (n, expect)
PY
grep -q "per arcmin^2" err || fail "the density is not reported: $(cat err)"

# The tile grid: whole tiles from (1, 1), the last column and row take what is left.
"$BIN/$prog" --size 0.4 0.3 --pixel-scale 0.03985 --tile-grid 320 240 >grid.txt || fail "--tile-grid failed"
[ "$(cat grid.txt | tr '\n' ';')" = "0 0 1 1 320 240;1 0 321 1 602 240;0 1 1 241 320 452;1 1 321 241 602 452;" ] ||
  fail "--tile-grid: $(cat grid.txt)"
rc=0; "$BIN/$prog" --area 1 --tile-grid 0 >out 2>err || rc=$?
expect_error "$rc" 2 'tile-grid'
rc=0; "$BIN/$prog" --area 1 >out 2>err || rc=$?
expect_error "$rc" 2 'MODEL'

# Bad input.
# Shapes conditional on magnitude (perturbed, --mix 1, the parents' magnitudes): a 6 arcmin² field's bright end no longer
# copies one parent alone as the paper's draw (--neighbours 0) does (the summary's largest share
# at I < 22 falls), tiles still reproduce the field, and a shape taken from another parent than
# the magnitude names both.
"$BIN/$prog" morph.json --area 6 --pixel-scale 0.03985 --seed 7 --neighbours 0 >paper6.jsonl 2>paper6.err ||
  fail "6 arcmin² failed"
"$BIN/$prog" morph.json --area 6 --pixel-scale 0.03985 --seed 7 --neighbours 16 --mix 1 \
  --counts parents >cond6.jsonl 2>cond6.err || fail "--neighbours 16 failed"
python3 - <<'PY' || fail "--neighbours does not spread the bright end: $(cat paper6.err cond6.err)"
import json, re
def share(path):  # "I < 22: 43/63 from 117"
    m = re.search(r"I < 22: (\d+)/(\d+)", open(path).read())
    return int(m.group(1)) / int(m.group(2))
assert share("cond6.err") < share("paper6.err"), (share("cond6.err"), share("paper6.err"))
rows = [json.loads(l) for l in open("cond6.jsonl")]
moved = [r for r in rows if "mag_parent" in r]
assert moved and all(r["mag_parent"] != r["parent"] for r in moved)
assert all(r["perturbation"] <= 0.5 for r in rows if r["kind"] == "galaxy")
PY
rc=0; "$BIN/$prog" morph.json --area 1 --neighbours -1 >out 2>err || rc=$?
expect_error "$rc" 2 'neighbours'

# With the real field recorded (smooth --like), conditional draws can take their magnitudes from
# a power law fitted to its counts (--counts fit): the one I = 20.7 galaxy of a
# 0.12 arcmin² cut no longer puts 1/64 of a 6 arcmin² field's draws at I ≈ 21 (73 brighter
# than 22 where the fitted slope, 0.27 dex/mag, expects 28), and every draw's shape
# parent is its one parent. --counts parents keeps the parents' magnitudes.
"$BIN/$prog" dense.json --area 6 --pixel-scale 0.03985 --seed 7 --neighbours 16 --counts fit \
  >fit6.jsonl 2>fit6.err || fail "--counts fit failed: $(cat fit6.err)"
"$BIN/$prog" dense.json --area 6 --pixel-scale 0.03985 --seed 7 --neighbours 16 --counts parents \
  >parents6.jsonl 2>parents6.err || fail "--counts parents failed: $(cat parents6.err)"
python3 - <<'PY' || fail "fitted counts: $(cat fit6.err parents6.err)"
import json, re
line = open("fit6.err").read()
m = re.search(r"galaxy counts: d log10 N / dm = ([0-9.e+-]+), ([0-9.e+-]+) per arcmin\^2 over ([0-9.]+) - 29, fitted to (\d+) galaxies of 1 field", line)
assert m, line
slope, density = float(m.group(1)), float(m.group(2))
assert 0.1 < slope < 0.6, slope
assert abs(float(m.group(3)) - (20.7447 - 1.0)) < 1e-3, m.group(3)  # half the 2-mag shift above 117
def rows(path):
    return [json.loads(l) for l in open(path) if '"galaxy"' in l]
fit, par = rows("fit6.jsonl"), rows("parents6.jsonl")
assert "mag_parent" not in json.dumps(fit)
assert any("mag_parent" in r for r in par)
assert re.search(r"\(%g per arcmin\^2" % density, line) or abs(len(fit) / 6.0 - density) < 0.1 * density
bright_fit = sum(1 for r in fit if r["mag"] < 22)
bright_par = sum(1 for r in par if r["mag"] < 22)
print("  [measured] galaxies brighter than I = 22 in 6 arcmin^2: fitted counts", bright_fit,
      "parents' magnitudes", bright_par, "; slope", slope)
assert bright_par > 1.5 * bright_fit + 5, (bright_fit, bright_par)
PY
# Tiles of a fitted-counts field give its records back, byte for byte (2×2 over 1024²).
"$BIN/$prog" dense.json --size 0.6797 --pixel-scale 0.03985 --seed 7 --neighbours 16 --counts fit -q >fitw.jsonl ||
  fail "--counts fit on 1024² failed"
: >fitt.jsonl
for y in "1 512" "513 1024"; do
  for x in "1 512" "513 1024"; do
    set -- $x $y
    "$BIN/$prog" dense.json --size 0.6797 --pixel-scale 0.03985 --seed 7 --neighbours 16 -q \
      --counts fit --tile "$1" "$3" "$2" "$4" >>fitt.jsonl || fail "fitted-counts tile $x $y failed"
  done
done
cmp -s <(sort -u fitt.jsonl) <(sort fitw.jsonl) || fail "fitted-counts tiles differ from their field"
# A field too thin to fit counts to: one line that names the model and the way out.
python3 - <<'PY'
import json
m = json.load(open("dense.json"))
m["source_field"]["mags"] = m["source_field"]["mags"][:1]
json.dump(m, open("thin.json", "w"))
PY
rc=0; "$BIN/$prog" thin.json --area 1 --neighbours 4 --counts fit >out 2>err || rc=$?
expect_error "$rc" 1 'thin.json: .*too few to fit counts to; draw with --counts parents'
[ ! -s out ] || fail "a failed fit wrote objects"
"$BIN/$prog" thin.json --area 1 --neighbours 4 --counts parents -q >out || fail "--counts parents on a thin field failed"
rc=0; "$BIN/$prog" dense.json --area 1 --neighbours 4 --counts bogus >out 2>err || rc=$?
expect_error "$rc" 2 'counts'

# Mixtures (the default with --neighbours): every galaxy names its parents and their weights
# (summing to 1, the parent's the largest); --faint-limit adds galaxies below --mag-limit
# (ids u…, below_limit) and leaves the others' records as they were.
"$BIN/$prog" dense.json --size 0.6797 --pixel-scale 0.03985 --seed 7 -q >mix.jsonl || fail "mixtures failed"
"$BIN/$prog" dense.json --size 0.6797 --pixel-scale 0.03985 --seed 7 --faint-limit 31 >faint.jsonl 2>err ||
  fail "--faint-limit failed: $(cat err)"
grep -q 'galaxies below the limit' err || fail "no count of the galaxies below the limit: $(cat err)"
python3 - <<'PY' || fail "mixtures or faint galaxies break the checks"
import json
mix = [json.loads(l) for l in open("mix.jsonl")]
faint = [json.loads(l) for l in open("faint.jsonl")]
for r in mix:
    w = r["weights"]
    assert len(r["parents"]) == len(w) and abs(sum(w) - 1) < 1e-12 and w[0] == max(w), r["id"]
    assert r["parent"] == r["parents"][0], r["id"]
below = [r for r in faint if r["id"].startswith("u")]
assert [r for r in faint if not r["id"].startswith("u")] == mix
assert len(below) > len(mix) / 2, (len(below), len(mix))
assert all(r["below_limit"] and 29 < r["mag"] <= 31 for r in below)
PY
rc=0; "$BIN/$prog" dense.json --area 1 --mix 5 --neighbours 3 >out 2>err || rc=$?
expect_error "$rc" 1 'mix: a mixture of 5 parents needs neighbours ≥ 5'
[ ! -s out ] || fail "a refused mixture wrote objects"
rc=0; "$BIN/$prog" dense.json --area 1 --faint-limit 28 >out 2>err || rc=$?
expect_error "$rc" 1 'faint_limit: must be fainter than the magnitude limit'
rc=0; "$BIN/$prog" morph.json --area 1 --faint-limit 31 --counts fit >out 2>err || rc=$?
expect_error "$rc" 1 'morph.json: --faint-limit needs a model that recorded its fields'
"$BIN/shapesim-smooth" -q --delta --like "$hdf" <shapelets.jsonl >ddense.json || fail "smooth --delta --like failed"
"$BIN/$prog" ddense.json --area 1 --faint-limit 31 -q >dfaint.jsonl || fail "δ with --faint-limit failed"
python3 -c 'import json
rows = [json.loads(l) for l in open("dfaint.jsonl")]
below = [r for r in rows if r.get("below_limit")]
assert below and all(len(r["parents"]) == 1 for r in below), len(below)' ||
  fail "δ galaxies below the limit are not scaled copies of one parent"

# The count law (--counts law, the default): the galaxies brighter than any magnitude are the
# same galaxies (ids, magnitudes, places, parents) whatever --mag-limit, and the density drawn is
# the law's; tiles give the field back; a law from a file draws its own counts; a bad file is
# refused naming its line.
for L in 25 27.5 30; do
  "$BIN/$prog" dense.json --area 6 --pixel-scale 0.03985 --seed 7 --mag-limit $L >law$L.jsonl 2>law$L.err ||
    fail "--mag-limit $L failed: $(cat law$L.err)"
done
grep -q 'galaxy counts: .* per arcmin^2 over 16 - 25, COSMOS2020' law25.err || fail "law not reported: $(cat law25.err)"
python3 - <<'PY' || fail "the count law's galaxies move with --mag-limit"
import json
def bright(path, m=25):
    return sorted((r["id"], r["mag"], r["x"], r["y"]) for r in map(json.loads, open(path))
                  if r["kind"] == "galaxy" and r["mag"] <= m)
a, b, c = bright("law25.jsonl"), bright("law27.5.jsonl"), bright("law30.jsonl")
assert a == b == c and len(a) > 150, (len(a), len(b), len(c))
n30 = sum(1 for l in open("law30.jsonl") if '"galaxy"' in l)
print("  [measured] 6 arcmin^2: I <= 25:", len(a), "(law 44.6/arcmin^2: 268); I <= 30:", n30, "(law 935: 5608)")
assert abs(len(a) - 6 * 44.63) < 5 * (6 * 44.63) ** 0.5 and abs(n30 - 6 * 934.7) < 5 * (6 * 934.7) ** 0.5
PY
: >lawt.jsonl
for x in "1 1500" "1501 3688"; do
  set -- $x
  "$BIN/$prog" dense.json --area 6 --pixel-scale 0.03985 --seed 7 --mag-limit 25 -q \
    --tile "$1" 1 "$2" 3688 >>lawt.jsonl || fail "law tile $x failed"
done
cmp -s <(sort -u lawt.jsonl) <(sort law25.jsonl) || fail "the law's tiles differ from their field"
printf '# mag log10(N per deg^2 per mag)\n20 3.0\n24 4.0\n' >flat.law
"$BIN/$prog" dense.json --area 6 --pixel-scale 0.03985 --seed 7 --mag-limit 24 --counts flat.law \
  >filelaw.jsonl 2>err || fail "--counts FILE failed: $(cat err)"
python3 - <<'PY' || fail "a count law file is not drawn"
import json, math
n = sum(1 for l in open("filelaw.jsonl") if '"galaxy"' in l)
# dN/dm = 10^(3 + (m - 20)/4) per deg^2, from 17 to 24: the integral over 3600 arcmin^2/deg^2
k = 0.25 * math.log(10)
expect = 6 / 3600 * 1e3 * (math.exp(k * 4) - math.exp(-k * 3)) / k
assert abs(n - expect) < 5 * math.sqrt(expect), (n, expect)
PY
printf '20 3.0\n19 4.0\n' >bad.law
rc=0; "$BIN/$prog" dense.json --area 1 --counts bad.law >out 2>err || rc=$?
expect_error "$rc" 1 'bad.law:2: magnitudes must ascend'

rc=0; "$BIN/$prog" nosuch.json --area 1 >out 2>err || rc=$?
expect_error "$rc" 1 'nosuch.json: cannot open'
rc=0; "$BIN/$prog" shapelets.jsonl --area 1 >out 2>err || rc=$?
expect_error "$rc" 1 'shapelets.jsonl'
rc=0; "$BIN/$prog" morph.json >out 2>err || rc=$?
expect_error "$rc" 2 'exactly one of --like, --area, --size'
rc=0; "$BIN/$prog" morph.json --area 1 --tile 1 1 10 >out 2>err || rc=$?
expect_error "$rc" 2 'tile'
rc=0; "$BIN/$prog" morph.json --area 1 --mag-limit 15 >out 2>err || rc=$?
expect_error "$rc" 1 'magnitude limit'
echo '{"schema":"shapesim.morphology/1","n_max":0}' >broken.json
rc=0; "$BIN/$prog" broken.json --area 1 >out 2>err || rc=$?
expect_error "$rc" 1 'broken.json.*lambda'
[ ! -s out ] || fail "output written for a broken model"
exit 0
