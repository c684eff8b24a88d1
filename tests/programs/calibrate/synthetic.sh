#!/usr/bin/env bash
# shapesim-calibrate on synthetic catalogues of known response e = (1 + m) g + c: recovered
# exactly without noise, within its bootstrap errors (which match σ_e/(σ_g √N)) with shape
# noise, alike from JSON lines, CSV, SExtractor's ASCII_HEAD and a FITS table, over two images;
# bins by a column; bad input fails in one line with nothing written.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
cd "$TMPDIR"

# Truth (shapesim.truth/1) and shapes: N galaxies on a grid, g uniform in ±0.05, shapes measured
# at a small offset, with magnitude and S/N columns; one in 50 measurements a stray.
python3 - <<'PY'
import json, random, math
def make(name, n, m, c, noise, seed):
    r = random.Random(seed)
    with open(name + ".truth.jsonl", "w") as t, open(name + ".csv", "w") as s:
        s.write("x,y,e1,e2,snr\n")
        for k in range(n):
            x, y = 10 + 6 * (k % 300), 10 + 6 * (k // 300)
            g1, g2 = r.uniform(-0.05, 0.05), r.uniform(-0.05, 0.05)
            mag = 22 + 6 * r.random()
            t.write(json.dumps({"schema": "shapesim.truth/1", "id": "g%d" % k, "kind": "galaxy",
                "ra": 0, "dec": 0, "x": x, "y": y, "flux": 10 ** (-0.4 * (mag - 30)), "mag": mag,
                "e1": 0, "e2": 0, "rms_radius": 2, "lensing_error": 0, "g1": g1, "g2": g2,
                "kappa": 0, "mu": 1, "n_max": 0, "stamp_radius": 10}) + "\n")
            e1 = (1 + m[0]) * g1 + c[0] + r.gauss(0, noise)
            e2 = (1 + m[1]) * g2 + c[1] + r.gauss(0, noise)
            s.write("%r,%r,%r,%r,%r\n" % (x + 0.3, y - 0.2, e1, e2, 100 / (1 + k % 7)))
            if k % 50 == 0:
                s.write("%r,%r,0.5,0.5,1\n" % (x + 3, y + 3))  # a stray, matched to nothing
make("exact", 3000, (0.02, -0.03), (5e-4, -2e-4), 0.0, 1)
make("noisy", 18000, (0.04, -0.02), (1e-3, 0.0), 0.26, 2)
make("noisy2", 18000, (0.04, -0.02), (1e-3, 0.0), 0.26, 3)
PY

"$BIN/shapesim-calibrate" exact.truth.jsonl exact.csv --json exact.json --bin snr:2 --figures fig \
  >exact.md 2>err || fail "calibrate failed: $(cat err)"
[ -s fig/calibration.png ] && [ -s fig/residuals.dat ] && [ -s fig/bins.dat ] || fail "no figure: $(ls fig)"
# The residuals e − g of an exact m = 0.02 lie on 0.02 g + 0.0005, bin by bin.
python3 - <<'PY' || fail "the figure's residuals are not the fit's"
rows = [l.split() for l in open("fig/residuals.dat") if l.strip() and not l.startswith("#")]
assert len(rows) == 20, len(rows)
for c, g, r, err, n in rows:
    m, cc = (0.02, 5e-4) if c == "1" else (-0.03, -2e-4)
    assert abs(float(r) - (m * float(g) + cc)) < 1e-12, (c, g, r)
PY
python3 - <<'PY' || fail "m and c not recovered exactly: $(cat exact.md)"
import json
j = json.load(open("exact.json"))
a = j["all"]
assert a["galaxies"] == 3000 and j["unmatched"] == 60, (a["galaxies"], j["unmatched"])
assert abs(a["g1"]["m"] - 0.02) < 1e-10 and abs(a["g2"]["m"] + 0.03) < 1e-10, a
assert abs(a["g1"]["c"] - 5e-4) < 1e-12 and abs(a["g2"]["c"] + 2e-4) < 1e-12, a
assert a["g1"]["m_err"] < 1e-10
bins = j["bins"]["snr"]
assert len(bins) == 2 and sum(b["galaxies"] for b in bins) == 3000
assert all(abs(b["fit"]["g1"]["m"] - 0.02) < 1e-10 for b in bins)
md = open("exact.md").read()
assert "| 1 | 0.02 ± " in md and "| 0.0005 ± " in md and "## By snr" in md, md
PY

# Two images at once, with shape noise: within 3σ, the errors as shape noise predicts.
"$BIN/shapesim-calibrate" -q noisy.truth.jsonl noisy.csv noisy2.truth.jsonl noisy2.csv \
  --json noisy.json >noisy.md || fail "calibrate of two images failed"
python3 - <<'PY' || fail "noisy recovery off: $(cat noisy.md)"
import json, math
a = json.load(open("noisy.json"))["all"]
assert a["galaxies"] == 36000
predicted = 0.26 / (0.1 / math.sqrt(12) * math.sqrt(36000))   # σ_e / (σ_g √N)
assert abs(a["g1"]["m_err"] / predicted - 1) < 0.2, (a["g1"]["m_err"], predicted)
assert abs(a["g1"]["m"] - 0.04) < 3 * a["g1"]["m_err"] and abs(a["g2"]["m"] + 0.02) < 3 * a["g2"]["m_err"], a
assert abs(a["g1"]["c"] - 1e-3) < 3 * a["g1"]["c_err"] and abs(a["g2"]["c"]) < 3 * a["g2"]["c_err"], a
PY

# The same shapes as JSON lines, SExtractor ASCII_HEAD (other column names) and a FITS table.
python3 - <<'PY'
import csv, json
rows = list(csv.DictReader(open("exact.csv")))
with open("exact.jsonl", "w") as f:
    for r in rows:
        f.write(json.dumps({"schema": "user.shapes/1", **{k: float(v) for k, v in r.items()}}) + "\n")
with open("exact.cat", "w") as f:
    for k, n in enumerate(["NUMBER", "X_IMAGE", "Y_IMAGE", "E1", "E2", "SNR_WIN"], 1):
        f.write("#%4d %-16s column %d\n" % (k, n, k))
    for i, r in enumerate(rows, 1):
        f.write("%d %s %s %s %s %s\n" % (i, r["x"], r["y"], r["e1"], r["e2"], r["snr"]))
PY
# SExtractor's windowed second moments of the same shapes: the ellipse of ε.
python3 - <<'PY'
import csv
rows = list(csv.DictReader(open("exact.csv")))
with open("moments.cat", "w") as f:
    for k, n in enumerate(["NUMBER", "XWIN_IMAGE", "YWIN_IMAGE", "X2WIN_IMAGE", "Y2WIN_IMAGE", "XYWIN_IMAGE"], 1):
        f.write("#%4d %-16s column %d\n" % (k, n, k))
    for i, r in enumerate(rows, 1):
        e1, e2, s2 = float(r["e1"]), float(r["e2"]), 4.0
        d = 1 - e1 * e1 - e2 * e2
        f.write("%d %s %s %r %r %r\n" % (i, r["x"], r["y"], s2 * ((1 + e1) ** 2 + e2 ** 2) / d,
                                          s2 * ((1 - e1) ** 2 + e2 ** 2) / d, s2 * 2 * e2 / d))
PY
"$BIN/shapesim-calibrate" -q --position XWIN_IMAGE,YWIN_IMAGE --moments X2WIN_IMAGE,Y2WIN_IMAGE,XYWIN_IMAGE \
  exact.truth.jsonl moments.cat --json j4.json >/dev/null || fail "--moments failed"
rc=0; "$BIN/shapesim-calibrate" --moments a,b exact.truth.jsonl moments.cat >out 2>err || rc=$?
expect_error $rc 2 "^shapesim-calibrate: --moments: give three names, XX,YY,XY"
"$BIN/shapesim-table" --format fits -o exact.fits exact.jsonl 2>err || fail "table failed: $(cat err)"
"$BIN/shapesim-calibrate" -q exact.truth.jsonl exact.jsonl --json j1.json >/dev/null || fail "JSON lines failed"
"$BIN/shapesim-calibrate" -q exact.truth.jsonl exact.fits --json j2.json >/dev/null || fail "FITS failed"
"$BIN/shapesim-calibrate" -q --position X_IMAGE,Y_IMAGE --e1 E1 --e2 E2 --bin SNR_WIN \
  exact.truth.jsonl exact.cat --json j3.json >/dev/null || fail "SExtractor ASCII_HEAD failed"
python3 - <<'PY' || fail "the formats disagree"
import json
ref = json.load(open("exact.json"))["all"]
for f in ("j1.json", "j2.json", "j3.json", "j4.json"):
    a = json.load(open(f))["all"]
    tol = 1e-12 if f != "j4.json" else 1e-9   # the moments' round trip costs a few ulps of e
    for k in ("g1", "g2"):
        assert abs(a[k]["m"] - ref[k]["m"]) < tol and abs(a[k]["c"] - ref[k]["c"]) < tol / 100, (f, a, ref)
PY

# Rings: 100 pairs sharing their shear, one copy of ten pairs unmeasured. Each pair is one
# bootstrap block; --complete-rings leaves out the ten whose partner was lost.
python3 - <<'PY'
import json, random
r = random.Random(5)
with open("rings.truth.jsonl", "w") as t, open("rings.csv", "w") as s:
    s.write("x,y,e1,e2\n")
    for k in range(200):
        pair = k // 2
        r.seed(pair)
        g1, g2 = r.uniform(-0.05, 0.05), r.uniform(-0.05, 0.05)
        x, y = 10 + 6 * (k % 30), 10 + 6 * (k // 30)
        t.write(json.dumps({"schema": "shapesim.truth/1", "id": "g%d" % k, "kind": "galaxy", "ra": 0,
            "dec": 0, "x": x, "y": y, "flux": 1, "e1": 0, "e2": 0, "rms_radius": 2, "lensing_error": 0,
            "g1": g1, "g2": g2, "kappa": 0, "mu": 1, "n_max": 0, "stamp_radius": 10,
            "ring": {"first": "g%d" % (2 * pair), "member": k % 2, "of": 2, "x": x, "y": y}}) + "\n")
        if pair < 10 and k % 2 == 1: continue
        s.write("%r,%r,%r,%r\n" % (x, y, 1.01 * g1 + 0.3 * (-1) ** k, 1.01 * g2))
PY
"$BIN/shapesim-calibrate" -q rings.truth.jsonl rings.csv --json all.json >/dev/null || fail "rings failed"
"$BIN/shapesim-calibrate" -q rings.truth.jsonl rings.csv --complete-rings --json complete.json >/dev/null ||
  fail "--complete-rings failed"
python3 - <<'PY' || fail "rings are not blocks, or incomplete ones not left out"
import json
a, c = json.load(open("all.json")), json.load(open("complete.json"))
assert (a["all"]["galaxies"], a["all"]["blocks"]) == (190, 100), a["all"]
assert (c["all"]["galaxies"], c["all"]["blocks"], c["incomplete_rings_left_out"]) == (180, 90, 10), c
# Complete pairs cancel their ±0.3 exactly: m1 = 0.01 to rounding; the ten lone copies do not.
assert abs(c["all"]["g1"]["m"] - 0.01) < 1e-9 and c["all"]["g1"]["m_err"] < 1e-9, c["all"]
assert abs(a["all"]["g1"]["m"] - 0.01) > 1e-3, a["all"]
PY

# On the sky (--sky): the same galaxies placed across RA 0 at 0.1″ a pixel, matched by
# ra, dec (the shapes' RA written in (−180°, 180]), give the pixel matching's m and c.
python3 - <<'PY'
import csv, json
def sky(x, y):
    return ((x - 900) * 0.1 / 3600) % 360, 10 + y * 0.1 / 3600
with open("sky.truth.jsonl", "w") as f:
    for l in open("exact.truth.jsonl"):
        t = json.loads(l)
        t["ra"], t["dec"] = sky(t["x"], t["y"])
        f.write(json.dumps(t) + "\n")
with open("sky.csv", "w") as f:
    f.write("ra,dec,e1,e2\n")
    for r in csv.DictReader(open("exact.csv")):
        ra, dec = sky(float(r["x"]), float(r["y"]))
        ra = ra - 360 if ra > 180 else ra   # this catalogue writes RA in (-180, 180]
        f.write("%r,%r,%s,%s\n" % (ra, dec, r["e1"], r["e2"]))
PY
"$BIN/shapesim-calibrate" -q --sky --position ra,dec sky.truth.jsonl sky.csv --json sky.json >/dev/null ||
  fail "--sky failed"
python3 - <<'PY' || fail "--sky does not match as the pixels do"
import json
a, ref = json.load(open("sky.json")), json.load(open("exact.json"))
assert a["all"]["galaxies"] == ref["all"]["galaxies"] == 3000, a["all"]
for k in ("g1", "g2"):
    assert abs(a["all"][k]["m"] - ref["all"][k]["m"]) < 1e-12, (a["all"], ref["all"])
PY

# Bad input: one line, nothing written.
rc=0; "$BIN/shapesim-calibrate" exact.truth.jsonl >out 2>err || rc=$?
expect_error $rc 2 "^shapesim-calibrate: give pairs of files"
rc=0; "$BIN/shapesim-calibrate" exact.truth.jsonl exact.csv --e1 shear1 -o r.md 2>err || rc=$?
expect_error $rc 1 "^shapesim-calibrate: exact.csv: no column shear1"
[ ! -e r.md ] || fail "a refused run left its report"
python3 -c '
import json
for l in open("exact.truth.jsonl"):
    t = json.loads(l); t["g1"] = 0.02; print(json.dumps(t))' >one.truth.jsonl
rc=0; "$BIN/shapesim-calibrate" one.truth.jsonl exact.csv >out 2>err || rc=$?
expect_error $rc 1 "the true g1 takes one value: m and c need the shear to vary"
rc=0; "$BIN/shapesim-calibrate" exact.truth.jsonl exact.csv --bin nosuch -o r.md 2>err || rc=$?
expect_error $rc 1 "^shapesim-calibrate: exact.csv: --bin nosuch: no such column, nor a truth field"
[ ! -e r.md ] || fail "a refused run left its report"
rc=0; "$BIN/shapesim-calibrate" exact.truth.jsonl exact.csv --bin snr:0 >out 2>err || rc=$?
expect_error $rc 2 "^shapesim-calibrate: --bin snr:0: N must be 1 to 100"

# PSF leakage: a truth drawn through a varying PSF (render --psf-field) carries psf_e1; shapes
# with c1 = 0.1 psf_e1 give, in two bins of psf_e1, c1 = 0.1 × each bin's mean psf_e1.
python3 - <<'PY'
import json
with open("leak.truth.jsonl", "w") as t, open("leak.csv", "w") as s:
    s.write("x,y,e1,e2\n")
    for l in open("exact.truth.jsonl"):
        r = json.loads(l)
        r["psf_e1"] = -0.03 if int(r["id"][1:]) % 2 == 0 else 0.03
        t.write(json.dumps(r) + "\n")
        s.write("%r,%r,%r,%r\n" % (r["x"], r["y"], r["g1"] + 0.1 * r["psf_e1"], r["g2"]))
PY
"$BIN/shapesim-calibrate" -q leak.truth.jsonl leak.csv --bin psf_e1:2 --json leak.json >/dev/null ||
  fail "--bin psf_e1 failed"
python3 - <<'PY' || fail "the psf_e1 bins do not show the leakage"
import json
b = json.load(open("leak.json"))["bins"]["psf_e1"]
assert len(b) == 2, b
assert abs(b[0]["fit"]["g1"]["c"] + 0.003) < 1e-10 and abs(b[1]["fit"]["g1"]["c"] - 0.003) < 1e-10, b
PY
exit 0
