#!/usr/bin/env bash
# shapesim-survey (issue 37): a shipped survey by name gives an image, its objects, its truth
# and the commands it ran; the header carries BUNIT, EXPTIME, GAIN, MAGZERO/PHOTZP; the same
# seed gives the same bits; fitsverify finds nothing. On the Rubin-like ground survey (Moffat
# 0.7″ at 0.2″/px, sky 20.46 mag/arcsec², read noise 9 e-, gain 1.6): the sky's rms (image −
# its noise-free twin, which holds no sky, where the sources add < 1% of the sky) is within 1%
# of √(sky e- + read²)/gain, and stars measured in 5″ apertures with the header's MAGZERO
# alone are within 0.01 mag of the truth. truth.fits is a FITS table astropy reads with units, the
# image's WCS maps the truth's x, y to its ra, dec, and a sheared survey's truth holds g, kappa, mu
# and the intrinsic beside the lensed ellipticity. A survey without a zero point, a bad PSF spec and an
# unknown model are one line each.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
tools=$(cd ../tools && pwd)
check_help shapesim-survey
check_version shapesim-survey
cd "$TMPDIR"

# The two commands, run from bin/ beside it, on the shipped model.
"$BIN/shapesim-survey" rubin-i --dry-run >cmds || fail "--dry-run failed"
[ "$(wc -l <cmds)" -eq 3 ] || fail "--dry-run: $(cat cmds)"
grep -q "^$BIN/shapesim-table .*truth.jsonl --like .*image.fits -o .*truth.fits$" cmds || fail "table: $(tail -1 cmds)"
grep -q "^$BIN/shapesim-sample .*/models/merged.json .*--pixels 1200 " cmds || fail "sample: $(head -1 cmds)"
grep -q "^$BIN/shapesim-render .*--psf-analytic moffat:0.7,3.5 .*--gain 1.6 --saturation 62500 --exptime 30 " cmds ||
  fail "render: $(sed -n 2p cmds)"

stars=(--pixels 400 --mag-limit 21 --star-density 20 --star-mag-min 17 --star-mag-max 19 --seed 4 -q)
"$BIN/shapesim-survey" rubin-i "${stars[@]}" -o a || fail "shapesim-survey rubin-i failed"
"$BIN/shapesim-survey" rubin-i "${stars[@]}" -o b -j 2 || fail "second run failed"
"$BIN/shapesim-survey" rubin-i "${stars[@]}" --noise-free -o clean || fail "--noise-free failed"
for f in image.fits objects.jsonl truth.jsonl truth.fits commands.sh; do [ -s "a/$f" ] || fail "no $f"; done
cmp a/objects.jsonl b/objects.jsonl && cmp a/truth.jsonl b/truth.jsonl || fail "not deterministic"
cmp <(tail -c +20000 a/image.fits) <(tail -c +20000 b/image.fits) || fail "pixels not deterministic"
cmp a/objects.jsonl clean/objects.jsonl || fail "--noise-free drew other objects"
sh -n a/commands.sh || fail "commands.sh is not a shell script"
if command -v fitsverify >/dev/null; then
  for f in image.fits truth.fits; do
    fitsverify -q a/$f | grep -q "^verification OK" || fail "fitsverify: $(fitsverify a/$f | tail -5)"
  done
fi

# The truth as astropy reads it: a FITS table with units, the same rows as truth.jsonl, the
# image's WCS without a warning, the intrinsic and the lensed shapes of a sheared survey.
"$BIN/shapesim-survey" rubin-i --pixels 200 --shear 0.05 0 --seed 2 -q -o sheared || fail "--shear failed"
/usr/bin/python3 - <<'PY' || fail "astropy read the truth or the WCS otherwise"
import json, math, warnings
warnings.simplefilter("error")
from astropy.table import Table
from astropy.io import fits
from astropy.wcs import WCS
t = Table.read("a/truth.fits")
rows = [json.loads(l) for l in open("a/truth.jsonl")]
assert len(t) == len(rows) > 0, (len(t), len(rows))
assert str(t["flux"].unit) == "adu" and str(t["ra"].unit) == "deg" and str(t["x"].unit) == "pix"
assert str(t["mag"].unit) == "mag" and str(t["rms_radius"].unit) == "pix"
for r, row in zip(rows, t):
    assert row["id"] == r["id"] and row["kind"] == r["kind"] and row["x"] == r["x"] and row["flux"] == r["flux"]
w = WCS(fits.getheader("a/image.fits", 1))
ra, dec = w.all_pix2world([[rows[0]["x"], rows[0]["y"]]], 1)[0]
assert abs(ra - rows[0]["ra"]) < 1e-9 and abs(dec - rows[0]["dec"]) < 1e-9, (ra, dec, rows[0])
s = [r for r in (json.loads(l) for l in open("sheared/truth.jsonl")) if r["kind"] == "galaxy"]
assert s and all(r["g1"] == 0.05 and r["g2"] == 0 and r["kappa"] == 0 for r in s)
assert all(abs(r["mu"] - 1 / (1 - 0.05 ** 2)) < 1e-12 for r in s)
# Lensing moves every ellipticity: e ≈ e0 + g (1 - |e0|^2) to first order for small e0.
d = [r["e1"] - r["e1_intrinsic"] for r in s if abs(r["e1_intrinsic"]) < 0.2 and abs(r["e2_intrinsic"]) < 0.2]
assert d and all(0.03 < v < 0.07 for v in d), d
u = [r for r in rows if r["kind"] == "galaxy"]
assert all(r["e1"] == r["e1_intrinsic"] and r["g1"] == 0 and r["mu"] == 1 for r in u)
print(f"truth.fits: {len(t)} rows with units; sheared e1 - e1_intrinsic {min(d):.4f}..{max(d):.4f} for g1 = 0.05")
PY

python3 - "$tools" <<'PY' || fail "the ground survey is off"
import json, math, sys
sys.path.insert(0, sys.argv[1])
from fitsdata import read
def header(path):
    raw = open(path, "rb").read(2880 * 8).decode("ascii", "replace")
    cards = [raw[i:i + 80] for i in range(0, len(raw), 80)]
    h = {}
    for c in cards:
        if c[8:10] == "= " and c[:8].strip() not in h:
            v = c[10:].split("/")[0].strip()
            h[c[:8].strip()] = v.strip("'").strip()
    return h
h = header("a/image.fits")
assert h["BUNIT"] == "adu", h["BUNIT"]
assert float(h["EXPTIME"]) == 30.0 and float(h["GAIN"]) == 1.6, (h["EXPTIME"], h["GAIN"])
zp = 28.36 + 2.5 * math.log10(30 / 1.6)
assert abs(float(h["MAGZERO"]) - zp) < 1e-6 and h["PHOTZP"] == h["MAGZERO"], h["MAGZERO"]
sky_e = 10 ** (-0.4 * (20.46 - 28.36)) * 0.2 ** 2 * 30
assert abs(float(h["SKY"]) - sky_e / 1.6) < 1e-6, h["SKY"]

_, nx, ny, img = read("a/image.fits")
_, _, _, clean = read("clean/image.fits")
sky = sky_e / 1.6
d = [img[j][i] - clean[j][i] for j in range(ny) for i in range(nx) if clean[j][i] < 0.01 * sky]
mean = sum(d) / len(d)
rms = math.sqrt(sum((v - mean) ** 2 for v in d) / (len(d) - 1))
want = math.sqrt(sky_e + 9 ** 2) / 1.6
print(f"sky rms {rms:.4f} ADU over {len(d)} pixels, predicted {want:.4f} ({rms / want - 1:+.4f})")
assert abs(rms / want - 1) < 0.01, (rms, want)

truth = [json.loads(l) for l in open("a/truth.jsonl")]
r = 25  # pixels: 5″, 7 FWHM (the Moffat's light beyond it: 3e-5)
checked = 0
for t in truth:
    if t["kind"] != "star": continue
    x, y = t["x"], t["y"]
    if not (r < x < nx - r and r < y < ny - r): continue
    if any(o is not t and math.hypot(o["x"] - x, o["y"] - y) < r + 10 and o["mag"] < t["mag"] + 5
           for o in truth):
        continue
    s = 0.0
    for j in range(int(y - r), int(y + r) + 2):
        for i in range(int(x - r), int(x + r) + 2):
            if (i - x) ** 2 + (j - y) ** 2 <= r * r:
                s += clean[j - 1][i - 1]  # the noise-free image: no sky
    mag = float(h["MAGZERO"]) - 2.5 * math.log10(s)
    print(f"star {t['id']}: {mag:.4f} against {t['mag']:.4f}")
    assert abs(mag - t["mag"]) < 0.01, (t["id"], mag, t["mag"])
    checked += 1
assert checked >= 3, checked
PY

# The same stars measured by shapesim-measure (a pixel-integrated Moffat fitted to each star:
# the seeing; a 5″ aperture with the header's zero point) and by SExtractor (MAG_APER in the
# same aperture, MAG_ZEROPOINT from the header): isolated stars brighter than 18.3 within 1% of
# 0.7″ and within 0.01 mag of the truth.
"$BIN/shapesim-measure" a/image.fits --with-stars --aperture 5 --psf-analytic moffat:0.7,3.5 -q \
  >stars.morph.jsonl || fail "shapesim-measure --with-stars failed"
sex=""
if command -v source-extractor >/dev/null; then
  zp=$(python3 -c "import math; print(28.36 + 2.5 * math.log10(30 / 1.6))")
  printf 'NUMBER\nX_IMAGE\nY_IMAGE\nMAG_APER\nFWHM_IMAGE\nFLAGS\n' >stars.param
  source-extractor a/image.fits -c /dev/null -CATALOG_NAME stars.cat -CATALOG_TYPE ASCII_HEAD \
    -PARAMETERS_NAME stars.param -FILTER N -PHOT_APERTURES 25 -MAG_ZEROPOINT "$zp" \
    -GAIN 1.6 -PIXEL_SCALE 0 -SEEING_FWHM 0.7 -SATUR_LEVEL 1e9 -VERBOSE_TYPE QUIET \
    -STARNNW_NAME /usr/share/source-extractor/default.nnw || fail "source-extractor failed"
  sex=stars.cat
fi
python3 - "$sex" <<'PY' || fail "stars measured off the truth"
import json, math, sys
truth = [json.loads(l) for l in open("a/truth.jsonl")]
ours = [json.loads(l) for l in open("stars.morph.jsonl")]
sex = []
if sys.argv[1]:
    cols = {}
    for line in open(sys.argv[1]):
        p = line.split()
        if line.startswith("#"): cols[p[2]] = int(p[1]) - 1
        else: sex.append({k: float(p[i]) for k, i in cols.items()})
def isolated(t):
    return all(o is t or math.hypot(o["x"] - t["x"], o["y"] - t["y"]) > 30 or o["mag"] > t["mag"] + 5
               for o in truth)
stars = [t for t in truth if t["kind"] == "star" and t["mag"] < 18.3 and isolated(t)
         and 15 < t["x"] < 385 and 15 < t["y"] < 385]
assert len(stars) >= 5, len(stars)
for t in stars:
    m = min(ours, key=lambda r: math.hypot(r["x"] - t["x"], r["y"] - t["y"]))
    assert math.hypot(m["x"] - t["x"], m["y"] - t["y"]) < 1 and m["kind"] == "star", (t["id"], m)
    fwhm = m["fwhm_moffat"] * 0.2
    print(f"star {t['id']} {t['mag']:.3f}: Moffat FWHM {fwhm:.4f}\", beta {m['beta_moffat']:.2f}; "
          f"mag_aper {m['mag_aper'] - t['mag']:+.4f}", end="")
    assert abs(fwhm / 0.7 - 1) < 0.01, (t["id"], fwhm)
    assert abs(m["mag_aper"] - t["mag"]) < 0.01, (t["id"], m["mag_aper"], t["mag"])
    if sex:
        s = min(sex, key=lambda r: math.hypot(r["X_IMAGE"] - t["x"], r["Y_IMAGE"] - t["y"]))
        assert math.hypot(s["X_IMAGE"] - t["x"], s["Y_IMAGE"] - t["y"]) < 1, (t["id"], s)
        print(f"; SExtractor MAG_APER {s['MAG_APER'] - t['mag']:+.4f}", end="")
        assert abs(s["MAG_APER"] - t["mag"]) < 0.01, (t["id"], s["MAG_APER"], t["mag"])
    print()
PY

# Bad surveys: one line, exit 2, nothing written.
printf 'pixels = 64\npsf = moffat:0.7\nexposure = 30\n' >nozp.survey
rc=0; "$BIN/shapesim-survey" nozp.survey -o x >out 2>err || rc=$?
expect_error "$rc" 2 "needs zero-point"
rc=0; "$BIN/shapesim-survey" rubin-i --psf moffat:0.7,0.5 -o x >out 2>err || rc=$?
expect_error "$rc" 2 "psf"
rc=0; "$BIN/shapesim-survey" rubin-i --model no-such-model -o x >out 2>err || rc=$?
expect_error "$rc" 2 "model 'no-such-model': no such file and not a shipped one (hdf, merged)"
[ ! -e x ] || fail "a refused survey left a directory"
rc=0; "$BIN/shapesim-measure" a/image.fits --psf-analytic moffat:0.7,0.5 >out 2>err || rc=$?
expect_error "$rc" 2 "^shapesim-measure: --psf-analytic: .*beta"
rc=0; "$BIN/shapesim-detect" a/image.fits --psf-analytic gaussian:0.7 --psf-fwhm 0.7 --psf x.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 "exclude each other"
exit 0
