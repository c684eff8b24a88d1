#!/usr/bin/env bash
# Survey projections end to end (wcslib): a field with a DECam-like TPV header and one with VISTA's
# ZPN (tests/data/wcs) is sampled, rendered and detected. The rendered image carries its input's
# WCS card for card (PV terms included); every detection's RA/Dec equals astropy's
# all_pix2world of its x, y on the rendered header to 1e-10 degrees, and every sampled object's
# x, y equals astropy's all_world2pix of its RA/Dec to 1e-6 pixel.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
wcsdir=$(cd ../../data/wcs && pwd)
models=$(cd ../../../share/data/models && pwd)
cd "$TMPDIR"
for projection in tpv zpn; do
  # The fixture's header on a 768 x 768 field.
  /usr/bin/python3 - "$wcsdir/$projection.fits" "$projection-field.fits" <<'PY'
import sys, numpy as np
from astropy.io import fits
header = fits.getheader(sys.argv[1])
fits.PrimaryHDU(np.zeros((768, 768), dtype=np.float32), header=header).writeto(sys.argv[2])
PY
  "$BIN/shapesim-sample" -q "$models/hdf.json" --like "$projection-field.fits" --zero-point 30 \
    --seed 3 >"$projection.objects.jsonl" || fail "sample --like a $projection field failed"
  "$BIN/shapesim-render" -q "$projection.objects.jsonl" --like "$projection-field.fits" \
    --psf "$models/hdf.psf.jsonl" --galaxy-psf "$models/hdf.psf.jsonl" --noise-rms 1e-3 --seed 3 -o "$projection.fits" ||
    fail "render --like a $projection field failed"
  "$BIN/shapesim-detect" -q "$projection.fits" --zero-point 30 >"$projection.sources.jsonl" ||
    fail "detect on the $projection field failed"
  /usr/bin/python3 - "$projection" <<'PY' || fail "$projection: world coordinates differ from astropy's"
import json, sys, numpy as np
from astropy.io import fits
from astropy.wcs import WCS
name = sys.argv[1]
given, made = fits.getheader(name + "-field.fits"), fits.getheader(name + ".fits", 1)
keys = [k for k in given if k[:2] in ("CT", "CR", "CD", "PV")]
assert all(made[k] == given[k] for k in keys), [(k, given[k], made.get(k)) for k in keys if made.get(k) != given[k]]
assert any(k.startswith("PV") for k in keys)
wcs = WCS(made)
sources = [json.loads(l) for l in open(name + ".sources.jsonl")]
assert len(sources) >= 20, len(sources)
x, y = np.array([s["x"] for s in sources]), np.array([s["y"] for s in sources])
ra, dec = wcs.all_pix2world(x, y, 1)
got_ra, got_dec = np.array([s["ra"] for s in sources]), np.array([s["dec"] for s in sources])
worst = max(np.max(np.abs((got_ra - ra + 180) % 360 - 180)), np.max(np.abs(got_dec - dec)))
assert worst < 1e-10, worst
objects = [json.loads(l) for l in open(name + ".objects.jsonl")]
px, py = wcs.all_world2pix([o["ra"] for o in objects], [o["dec"] for o in objects], 1, tolerance=1e-12)
far = max(np.max(np.abs(px - [o["x"] for o in objects])), np.max(np.abs(py - [o["y"] for o in objects])))
assert far < 1e-6, far
print(f"{name}: {len(sources)} detections, RA/Dec within {worst:.1e} deg of astropy; "
      f"{len(objects)} objects' x, y within {far:.1e} px")
PY
done
# A projection wcslib does not know: one line naming the file and CTYPE1, no image.
/usr/bin/python3 - "$wcsdir/zpn.fits" <<'PY'
import sys
from astropy.io import fits
header = fits.getheader(sys.argv[1])
header["CTYPE1"], header["CTYPE2"] = "RA---XYZ", "DEC--XYZ"
fits.PrimaryHDU(fits.getdata(sys.argv[1]), header=header).writeto("unknown.fits")
PY
rc=0; "$BIN/shapesim-render" --like unknown.fits --noise-rms 1 -o bad.fits </dev/null >out 2>err || rc=$?
expect_error "$rc" 1 'unknown.fits.*CTYPE1: wcslib'
[ ! -e bad.fits ] || fail "render wrote an image with a WCS it could not read"
exit 0
