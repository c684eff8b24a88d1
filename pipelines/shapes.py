#!/usr/bin/python3
"""Helper of pipelines/shapes.sh (run with /usr/bin/python3: astropy + numpy).

  shapes.py stamps OUTDIR MAGCUT ZP PAD         real stamps brighter than MAGCUT -> OUTDIR/stamps/*.fits,
                                              OUTDIR/stamps/jobs.tsv (name, image, psf image[hdu], ...)
  shapes.py real   JOBS STAMPDIR OUT.tsv     the central galaxy of each stamp's measure output
  shapes.py sim    SIMDIR SEED MAGCUT ISO MATCH OUT.tsv
                                              isolated, matched, measured galaxies of one survey seed
  shapes.py report REAL.tsv SIM.tsv          the table (stdout)
"""
import json
import math
import os
import sys

import numpy as np

# The shipped real stamps (share/data/cosmos_catalog, share/data/cosmos_aegis: README there).
DATA = os.environ.get("SHAPES_DATA",
                      os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "share", "data"))
CATALOGUES = [
    # (tag, catalogue, exposure = gain in e- per e-/s unit)
    ("cosmos", f"{DATA}/cosmos_catalog/extension_26/real_galaxy_catalog_26_extension_example.fits", 2028.0),
    ("aegis", f"{DATA}/cosmos_aegis/AEGIS_F814w_catalog.fits", 2100.0),
]
PIXEL_SCALE = 0.03


def stamps(outdir, magcut, zp, pad):
    """pad > 0: each stamp (its NOISE_MEAN removed) is set in the middle of a canvas PAD pixels
    larger on every side, filled with white Gaussian noise of its NOISE_VARIANCE (a fixed
    seed per galaxy), so that the detection's background mesh (64 px) sees sky, as it does on
    the survey's image; pad = 0: the stamp as it is."""
    from astropy.io import fits
    os.makedirs(outdir, exist_ok=True)
    jobs = []
    for tag, cat, exptime in CATALOGUES:
        folder = os.path.dirname(cat)
        table = fits.open(cat)[1].data
        for row in table:
            mag = float(row["MAG"])
            if not mag < magcut:
                continue
            assert abs(float(row["PIXEL_SCALE"]) - PIXEL_SCALE) < 1e-6
            gal_file = os.path.join(folder, row["GAL_FILENAME"].strip())
            psf_file = os.path.join(folder, row["PSF_FILENAME"].strip())
            with fits.open(gal_file) as h:
                data = np.asarray(h[int(row["GAL_HDU"])].data, dtype=np.float32)
            if pad > 0:
                sy, sx = data.shape
                rng = np.random.default_rng([int(row["IDENT"]), 20240611])
                canvas = rng.normal(0.0, math.sqrt(float(row["NOISE_VARIANCE"])),
                                    (sy + 2 * pad, sx + 2 * pad)).astype(np.float32)
                canvas[pad:pad + sy, pad:pad + sx] = data - np.float32(row["NOISE_MEAN"])
                data = canvas
            ny, nx = data.shape
            hdr = fits.Header()
            hdr["BUNIT"] = ("electron/s", "as the ACS drizzled mosaics")
            hdr["CTYPE1"], hdr["CTYPE2"] = "RA---TAN", "DEC--TAN"
            hdr["CUNIT1"], hdr["CUNIT2"] = "deg", "deg"
            hdr["CRPIX1"], hdr["CRPIX2"] = (nx + 1) / 2.0, (ny + 1) / 2.0
            hdr["CRVAL1"], hdr["CRVAL2"] = float(row["RA"]), float(row["DEC"])
            hdr["CD1_1"], hdr["CD1_2"] = -PIXEL_SCALE / 3600.0, 0.0
            hdr["CD2_1"], hdr["CD2_2"] = 0.0, PIXEL_SCALE / 3600.0
            hdr["RADESYS"] = "ICRS"
            hdr["EXPTIME"] = exptime
            hdr["GAIN"] = (exptime, "electrons per image unit")
            hdr["MAGZERO"] = (zp, "AB zero point: mag = MAGZERO - 2.5 log10(value)")
            hdr["PHOTZP"] = zp
            hdr["CATMAG"] = (mag, "catalogue MAG")
            hdr["CATIDENT"] = str(row["IDENT"])
            hdr["PADDED"] = (pad, "pixels of white noise added on every side")
            name = f"{tag}-{row['IDENT']}"
            fits.PrimaryHDU(data, hdr).writeto(os.path.join(outdir, name + ".fits"), overwrite=True)
            # The PSF in cfitsio's [HDU] syntax ([0] is the primary HDU, as GalSim counts).
            jobs.append((name, tag, str(row["IDENT"]), f"{mag:.4f}", os.path.join(outdir, name + ".fits"),
                         f"{psf_file}[{int(row['PSF_HDU'])}]", f"{exptime:g}", str(nx), str(ny),
                         f"{math.sqrt(float(row['NOISE_VARIANCE'])):.4g}"))
    with open(os.path.join(outdir, "jobs.tsv"), "w") as f:
        for j in jobs:
            f.write("\t".join(j) + "\n")
    print(len(jobs))


def read_jsonl(path):
    out = []
    if os.path.exists(path):
        with open(path) as f:
            for line in f:
                line = line.strip()
                if line:
                    out.append(json.loads(line))
    return out


REAL_COLS = ["name", "source", "ident", "mag", "mag_meas", "shear_e1", "shear_e2", "shear_resolution",
             "snr", "flags", "shear_why", "dist_px", "n_det", "nx", "ny", "noise_rms"]


def fmt(v):
    if v is None:
        return "nan"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def real(jobs, stampdir, out):
    rows = []
    for line in open(jobs):
        name, tag, ident, mag, image, psf, exptime, nx, ny, noise = line.rstrip("\n").split("\t")
        recs = [r for r in read_jsonl(os.path.join(stampdir, name + ".morph.jsonl"))
                if r.get("kind", "galaxy") == "galaxy"]
        cx, cy = (int(nx) + 1) / 2.0, (int(ny) + 1) / 2.0  # FITS pixel coordinates of the centre
        best, dist = None, None
        for r in recs:
            d = math.hypot(r["x"] - cx, r["y"] - cy)
            if dist is None or d < dist:
                best, dist = r, d
        row = dict(name=name, source=tag, ident=ident, mag=float(mag), nx=nx, ny=ny, noise_rms=noise,
                   n_det=len(recs), dist_px=dist)
        if best is None:
            row["flags"] = "no_detection"
        else:
            row.update(mag_meas=best.get("mag"), shear_e1=best.get("shear_e1"),
                       shear_e2=best.get("shear_e2"), shear_resolution=best.get("shear_resolution"),
                       snr=best.get("snr"), flags=",".join(best.get("flags", [])) or "-",
                       shear_why=best.get("shear_why", "-"))
        rows.append(row)
    with open(out, "w") as f:
        f.write("\t".join(REAL_COLS) + "\n")
        for r in rows:
            f.write("\t".join(fmt(r.get(c)) for c in REAL_COLS) + "\n")


SIM_COLS = ["seed", "id", "x", "y", "mag", "truth_mag", "match_px", "nn_arcsec", "shear_e1", "shear_e2",
            "shear_resolution", "snr", "flags", "shear_why", "keep", "why"]
BAD_FLAGS = {"blended", "crowded", "truncated", "aperture_truncated"}


def sim(simdir, seed, magcut, iso, match_arcsec, out):
    recs = read_jsonl(os.path.join(simdir, "morph.jsonl"))
    truth = read_jsonl(os.path.join(simdir, "truth.jsonl"))
    tx = np.array([t["x"] for t in truth], float)
    ty = np.array([t["y"] for t in truth], float)
    tm = np.array([t.get("mag", np.nan) for t in truth], float)
    xy = np.array([[r["x"], r["y"]] for r in recs], float).reshape(-1, 2)
    scale = recs[0].get("pixel_scale", PIXEL_SCALE) if recs else PIXEL_SCALE
    rows = []
    for k, r in enumerate(recs):
        d = np.hypot(xy[:, 0] - r["x"], xy[:, 1] - r["y"])
        d[k] = np.inf
        nn = float(d.min()) * scale if len(d) > 1 else np.inf
        dt = np.hypot(tx - r["x"], ty - r["y"])
        j = int(np.argmin(dt)) if len(dt) else -1
        match = float(dt[j]) if j >= 0 else np.inf
        flags = set(r.get("flags", []))
        why = []
        mag = r.get("mag")
        if r.get("kind", "galaxy") != "galaxy":
            why.append("star")
        if mag is None or not mag < magcut:
            why.append("faint")
        if match * scale > match_arcsec:
            why.append("no_truth_match")
        if nn < iso:
            why.append("neighbour")
        if flags & BAD_FLAGS:
            why.append("flag:" + "+".join(sorted(flags & BAD_FLAGS)))
        if "shear_failed" in flags:
            why.append("shear_failed")
        rows.append(dict(seed=seed, id=r["id"], x=r["x"], y=r["y"], mag=mag,
                         truth_mag=float(tm[j]) if j >= 0 else None, match_px=match, nn_arcsec=nn,
                         shear_e1=r.get("shear_e1"), shear_e2=r.get("shear_e2"),
                         shear_resolution=r.get("shear_resolution"), snr=r.get("snr"),
                         flags=",".join(r.get("flags", [])) or "-", shear_why=r.get("shear_why", "-"),
                         keep=int(not why), why=",".join(why) or "-"))
    with open(out, "w") as f:
        f.write("\t".join(SIM_COLS) + "\n")
        for r in rows:
            f.write("\t".join(fmt(r.get(c)) for c in SIM_COLS) + "\n")


def read_tsv(path):
    with open(path) as f:
        cols = f.readline().rstrip("\n").split("\t")
        return [dict(zip(cols, l.rstrip("\n").split("\t"))) for l in f if l.strip()]


def ks_2samp(a, b):
    """Two-sample KS statistic and asymptotic p (Numerical Recipes' kstwo, Stephens' correction)."""
    a, b = np.sort(a), np.sort(b)
    n, m = len(a), len(b)
    if n == 0 or m == 0:
        return float("nan"), float("nan")
    allv = np.concatenate([a, b])
    d = float(np.max(np.abs(np.searchsorted(a, allv, side="right") / n -
                            np.searchsorted(b, allv, side="right") / m)))
    en = math.sqrt(n * m / (n + m))
    lam = (en + 0.12 + 0.11 / en) * d
    if lam < 1e-3:
        return d, 1.0
    p = 2.0 * sum((-1) ** (j - 1) * math.exp(-2.0 * j * j * lam * lam) for j in range(1, 101))
    return d, min(max(p, 0.0), 1.0)


def stats(e1, e2):
    e1, e2 = np.asarray(e1), np.asarray(e2)
    n = len(e1)
    if n == 0:
        return dict(n=0, rms1=np.nan, rms2=np.nan, rms=np.nan, med=np.nan)
    return dict(n=n, rms1=math.sqrt(np.mean(e1 ** 2)), rms2=math.sqrt(np.mean(e2 ** 2)),
                rms=math.sqrt(np.mean(np.concatenate([e1, e2]) ** 2)), med=float(np.median(np.hypot(e1, e2))))


def boot_ratio_err(re1, re2, se1, se2, nboot=2000, seed=12345):
    """Bootstrap sd of rms_pooled(sim)/rms_pooled(real), resampling galaxies on both sides."""
    rng = np.random.default_rng(seed)
    re = np.concatenate([[re1], [re2]]).T
    se = np.concatenate([[se1], [se2]]).T
    if len(re) < 2 or len(se) < 2:
        return float("nan")
    out = []
    for _ in range(nboot):
        a = re[rng.integers(0, len(re), len(re))]
        b = se[rng.integers(0, len(se), len(se))]
        out.append(math.sqrt(np.mean(b ** 2)) / math.sqrt(np.mean(a ** 2)))
    return float(np.std(out))


def report(real_tsv, sim_tsv):
    real_rows = read_tsv(real_tsv)
    sim_rows = read_tsv(sim_tsv)

    def f(x):
        return float(x) if x not in ("nan", "", "None") else float("nan")

    real_ok = [r for r in real_rows if np.isfinite(f(r["shear_e1"]))]
    sim_ok = [r for r in sim_rows if r["keep"] == "1"]
    n_real_fail = len(real_rows) - len(real_ok)
    why_real = {}
    for r in real_rows:
        if not np.isfinite(f(r["shear_e1"])):
            k = r["shear_why"] if r["flags"] != "no_detection" else "no_detection"
            why_real[k] = why_real.get(k, 0) + 1
    sim_bright = [r for r in sim_rows if "faint" not in r["why"].split(",") and "star" not in r["why"]]
    why_sim = {}
    for r in sim_bright:
        for w in r["why"].split(","):
            if w != "-":
                why_sim[w] = why_sim.get(w, 0) + 1
    print(f"real: {len(real_rows)} stamps with catalogue MAG < cut; {len(real_ok)} measured; "
          f"not measured: {why_real or 'none'}")
    print(f"sim:  {len(sim_bright)} detections brighter than the cut over seeds "
          f"{sorted(set(r['seed'] for r in sim_rows))}; {len(sim_ok)} kept; "
          f"dropped (a galaxy can have several reasons): {why_sim or 'none'}")
    print(f"sim shear_failed among isolated bright galaxies: "
          f"{sum(1 for r in sim_bright if r['why'] == 'shear_failed')}")
    print()
    bins = [("all", -99, 99), ("I<23.5", -99, 23.5), ("23.5-25", 23.5, 99)]
    hdr = ("| bin | side | N | rms e1 | rms e2 | rms pooled | median abs(e) | sim/real pooled (±boot) "
           "| KS D | KS p |")
    print(hdr)
    print("|" + "---|" * 10)
    for label, lo, hi in bins:
        r = [x for x in real_ok if lo <= f(x["mag"]) < hi]
        s = [x for x in sim_ok if lo <= f(x["mag"]) < hi]
        re1 = [f(x["shear_e1"]) for x in r]; re2 = [f(x["shear_e2"]) for x in r]
        se1 = [f(x["shear_e1"]) for x in s]; se2 = [f(x["shear_e2"]) for x in s]
        a, b = stats(re1, re2), stats(se1, se2)
        d, p = ks_2samp(np.hypot(re1, re2), np.hypot(se1, se2))
        err = boot_ratio_err(re1, re2, se1, se2)
        print(f"| {label} | real | {a['n']} | {a['rms1']:.3f} | {a['rms2']:.3f} | {a['rms']:.3f} | "
              f"{a['med']:.3f} | | | |")
        print(f"| {label} | sim | {b['n']} | {b['rms1']:.3f} | {b['rms2']:.3f} | {b['rms']:.3f} | "
              f"{b['med']:.3f} | | | |")
        print(f"| {label} | sim/real | | {b['rms1'] / a['rms1']:.3f} | {b['rms2'] / a['rms2']:.3f} | "
              f"{b['rms'] / a['rms']:.3f} | {b['med'] / a['med']:.3f} | {b['rms'] / a['rms']:.3f} ± {err:.3f} "
              f"| {d:.3f} | {p:.3g} |")
    # Sensitivity: the real side with the simulated side's flag cut as well.
    rc = [x for x in real_ok if not set(x["flags"].split(",")) & BAD_FLAGS]
    re1 = [f(x["shear_e1"]) for x in rc]; re2 = [f(x["shear_e2"]) for x in rc]
    se1 = [f(x["shear_e1"]) for x in sim_ok]; se2 = [f(x["shear_e2"]) for x in sim_ok]
    a, b = stats(re1, re2), stats(se1, se2)
    d, p = ks_2samp(np.hypot(re1, re2), np.hypot(se1, se2))
    print(f"\nreal without blended/crowded/truncated central objects: N {a['n']}, rms {a['rms1']:.3f} / "
          f"{a['rms2']:.3f} (pooled {a['rms']:.3f}), median |e| {a['med']:.3f}; sim/real pooled "
          f"{b['rms'] / a['rms']:.3f}; KS p {p:.3g}")


if __name__ == "__main__":
    cmd = sys.argv[1]
    if cmd == "stamps":
        stamps(sys.argv[2], float(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5]))
    elif cmd == "real":
        real(sys.argv[2], sys.argv[3], sys.argv[4])
    elif cmd == "sim":
        sim(sys.argv[2], sys.argv[3], float(sys.argv[4]), float(sys.argv[5]), float(sys.argv[6]), sys.argv[7])
    elif cmd == "report":
        report(sys.argv[2], sys.argv[3])
    else:
        sys.exit(__doc__)
