#!/usr/bin/env bash
# shapesim-render --psf-field: a PSF that varies across the field, read from the model psfex
# makes of a ground-based star field (SExtractor, then psfex, as a survey pipeline runs them).
# Stars rendered across the field match psfex's own PSF at their places (FWHM and ellipticity
# within 1%); psfex's snapshots check that its model is read as psfex evaluates it; the truth
# records the PSF's shape; measure --shear-estimate --psf-field corrects each galaxy by the PSF
# at its place, and decompose --psf-field fits each through it; a file that is not a PSFEx
# model is one line of error, nothing written.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
command -v source-extractor >/dev/null && command -v psfex >/dev/null ||
  fail "source-extractor and psfex are needed (share/scripts/install-deps.sh installs them)"
xdf=$(cd ../../../share/data/xdf && pwd)
cd "$TMPDIR"

# A 1024² ground-based frame at 0.2″ with 196 Moffat stars (β 3) whose FWHM grows with y and
# with x² and whose ellipticity turns across the field, pixel-integrated, with noise.
/usr/bin/python3 - <<'PY' || fail "could not make the star field"
import numpy as np
from astropy.io import fits
from astropy.wcs import WCS
rng = np.random.default_rng(1)
n = 1024
img = np.zeros((n, n))
xs, ys = np.meshgrid(np.linspace(40, n - 40, 14), np.linspace(40, n - 40, 14))
xs = xs.ravel() + rng.uniform(-8, 8, xs.size)
ys = ys.ravel() + rng.uniform(-8, 8, ys.size)
sub, r = 5, 12
off = (np.arange(sub) + 0.5) / sub - 0.5
for x0, y0 in zip(xs, ys):
    u, v = (x0 - 1) / (n - 1) * 2 - 1, (y0 - 1) / (n - 1) * 2 - 1
    fwhm, e1, e2, beta = 4.0 + 0.6 * v + 0.3 * u * u, 0.06 * u, 0.04 * v, 3.0
    alpha = fwhm / (2 * np.sqrt(2 ** (1 / beta) - 1))
    ix0, iy0 = int(round(x0)), int(round(y0))
    gx = (np.arange(ix0 - r, ix0 + r + 1)[:, None] + off[None, :]).ravel()
    gy = (np.arange(iy0 - r, iy0 + r + 1)[:, None] + off[None, :]).ravel()
    X, Y = np.meshgrid(gx - x0, gy - y0)
    e, th = np.hypot(e1, e2), 0.5 * np.arctan2(e2, e1)
    xp = np.cos(th) * X + np.sin(th) * Y
    yp = -np.sin(th) * X + np.cos(th) * Y
    q = np.sqrt((1 - e) / (1 + e))
    prof = (1 + (xp ** 2 * q + yp ** 2 / q) / alpha ** 2) ** (-beta)
    prof = (prof / prof.sum()).reshape(2 * r + 1, sub, 2 * r + 1, sub).sum(axis=(1, 3))
    img[iy0 - r - 1:iy0 + r, ix0 - r - 1:ix0 + r] += 10 ** rng.uniform(4.3, 5.3) * prof
img += rng.normal(0, 5.0, img.shape)
w = WCS(naxis=2)
w.wcs.ctype = ["RA---TAN", "DEC--TAN"]
w.wcs.crpix = [512.5, 512.5]
w.wcs.crval = [150.0, 2.0]
w.wcs.cd = [[-0.2 / 3600, 0], [0, 0.2 / 3600]]
h = w.to_header()
h["GAIN"] = 1.0
fits.writeto("field.fits", img.astype(np.float32), h, overwrite=True)
PY

# SExtractor's vignettes, then psfex: a degree-2 model sampled at the image's pixels, with its
# 9 × 9 snapshots (psfex evaluating its own model across the field).
printf '%s\n' X_IMAGE Y_IMAGE 'FLUX_APER(1)' 'FLUXERR_APER(1)' FLUX_RADIUS ELONGATION FLAGS \
  SNR_WIN 'VIGNET(35,35)' >psf.param
source-extractor field.fits -c /dev/null -CATALOG_NAME stars.ldac -CATALOG_TYPE FITS_LDAC \
  -PARAMETERS_NAME psf.param -FILTER N -DETECT_THRESH 10 -PHOT_APERTURES 10 \
  -STARNNW_NAME /usr/share/source-extractor/default.nnw -VERBOSE_TYPE QUIET 2>sex.err ||
  fail "source-extractor failed: $(cat sex.err)"
psfex stars.ldac -c /dev/null -PSF_SAMPLING 1.0 -PSF_SIZE 25,25 -PSFVAR_DEGREES 2 \
  -CHECKIMAGE_TYPE SNAPSHOTS -CHECKIMAGE_NAME snap.fits -CHECKPLOT_TYPE NONE -WRITE_XML N \
  -VERBOSE_TYPE QUIET 2>psfex.err || fail "psfex failed: $(cat psfex.err)"
[ -s stars.psf ] && [ -s snap_stars.fits ] || fail "psfex wrote no model: $(cat psfex.err)"

# FWHM from the area above half the peak (8× bilinear); ellipticity (distortion) from adaptive
# Gaussian-weighted moments: measured alike on psfex's image and on ours.
cat >shape.py <<'PY'
import numpy as np
def shape(im):
    # FWHM from the area above half the peak (8× bilinear); ellipticity (distortion) from
    # adaptive Gaussian-weighted moments: both measured alike on both images.
    k = 8
    n = im.shape[0]
    g = np.linspace(0, n - 1, (n - 1) * k + 1)
    i0 = np.minimum(np.floor(g).astype(int), n - 2)
    f = g - i0
    rows = im[i0] * (1 - f)[:, None] + im[i0 + 1] * f[:, None]
    fine = rows[:, i0] * (1 - f)[None, :] + rows[:, i0 + 1] * f[None, :]
    fwhm = 2 * np.sqrt((fine > fine.max() / 2).sum() / k ** 2 / np.pi)
    yy, xx = np.mgrid[0:n, 0:n].astype(float)
    cx = cy = (n - 1) / 2
    m = np.array([[4.0, 0], [0, 4.0]])
    for _ in range(100):
        d = np.stack([xx - cx, yy - cy])
        inv = np.linalg.inv(m)
        wgt = im * np.exp(-0.5 * np.einsum("i...,ij,j...->...", d, inv, d))
        s = wgt.sum()
        cx, cy = (wgt * xx).sum() / s, (wgt * yy).sum() / s
        q = np.array([[(wgt * d[0] ** 2).sum(), (wgt * d[0] * d[1]).sum()],
                      [(wgt * d[0] * d[1]).sum(), (wgt * d[1] ** 2).sum()]]) / s
        new = 2 * q
        if abs(new - m).max() < 1e-10:
            break
        m = new
    e1 = (m[0, 0] - m[1, 1]) / (m[0, 0] + m[1, 1])
    e2 = 2 * m[0, 1] / (m[0, 0] + m[1, 1])
    return fwhm, e1, e2
PY

# 25 stars across the field at pixel centres, far enough apart not to touch.
/usr/bin/python3 - <<'PY' || fail "could not write the stars"
import json
from astropy.io import fits
from astropy.wcs import WCS
w = WCS(fits.getheader("field.fits"))
with open("stars.jsonl", "w") as out:
    for j, y in enumerate([40, 280, 512, 750, 985]):
        for i, x in enumerate([45, 270, 515, 760, 980]):
            ra, dec = w.all_pix2world([[x, y]], 1)[0]
            out.write(json.dumps({"schema": "shapesim.object/1", "id": f"s{i}{j}", "kind": "star",
                                  "ra": ra, "dec": dec, "flux": 1000.0}) + "\n")
PY
"$BIN/shapesim-render" stars.jsonl --like field.fits --psf-field stars.psf --noise-free \
  -o rendered.fits --truth truth.jsonl 2>render.err || fail "render --psf-field failed: $(cat render.err)"
grep -q "PSF varying across the field" render.err || fail "render did not say which PSF: $(cat render.err)"

/usr/bin/python3 - <<'PY' || fail "the stars do not match psfex's PSF"
import json
import numpy as np
from astropy.io import fits
t = fits.open("stars.psf")[1]
H, B = t.header, t.data["PSF_MASK"][0]
deg = H["POLDEG1"]

def psfex_at(x, y):
    dx = (x - H["POLZERO1"]) / H["POLSCAL1"]
    dy = (y - H["POLZERO2"]) / H["POLSCAL2"]
    P = [dx ** i * dy ** j for j in range(deg + 1) for i in range(deg + 1 - j)]
    return np.tensordot(P, B, (0, 0))

# The formula is psfex's own: its 9 × 9 snapshots, at x̃, ỹ = −4/9 … 4/9.
snap = fits.getdata("snap_stars.fits")
for j in range(9):
    for i in range(9):
        x = H["POLZERO1"] + H["POLSCAL1"] * (i - 4) / 9
        y = H["POLZERO2"] + H["POLSCAL2"] * (j - 4) / 9
        s = snap[25 * j:25 * (j + 1), 25 * i:25 * (i + 1)]
        assert abs(psfex_at(x, y) - s).max() < 1e-5 * s.max(), (i, j)

exec(open("shape.py").read())

image = fits.getdata("rendered.fits")
truth = {t["id"]: t for t in map(json.loads, open("truth.jsonl"))}
worst_f = worst_e = 0.0
for line in open("stars.jsonl"):
    s = json.loads(line)
    t = truth[s["id"]]
    x, y = round(t["x"]), round(t["y"])
    assert abs(t["x"] - x) < 1e-6 and abs(t["y"] - y) < 1e-6, (t["x"], t["y"])
    assert {"psf_e1", "psf_e2", "psf_rms_radius"} <= set(t), t
    ours = image[y - 13:y + 12, x - 13:x + 12]
    f0, a1, a2 = shape(psfex_at(x, y))
    f1, b1, b2 = shape(ours)
    worst_f = max(worst_f, abs(f1 / f0 - 1))
    worst_e = max(worst_e, np.hypot(b1 - a1, b2 - a2) / max(np.hypot(a1, a2), 0.01))
print(f"stars against psfex's PSF at their places: FWHM within {100 * worst_f:.2f}%, "
      f"ellipticity within {100 * worst_e:.1e}% (of |e|, at least 0.01)")
assert worst_f < 0.01 and worst_e < 0.01
# The PSF varies: the truth follows it (e1 grows with x, the size with y).
t = [truth[f"s{i}2"] for i in range(5)]
assert t[0]["psf_e1"] < -0.01 and t[4]["psf_e1"] > 0.01, [s["psf_e1"] for s in t]
t = [truth[f"s2{j}"] for j in range(5)]
assert t[4]["psf_rms_radius"] > 1.1 * t[0]["psf_rms_radius"], [s["psf_rms_radius"] for s in t]
PY

# A real image: the shipped XDF F814W cut (0.06″ pixels). psfex finds too few stars to let
# the PSF vary (degree 0) and samples it 1.06 pixels apart; a star rendered through its model
# has psfex's FWHM (in pixels) and ellipticity.
source-extractor "$xdf/f814w_sci.fits" -c /dev/null -CATALOG_NAME xdf.ldac -CATALOG_TYPE FITS_LDAC \
  -PARAMETERS_NAME psf.param -FILTER N -DETECT_THRESH 5 -PHOT_APERTURES 6 \
  -STARNNW_NAME /usr/share/source-extractor/default.nnw -VERBOSE_TYPE QUIET 2>sex.err ||
  fail "source-extractor failed on the XDF: $(cat sex.err)"
psfex xdf.ldac -c /dev/null -PSF_SIZE 25,25 -PSFVAR_DEGREES 0 -SAMPLE_FWHMRANGE 1.5,8 \
  -SAMPLE_MINSN 20 -CHECKPLOT_TYPE NONE -CHECKIMAGE_TYPE NONE -WRITE_XML N -VERBOSE_TYPE QUIET \
  2>psfex.err || fail "psfex failed on the XDF: $(cat psfex.err)"
printf '{"schema":"shapesim.object/1","id":"s1","kind":"star","ra":0,"dec":0,"flux":1000}\n' >one.jsonl
"$BIN/shapesim-render" one.jsonl --pixels 101 --pixel-scale 0.06 --psf-field xdf.psf --noise-free \
  -o one.fits 2>render.err || fail "render --psf-field xdf.psf failed: $(cat render.err)"
grep -q "constant (psfex's degree 0)" render.err || fail "render: $(cat render.err)"
/usr/bin/python3 - <<'PY' || fail "the XDF star does not match psfex's PSF"
import numpy as np
from astropy.io import fits
exec(open("shape.py").read())
t = fits.open("xdf.psf")[1]
step = t.header["PSF_SAMP"]
assert t.header["ACCEPTED"] >= 8 and abs(step - 1) > 0.01, (t.header["ACCEPTED"], step)
f0, a1, a2 = shape(t.data["PSF_MASK"][0][0])
f1, b1, b2 = shape(fits.getdata("one.fits")[38:63, 38:63])
print(f"XDF: {t.header['ACCEPTED']} stars, sampling {step:.3f}: FWHM {f1:.3f} px against psfex's "
      f"{f0 * step:.3f}, e ({b1:.4f}, {b2:.4f}) against ({a1:.4f}, {a2:.4f})")
assert abs(f1 / (f0 * step) - 1) < 0.01 and np.hypot(b1 - a1, b2 - a2) < 0.01 * max(np.hypot(a1, a2), 0.01)
PY

# Round galaxies (intrinsic Gaussians) through the varying PSF: measure's PSF-blurred e1, e2
# follow the PSF across the field; --shear-estimate --psf-field takes it out at each place.
sed 's/"kind": "star"/"kind": "galaxy"/; s/"flux": 1000.0}/"flux": 5000.0, "beta": 0.4, "pixel_scale": 0.2, "n_max": 0, "coeffs": [[705.2, 0]], "frame": "intrinsic"}/' \
  stars.jsonl >galaxies.jsonl
"$BIN/shapesim-render" galaxies.jsonl --like field.fits --psf-field stars.psf --noise-rms 0.05 \
  --seed 3 -o galaxies.fits -q || fail "render of the galaxies failed"
"$BIN/shapesim-measure" galaxies.fits --shear-estimate --psf-field stars.psf -q >measured.jsonl ||
  fail "measure --shear-estimate --psf-field failed"
/usr/bin/python3 - <<'PY' || fail "the shear estimate did not follow the PSF"
import json, math
truth = [json.loads(l) for l in open("truth.jsonl")]
got = []
for r in map(json.loads, open("measured.jsonl")):
    if min(math.hypot(r["x"] - t["x"], r["y"] - t["y"]) for t in truth) < 2:
        got.append(r)
assert len(got) == 25, len(got)
blurred = max(math.hypot(r["e1"], r["e2"]) for r in got)
corrected = max(math.hypot(r["shear_e1"], r["shear_e2"]) for r in got)
print(f"round galaxies: |e| up to {blurred:.4f} through the PSF, {corrected:.4f} corrected")
assert blurred > 0.02 and corrected < 0.005
PY

# decompose --psf-field: each galaxy's intrinsic model fitted through the PSF at its place
# gives back the round Gaussian drawn (β 0.4″), wherever it is.
"$BIN/shapesim-detect" galaxies.fits --stamps stamps.fits -q >sources.jsonl || fail "detect failed"
"$BIN/shapesim-decompose" --psf-field stars.psf -q <sources.jsonl >models.jsonl ||
  fail "decompose --psf-field failed"
/usr/bin/python3 - <<'PY' || fail "decompose --psf-field did not give the galaxies back"
import json, math
truth = [json.loads(l) for l in open("truth.jsonl")]
src = {r["id"]: r for r in map(json.loads, open("sources.jsonl"))}
betas = []
for r in map(json.loads, open("models.jsonl")):
    s = src[r["id"]]
    if min(math.hypot(s["x"] - t["x"], s["y"] - t["y"]) for t in truth) < 2:
        assert r["frame"] == "intrinsic" and r["n_max"] <= 2, r
        betas.append(r["beta"])
print(f"decompose --psf-field: beta {min(betas):.4f} to {max(betas):.4f} arcsec (0.4 drawn)")
assert len(betas) == 25 and max(abs(b - 0.4) for b in betas) < 0.004
PY

# A field larger than the image psfex measured: render says how many objects lie beyond the
# stars (their PSF extrapolated); none is said for the image itself.
! grep -q "beyond the stars" render.err || fail "a warning for objects within the stars: $(cat render.err)"
/usr/bin/python3 - <<'PY'
import json
with open("far.jsonl", "w") as out:
    for line in open("stars.jsonl"):
        s = json.loads(line)
        s["ra"] = 150.0 + (s["ra"] - 150.0) * 1.6  # spread 1.6x about the field's centre
        out.write(json.dumps(s) + "\n")
PY
"$BIN/shapesim-render" far.jsonl --pixels 1800 --pixel-scale 0.2 --ra 150 --dec 2 --psf-field stars.psf \
  --noise-free -o far.fits 2>far.err || fail "render beyond the stars failed: $(cat far.err)"
grep -qE "^shapesim-render: warning: [0-9]+ of 25 objects lie beyond the stars the PSF field was fitted to" far.err ||
  fail "no warning for objects beyond the stars: $(cat far.err)"

# Not a PSFEx model; with --psf: one line, no image.
rc=0
"$BIN/shapesim-render" stars.jsonl --like field.fits --psf-field field.fits -o bad.fits 2>err || rc=$?
expect_error "$rc" 1 "field.fits.*PSF_DATA"
[ ! -e bad.fits ] || fail "a refused render wrote its image"
rc=0
"$BIN/shapesim-render" stars.jsonl --like field.fits --psf-field stars.psf --psf-analytic gaussian:0.8 \
  -o bad.fits 2>err || rc=$?
expect_error "$rc" 2 "psf-field"
[ ! -e bad.fits ] || fail "a refused render wrote its image"
rc=0
"$BIN/shapesim-render" stars.jsonl --like field.fits --psf-field stars.psf --galaxy-psf stars.psf \
  -o bad.fits 2>err || rc=$?
expect_error "$rc" 2 "psf-field with --galaxy-psf"
rc=0
"$BIN/shapesim-decompose" --psf-field stars.psf --psf-analytic gaussian:0.8 <sources.jsonl >bad.jsonl 2>err || rc=$?
expect_error "$rc" 2 "psf-field"
rc=0
"$BIN/shapesim-measure" galaxies.fits --psf-field stars.psf >bad.jsonl 2>err || rc=$?
expect_error "$rc" 2 "shear-estimate"
echo "ok"
