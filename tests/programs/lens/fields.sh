#!/usr/bin/env bash
# shapesim-lens on galaxies sampled from the HDF morphology: every galaxy gets the lensing of
# the field where it is (stars none; a ring its first copy's), the same bits whatever the tile
# its objects were sampled in; render applies it (the truth's g, and e moved from e_intrinsic);
# NFW halos shear tangentially; rotated pairs cut the scatter of the mean shear ≥ 10× against
# random orientations; bad input fails in one line with nothing written.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
tools=$(cd ../tools && pwd)
cd "$TMPDIR"
hdf_morphology
# The HDF's PSF: the models hold it (observed frame), so render convolves them with nothing
# and lenses PSF and all (render says so); the mechanics tested here are the same.
"$BIN/shapesim-decompose" -q --psf-image "$HDF_DATA/wfpc2_f814w_tinytim_psf.fits" --like "$HDF_IMAGE" \
  --psf-box 0.0996 0.05 >psf.jsonl || fail "decompose --psf-image failed"
psf=(--psf psf.jsonl --galaxy-psf psf.jsonl)
python3 -c '
for k in range(60):
    l = 10 ** (2 + k * 0.1)
    print(l, 1e-10 * min(1.0, (l / 1e3) ** -1.5))' >ps.txt
field=(--pixels 1500 --pixel-scale 0.0398)

# A field with rings of two and three stars, lensed by a random field and a cluster 40″ south.
"$BIN/shapesim-sample" -q morph.json "${field[@]}" --zero-point 30.9 --ring 2 --star-count 3 --seed 4 \
  >objects.jsonl || fail "sample failed"
"$BIN/shapesim-lens" "${field[@]}" --power-spectrum ps.txt --halo 750 -250 3e14 5 0.3 --source-z 1.2 \
  --seed 9 <objects.jsonl >lensed.jsonl 2>lens.err || fail "lens failed: $(cat lens.err)"
grep -q "galaxies lensed: rms |g|" lens.err || fail "no summary: $(cat lens.err)"
python3 - <<'PY' || fail "the lensed catalogue is wrong"
import json, math
objs = [json.loads(l) for l in open("objects.jsonl")]
lensed = [json.loads(l) for l in open("lensed.jsonl")]
assert len(objs) == len(lensed) > 100
rings = {}
for o, l in zip(objs, lensed):
    if o["kind"] == "star":
        assert "lensing" not in l and l == o
        continue
    g = l["lensing"]
    assert set(g) == {"g1", "g2", "kappa", "magnify"} and g["magnify"] is True
    assert math.hypot(g["g1"], g["g2"]) < 0.5 and abs(g["kappa"]) < 0.5
    l.pop("lensing")
    assert l == o, "only the lensing is added"
    rings.setdefault(o["ring"]["first"], []).append(g)
assert all(len(r) == 2 and r[0] == r[1] for r in rings.values()), "a ring's copies differ"
PY

# Tiles: each tile's objects lensed alone carry the whole field's lensing, bit for bit.
for t in "1 1 750 1500" "751 1 1500 1500"; do
  "$BIN/shapesim-sample" -q morph.json "${field[@]}" --zero-point 30.9 --ring 2 --star-count 3 \
    --seed 4 --tile $t | "$BIN/shapesim-lens" -q "${field[@]}" --power-spectrum ps.txt \
    --halo 750 -250 3e14 5 0.3 --source-z 1.2 --seed 9 >>tiles.jsonl || fail "tile $t failed"
done
python3 - <<'PY' || fail "a tile's lensing differs from the whole field's"
import json
whole = {o["id"]: o.get("lensing") for o in map(json.loads, open("lensed.jsonl"))}
seen = 0
for o in map(json.loads, open("tiles.jsonl")):
    assert o.get("lensing") == whole[o["id"]], o["id"]
    seen += 1
assert seen >= len(whole)
PY

# Render applies each galaxy's own lensing, before the PSF: the truth's g is the record's and
# e moves from e_intrinsic by about g; a scene-wide --shear on top is refused.
"$BIN/shapesim-render" -q "${field[@]}" "${psf[@]}" --noise-free --truth truth.jsonl -o lensed.fits <lensed.jsonl ||
  fail "render failed"
python3 - <<'PY' || fail "render did not apply the lensing"
import json
lensing = {o["id"]: o["lensing"] for o in map(json.loads, open("lensed.jsonl")) if "lensing" in o}
n = 0
for t in map(json.loads, open("truth.jsonl")):
    if t["kind"] != "galaxy": continue
    g = lensing[t["id"]]
    assert (t["g1"], t["g2"], t["kappa"]) == (g["g1"], g["g2"], g["kappa"]), t["id"]
    mu = 1 / ((1 - g["kappa"]) ** 2 * (1 - g["g1"] ** 2 - g["g2"] ** 2))
    assert abs(t["mu"] / mu - 1) < 1e-12
    assert isinstance(t["ring"], dict)
    n += 1
assert n == len(lensing), (n, len(lensing))
PY
# The truth's own ellipticity as the shape estimate: rings sharing their lensing give m ≈ 0 to
# second order in g·e² with small errors, whatever the shear field (errors 0.006–0.013 with the
# merged model's ellipticities, rms ε ≈ 0.2 per component: within 3σ and 0.02).
"$BIN/shapesim-calibrate" -q truth.jsonl truth.jsonl --json self.json >self.md || fail "calibrate failed"
python3 - <<'PY' || fail "the truth does not calibrate to m = 0: $(cat self.md)"
import json
a = json.load(open("self.json"))["all"]
for k in ("g1", "g2"):
    assert abs(a[k]["m"]) < max(0.01, 3 * a[k]["m_err"]) and a[k]["m_err"] < 0.02, a
    assert abs(a[k]["c"]) < 1e-3, a
assert a["blocks"] * 2 == a["galaxies"], a   # each ring one bootstrap block
PY
rc=0
"$BIN/shapesim-render" -q "${field[@]}" "${psf[@]}" --noise-free --shear 0.01 0 -o twice.fits <lensed.jsonl 2>err || rc=$?
expect_error $rc 1 "carries its own lensing (shapesim-lens): --shear/--kappa would lens it twice"
[ ! -e twice.fits ] || fail "a refused render left its image"

# NFW: galaxies east and west of the halo (same y) are stretched along y (g1 < 0), those north
# and south along x (g1 > 0); κ falls with radius.
python3 -c '
import json
for k, (x, y) in enumerate([(700, 600), (500, 600), (600, 700), (600, 500), (900, 600)]):
    print(json.dumps({"schema": "shapesim.object/1", "id": "p%d" % k, "kind": "galaxy", "ra": 0, "dec": 0,
                      "x": x, "y": y, "flux": 1, "beta": 0.1, "pixel_scale": 0.05, "n_max": 0,
                      "coeffs": [[1, 0]]}))' >probes.jsonl
"$BIN/shapesim-lens" -q "${field[@]}" --halo 600 600 1e14 5 0.3 --source-z 1.2 --map map.fits --map-binning 1 \
  <probes.jsonl >probes.out || fail "lens of the probes failed"
# The map holds the same lensing at each pixel (float: to 1e-6).
python3 - "$tools" <<'PY' || fail "the map is not the probes' lensing"
import json, sys
sys.path.insert(0, sys.argv[1])
from fitsdata import read
probes = [json.loads(l) for l in open("probes.out")]
cards, nx, ny, kappa = read("map.fits", "KAPPA")
_, _, _, gamma1 = read("map.fits", "GAMMA1")
assert (nx, ny) == (1500, 1500) and cards["EXTNAME"] == "KAPPA", (nx, ny)
for p in probes:
    i, j = int(p["x"]) - 1, int(p["y"]) - 1
    l = p["lensing"]
    assert abs(kappa[j][i] - l["kappa"]) < 1e-6 * abs(l["kappa"]), (p["id"], kappa[j][i], l)
    assert abs(gamma1[j][i] - l["g1"] * (1 - l["kappa"])) < 1e-6 * abs(l["g1"]) + 1e-9, (p["id"], gamma1[j][i], l)
PY
python3 - <<'PY' || fail "the halo does not shear tangentially: $(cat probes.out)"
import json
g = [json.loads(l)["lensing"] for l in open("probes.out")]
assert g[0]["g1"] < 0 and g[1]["g1"] < 0 and g[2]["g1"] > 0 and g[3]["g1"] > 0, g
assert all(abs(x["g2"]) < 1e-12 for x in g), g
assert abs(g[0]["g1"] - g[1]["g1"]) < 1e-15 and abs(g[0]["g1"] + g[2]["g1"]) < 1e-15
assert g[4]["kappa"] < g[0]["kappa"] and abs(g[4]["g1"]) < abs(g[0]["g1"])
PY

# Shape-noise cancellation: the mean e of 200 galaxies under one shear scatters over seeds ≥ 10×
# less in rotated pairs than in random orientations.
for ring in 1 2; do
  for seed in 1 2 3 4 5 6; do
    "$BIN/shapesim-sample" -q morph.json --area 0.3 --zero-point 30.9 --count 200 --star-density 0 \
      --ring $ring --seed $seed | "$BIN/shapesim-lens" -q --area 0.3 --shear 0.03 -0.01 |
      "$BIN/shapesim-render" -q --area 0.3 "${psf[@]}" --noise-free --truth r$ring.s$seed.jsonl -o r.fits ||
      fail "ring $ring seed $seed failed"
  done
done
python3 - <<'PY' || fail "rotated pairs do not cancel the shape noise"
import json, statistics as st
def scatter(ring):
    means = []
    for seed in range(1, 7):
        t = [json.loads(l) for l in open("r%d.s%d.jsonl" % (ring, seed))]
        e = [x["e1"] for x in t if x["kind"] == "galaxy" and x["e1"] is not None]
        assert len(e) == 200, len(e)
        means.append(sum(e) / len(e))
    return st.pstdev(means), st.mean(means)
random, mr = scatter(1)
pairs, mp = scatter(2)
print("scatter of the mean e1: random %.2e, pairs %.2e (%.0fx); mean %.4f %.4f" % (random, pairs, random / pairs, mr, mp))
assert random > 10 * pairs, (random, pairs)
assert abs(mp - 0.03) < 0.003, mp
PY

# Bad input: one line, exit 1 or 2, nothing written.
rc=0; "$BIN/shapesim-lens" "${field[@]}" --halo 1 2 3 4 <objects.jsonl >out 2>err || rc=$?
expect_error $rc 2 "^shapesim-lens: --halo takes five numbers each"
rc=0; "$BIN/shapesim-lens" "${field[@]}" <objects.jsonl >out 2>err || rc=$?
expect_error $rc 2 "^shapesim-lens: no lens"
rc=0; "$BIN/shapesim-lens" "${field[@]}" --halo 600 600 1e16 4 0.3 --source-z 1 -o strong.jsonl <objects.jsonl 2>err || rc=$?
expect_error $rc 1 "is strongly lensed (kappa .*beyond weak lensing .*see --drop-strong)"
[ ! -e strong.jsonl ] || fail "a refused run left its output"
"$BIN/shapesim-lens" -q "${field[@]}" --halo 600 600 1e16 4 0.3 --source-z 1 --drop-strong <objects.jsonl \
  >dropped.jsonl || fail "--drop-strong failed"
[ "$(wc -l <dropped.jsonl)" -lt "$(wc -l <objects.jsonl)" ] || fail "--drop-strong dropped nothing"
rc=0; "$BIN/shapesim-lens" "${field[@]}" --shear 0.01 0 <lensed.jsonl >out 2>err || rc=$?
expect_error $rc 1 "^shapesim-lens: -:[0-9]*: lensing: object .* is already lensed"
printf '100 1e-9\n200 -1\n' >bad.txt
rc=0; "$BIN/shapesim-lens" "${field[@]}" --power-spectrum bad.txt <objects.jsonl >out 2>err || rc=$?
expect_error $rc 1 "^shapesim-lens: bad.txt:2: P(ell) must be finite and >= 0"
rc=0; "$BIN/shapesim-lens" "${field[@]}" --halo 600 600 1e14 4 1.5 --source-z 1 <objects.jsonl >out 2>err || rc=$?
expect_error $rc 1 "must lie behind the halo"
exit 0
